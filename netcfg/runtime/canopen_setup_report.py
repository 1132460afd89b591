"""What the CANopen set-up over SDO (netcfg.runtime.canopen_setup) found: each PDO as read back, each node's
set-up with the step it reached and what went wrong, and the report of a whole bus."""

from __future__ import annotations

from dataclasses import dataclass

from netcfg import cia301


@dataclass(frozen=True)
class PdoReadback:
    """One PDO as read back from the node over SDO."""

    kind: str  # "rpdo" | "tpdo"
    number: int
    message: str | None  # the runtime message it carries; None for a PDO the spec does not use
    cob_id: int  # the raw 0x14xx/0x18xx sub 1 value, flag bits included
    transmission: int | None
    inhibit_100us: int | None
    event_timer_ms: int | None
    sync_start: int | None
    entries: tuple[tuple[int, int, int], ...]  # (index, sub, bits)

    @property
    def valid(self) -> bool:
        return not self.cob_id & cia301.PDO_INVALID

    @property
    def can_id(self) -> int:
        return cia301.pdo_can_id(self.cob_id)[0]


@dataclass(frozen=True)
class NodeSetup:
    """The set-up of one node: ok, or an error saying what went wrong and what to do."""

    node: str
    node_id: int
    ok: bool
    error: str | None
    step: str  # the step reached: identity, pre-operational, <PDO> ..., read-back, start, done
    abort_code: int | None = None
    identity: tuple[int, int] | None = None  # (vendor id, product code) read from 0x1018
    pdos: tuple[PdoReadback, ...] = ()
    interpolation: tuple[int, int] | None = None  # 0x60C2 (value, index) read back
    started: bool = False
    notes: tuple[str, ...] = ()
    start_up: tuple[tuple[int, int, int], ...] = ()  # the start-up SDO writes read back: (index, sub, value)

    def __str__(self) -> str:
        if self.ok:
            started = "started (OPERATIONAL)" if self.started else "configured, not started"
            return f"{self.node} (node {self.node_id}): ok, {len(self.pdos)} PDOs verified, {started}"
        return f"{self.node} (node {self.node_id}): FAILED at {self.step}: {self.error}"


@dataclass(frozen=True)
class SetupReport:
    bus: str
    nodes: tuple[NodeSetup, ...]

    @property
    def ok(self) -> bool:
        return all(n.ok for n in self.nodes)

    @property
    def failed(self) -> tuple[NodeSetup, ...]:
        return tuple(n for n in self.nodes if not n.ok)

    def node(self, name: str) -> NodeSetup:
        for n in self.nodes:
            if n.node == name:
                return n
        raise KeyError(f"no node named {name!r} was set up on bus {self.bus!r}")

    def __str__(self) -> str:
        head = f"CANopen set-up of bus {self.bus}: {sum(n.ok for n in self.nodes)}/{len(self.nodes)} nodes ok"
        return "\n".join([head, *(f"  {n}" for n in self.nodes)])
