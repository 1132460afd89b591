"""Messages on an EtherCAT segment: a slave's assigned PDO named as a message, so that flows can cross the segment
(a CAN sensor's value through a gateway slave's TxPDO to a task on the master, a master task's command through a
gateway's RxPDO to a CAN bus).

A message on an EtherCAT bus is one PDO of one slave, written `pdo: {tpdo: N}` (the slave's TxPDO 0x1A00 + N - 1,
its inputs, which the master reads: producer the slave, consumer the master) or `pdo: {rpdo: N}` (RxPDO
0x1600 + N - 1, its outputs: producer the master, consumer the slave). The PDO must be one the slave's assignment
holds (0x1C12/0x1C13); its `map`, if given, names objects that PDO carries (the data the flow follows). It rides
every cycle, so it is periodic at the bus's cycle; its identifier is the PDO's logical address in the process
image (SOEM's IOmap offset), unique on the segment.

Its delivery, from the cycle's start (netcfg.protocols.ethercat.analysis has the frame's timing):

- a TxPDO is read by the LRW datagram as the datagram's bytes for that slave's inputs pass it (the sync manager's
  buffer as the application last wrote it: ETG.1000.4 and Beckhoff's EtherCAT Slave Controller Section I, chapter
  8.1 "Buffered mode") and delivered when the last frame is back at the master: at the latest the segment's
  latency (jitter, wire, forwarding, cables); at the earliest, after its read, the rest of the frames' bytes and
  the cables back from the slave;
- an RxPDO is copied into the frame as the master sends it and delivered to the slave when the last frame's end
  has passed it (a sync manager's buffer is handed to the application only after the frame's check sequence is
  good: Section I, chapter 8.1): at the latest the slave's frame-passed bound; at the earliest the frames' wire
  time and the cables to it.

A flow in step with the cycle (netcfg.protocols.ethercat.flow) also needs when the frame takes the data: an RxPDO
at the master's send, between the cycle's start and the master's jitter; a TxPDO as the datagram passes the slave,
between its read offset and the cables after the cycle's start and the jitter and the forwarding delays up to the
slave later still.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from netcfg import model
from netcfg.links import ethercat as link
from netcfg.runtime.pdos import PdoEntry
from netcfg.spec import schema
from netcfg.spec.source import Path

if TYPE_CHECKING:
    from netcfg.protocols.ethercat.cycle import CycleTiming
    from netcfg.protocols.ethercat.segment import AssignedPdo, Segment, Slave
    from netcfg.rules import Resolution

FIRST = {"tpdo": 0x1A00, "rpdo": 0x1600}
SIDE_OF = {"tpdo": "tx", "rpdo": "rx"}
PDO_SETTINGS = ("transmission", "inhibit", "event_timer", "sync_start")  # CANopen's, meaningless on a segment
# CoE data type codes (ETG.1000.6 Table 64, the CiA 301 numbers) of the ESI's base types, for runtime.json's entries
COE_TYPES = {
    "BOOL": 0x01, "BIT": 0x01, "SINT": 0x02, "INT": 0x03, "DINT": 0x04, "USINT": 0x05, "UINT": 0x06,
    "UDINT": 0x07, "REAL": 0x08, "LINT": 0x15, "ULINT": 0x1B, "LREAL": 0x11,
    "BOOLEAN": 0x01, "INTEGER8": 0x02, "INTEGER16": 0x03, "INTEGER32": 0x04, "UNSIGNED8": 0x05,
    "UNSIGNED16": 0x06, "UNSIGNED32": 0x07, "REAL32": 0x08, "INTEGER64": 0x15, "UNSIGNED64": 0x1B,
}
UNSIGNED_BY_BITS = {8: 0x05, 16: 0x06, 32: 0x07, 64: 0x1B}


@dataclass(frozen=True)
class PdoMessage:
    """Where a message's PDO lies: its slave, its direction and its bytes in the logical image."""

    name: str
    slave: str
    direction: str  # "inputs" (a TxPDO, slave to master) or "outputs" (an RxPDO, master to slave)
    logical: int  # its first byte in the logical image (outputs, then inputs)
    length: int
    index: int  # its mapping object in the slave's dictionary (0x1A00.., 0x1600..)


def _data_type(name: str, bits: int) -> int:
    base = name.split("(")[0].strip().upper()
    return COE_TYPES.get(base, UNSIGNED_BY_BITS.get(bits, 0x07 if bits > 8 else 0x05))


def object_ref(ref: int | str) -> tuple[int, int] | None:
    """An object written 0x6064 or '0x30D1:2' as (index, sub-index); None when it is neither."""
    if isinstance(ref, int):
        return ref, 0
    text = ref.strip()
    index, _, sub = text.partition(":")
    try:
        return int(index, 0), int(sub, 0) if sub else 0
    except ValueError:
        return None


def resolve_pdo(
    r: Resolution, m: schema.Message, sbus: schema.Bus, bus: model.Bus, path: Path
) -> tuple[model.Pdo, tuple[model.Signal, ...]] | None:
    seg: Segment | None = bus.ethercat
    assert m.pdo is not None
    ppath = (*path, "pdo")
    if seg is None:
        return None  # the segment's own errors are reported at the bus
    for key in PDO_SETTINGS:
        if key in m.pdo.model_fields_set:
            r.err(
                "wrong-section",
                f"'{key}' is a CANopen PDO setting; an EtherCAT PDO rides every cycle of bus '{sbus.name}'",
                (*ppath, key),
            )
    kind = "tpdo" if m.pdo.tpdo is not None else "rpdo"
    number = m.pdo.tpdo if m.pdo.tpdo is not None else m.pdo.rpdo
    assert number is not None
    index = FIRST[kind] + number - 1
    slave_name = m.producer if kind == "tpdo" else (m.consumers[0] if len(m.consumers) == 1 else "")
    other = list(m.consumers) if kind == "tpdo" else [m.producer]
    if kind == "rpdo" and len(m.consumers) != 1:
        r.err("pdo", f"RxPDO {number} goes to one slave: give 'consumers' one node", (*path, "consumers"))
        return None
    if seg.master is not None and other != [seg.master]:
        where = (*path, "consumers") if kind == "tpdo" else (*path, "producer")
        r.err(
            "pdo",
            f"message '{m.name}': a slave's {'TxPDO goes to' if kind == 'tpdo' else 'RxPDO comes from'} the "
            f"segment's master '{seg.master}', not {', '.join(repr(n) for n in other)}: the master's cyclic frame "
            "carries it (slave to slave goes through a task on the master)",
            where,
        )
        return None
    slave = next((s for s in seg.slaves if s.node == slave_name), None)
    if slave is None:
        in_section = sbus.ethercat is not None and any(s.node == slave_name for s in sbus.ethercat.slaves)
        if not in_section:  # (a listed slave that did not resolve has its error at the slave)
            names = ", ".join(s.node for s in seg.slaves) or "none"
            r.err(
                "pdo",
                f"message '{m.name}': '{slave_name}' is none of bus '{sbus.name}''s slaves ({names}); "
                f"{'a TxPDO' if kind == 'tpdo' else 'an RxPDO'} is a slave's",
                (*path, "producer") if kind == "tpdo" else (*path, "consumers"),
            )
        return None
    pdos = slave.tx if kind == "tpdo" else slave.rx
    pdo = next((p for p in pdos if p.index == index), None)
    if pdo is None:
        have = ", ".join(f"0x{p.index:04X}" for p in pdos) or "none"
        r.err(
            "pdo",
            f"message '{m.name}': slave '{slave.node}' has no {kind.upper()} {number} (0x{index:04X}) assigned; "
            f"its assignment holds {have}",
            (*ppath, kind),
        )
        return None
    carried = {(e[0], e[1]) for e in pdo.entries}
    for k, ref in enumerate(m.pdo.map):
        obj = ref.object if isinstance(ref, schema.PdoEntry) else ref
        parsed = object_ref(obj)
        if parsed is None or parsed not in carried:
            listed = ", ".join(f"0x{i:04X}:{s}" for i, s in sorted(carried)) or "nothing"
            r.err(
                "pdo-mapping",
                f"message '{m.name}': PDO 0x{index:04X} of slave '{slave.node}' carries {listed}, not '{obj}'",
                (*ppath, "map", k),
            )
            return None
    entries = tuple(
        PdoEntry(e[0], e[1], e[2], e[3], _data_type(e[4], e[2])) for e in pdo.entries if e[0] != 0
    )
    if not entries:
        r.err("pdo", f"message '{m.name}': PDO 0x{index:04X} of slave '{slave.node}' maps nothing", ppath)
        return None
    return model.Pdo(kind, number, slave.node, 0, None, None, None, entries), ()  # type: ignore[arg-type]


def logical_address(seg: Segment, slave: Slave, pdo: AssignedPdo) -> int:
    """The PDO's first byte in the logical image (each slave's PDOs byte-aligned, in their assignment's order)."""
    pdos = slave.rx if pdo.direction == "rx" else slave.tx
    bits = sum(p.bits for p in pdos[: pdos.index(pdo)])
    base = slave.out_offset if pdo.direction == "rx" else seg.out_bytes + slave.in_offset
    return base + bits // 8


def find_pdo(seg: Segment, pdo: model.Pdo) -> tuple[Slave, AssignedPdo] | None:
    slave = next((s for s in seg.slaves if s.node == pdo.node), None)
    if slave is None:
        return None
    index = FIRST[pdo.kind] + pdo.number - 1
    found = next((p for p in (slave.tx if pdo.kind == "tpdo" else slave.rx) if p.index == index), None)
    return None if found is None else (slave, found)


def message_id(seg: Segment | None, pdo: model.Pdo | None) -> int | None:
    if seg is None or pdo is None:
        return None
    found = find_pdo(seg, pdo)
    return None if found is None else logical_address(seg, *found)


def pdo_messages(bus: model.Bus, seg: Segment) -> list[PdoMessage]:
    out = []
    for msg in bus.messages:
        found = None if msg.pdo is None else find_pdo(seg, msg.pdo)
        if found is None:
            continue
        slave, pdo = found
        out.append(
            PdoMessage(
                msg.name,
                slave.node,
                "inputs" if pdo.direction == "tx" else "outputs",
                logical_address(seg, slave, pdo),
                -(-pdo.bits // 8),
                pdo.index,
            )
        )
    return out


def read_offset_ns(t: CycleTiming, logical: int, bitrate: int) -> int:
    """From the master's send to the moment a byte of the logical image leaves the master's port: the frames
    before it, its frame's preamble, Ethernet, EtherCAT and datagram headers, and the image's bytes before it."""
    start = 0
    before = 0  # wire bytes of the frames before its own
    for data, wire in zip(t.frames, t.frame_bytes):
        if logical < start + data or data == 0:
            head = link.PREAMBLE_SFD + link.ETHERNET_HEADER + link.ECAT_HEADER + link.DATAGRAM_HEADER
            return link.wire_ns(before + head + logical - start, bitrate)
        start += data
        before += wire
    return link.wire_ns(before, bitrate)


@dataclass(frozen=True)
class PdoTiming:
    """When a cycle's frame takes a PDO message's data and delivers it (see the module's docstring)."""

    best_ns: int  # the earliest delivery, from its take
    worst_ns: int  # the latest delivery, from the cycle's start
    read_ns: int  # an input's read, from the master's send (0: outputs, taken at the send)
    take_lo: int  # the earliest take from the cycle's start: the send, or the read as the datagram passes its slave
    take_hi: int  # the latest: the master's jitter later, and for an input the forwarding delays up to its slave


def delivery(t: CycleTiming, p: PdoMessage, position: int, cables_m: list[float], bitrate: int) -> PdoTiming:
    """One PDO message's timing in the cycle `t`. `position`: its slave's place in the line."""
    one_way = sum(link.propagation_ns(c) for c in cables_m[: position + 1])
    if p.direction == "inputs":
        read = read_offset_ns(t, p.logical, bitrate)
        best = int(t.wire_ns - read + one_way)  # floor: a lower bound
        # the frame's end has passed the slave at passed_ns: its bytes there left the master `read` after the send
        return PdoTiming(best, t.latency_ns, read, read + round(one_way), t.passed_ns[position] - t.wire_ns + read)
    return PdoTiming(int(t.wire_ns + one_way), t.passed_ns[position], 0, 0, t.jitter_ns)
