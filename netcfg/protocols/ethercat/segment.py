"""An EtherCAT segment as resolved: its slaves in wire order, each with its device (ESI or a built-in CoE profile),
its PDO assignment (0x1C12/0x1C13) and mappings, its DC settings, and the logical process image they make."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from netcfg.spec.source import Path

if TYPE_CHECKING:
    from netcfg import model


@dataclass(frozen=True)
class Entry:
    """One mapped object in the process image."""

    slave: str
    pdo: int
    index: int
    sub: int
    bits: int
    name: str
    data_type: str
    bit_offset: int  # from the start of its image (outputs or inputs)

    @property
    def padding(self) -> bool:
        return self.index == 0


@dataclass(frozen=True)
class AssignedPdo:
    index: int
    direction: str  # "rx" (outputs) or "tx" (inputs)
    sm: int
    entries: tuple[tuple[int, int, int, str, str], ...]  # (index, sub, bits, name, data type)

    @property
    def bits(self) -> int:
        return sum(e[2] for e in self.entries)


@dataclass(frozen=True)
class SyncManagerSetup:
    number: int
    kind: str
    start: int
    length: int  # bytes: the PDOs assigned to it, or the mailbox's default size
    control: int


@dataclass
class Slave:
    node: str
    position: int
    cable_m: float
    forwarding_ns: int
    vendor_id: int
    product_code: int
    revision: int
    device: str  # as the report names it: the ESI's <Type> or the profile
    source: str  # the ESI file as the spec writes it, or builtin:<profile>
    path: Path
    rx: list[AssignedPdo] = field(default_factory=list)
    tx: list[AssignedPdo] = field(default_factory=list)
    sync_managers: list[SyncManagerSetup] = field(default_factory=list)
    pdo_mappings: dict[int, tuple[tuple[int, int, int], ...]] = field(default_factory=dict)  # written at start-up
    assign_activate: int = 0
    sync0_shift_ns: int | None = None
    min_cycle_ns: int | None = None
    assign_writable: bool = True  # the device takes a PDO assignment by SDO (its 0x1C12/0x1C13 are writable)
    out_offset: int = 0  # bytes into the output image
    in_offset: int = 0

    @property
    def out_bytes(self) -> int:
        return -(-sum(p.bits for p in self.rx) // 8)

    @property
    def in_bytes(self) -> int:
        return -(-sum(p.bits for p in self.tx) // 8)


@dataclass
class Segment:
    cycle_ns: int
    master: str | None
    slaves: list[Slave]
    sync0_cycle_ns: int
    sync0_shift_ns: int
    master_jitter_ns: int
    path: Path
    outputs: list[Entry] = field(default_factory=list)
    inputs: list[Entry] = field(default_factory=list)

    @property
    def out_bytes(self) -> int:
        return sum(s.out_bytes for s in self.slaves)

    @property
    def in_bytes(self) -> int:
        return sum(s.in_bytes for s in self.slaves)

    def lay_out(self) -> None:
        """Each slave's outputs then, after every slave's, their inputs, byte-aligned per slave (as SOEM's IOmap
        lays them out); every entry at its bit offset in its image."""
        self.outputs, self.inputs = [], []
        out = inp = 0
        for s in self.slaves:
            s.out_offset, s.in_offset = out, inp
            self.outputs += _entries(s.node, s.rx, out * 8)
            self.inputs += _entries(s.node, s.tx, inp * 8)
            out += s.out_bytes
            inp += s.in_bytes


def segments(m: model.Model) -> Iterator[tuple[model.Bus, Segment]]:
    """Each EtherCAT bus of the model with its segment, in the spec's order."""
    for bus in m.buses.values():
        seg: Segment | None = bus.ethercat
        if seg is not None:
            yield bus, seg


def _entries(slave: str, pdos: list[AssignedPdo], start_bit: int) -> list[Entry]:
    out, bit = [], start_bit
    for p in pdos:
        for index, sub, bits, name, data_type in p.entries:
            out.append(Entry(slave, p.index, index, sub, bits, name, data_type, bit))
            bit += bits
    return out
