"""What a run of the live master is asked to do (Plan) and what it found, node by node (Outcome, NodeOutcome):
netcfg.runtime.operate fills them in, `netcfg run` reports them."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from netcfg.runtime.canopen_master import CycleRecord, MasterRun, SetupReport
from netcfg.runtime.supervision import Event


@dataclass
class Plan:
    """What to run. `cycles` None: until stop(). `at_cycle` holds actions run after a cycle whose end is at least
    that many seconds into the cycle phase (fault drills on simulated drives: kill, EMCY)."""

    cycles: int | None
    bus_name: str | None = None
    allow_missing: bool = False
    transition_timeout_s: float = 0.5
    sdo_timeout_s: float | None = None  # None: each node's sdo_timeout_ns (runtime.json)
    drills: list[tuple[float, str, Callable[[], None]]] = field(default_factory=list)  # (at s, text, action)
    stalls: list[tuple[float, float]] = field(default_factory=list)  # (from s, to s): the master's loop pauses
    on_cycle: Callable[[CycleRecord, Outcome], None] | None = None  # e.g. a live view


@dataclass
class NodeOutcome:
    name: str
    node_id: int
    setup_ok: bool = False
    setup_error: str | None = None
    started: bool = False
    cia402: bool = False
    cia402_over: str | None = None  # "SDO", or "PDO" when its controlword and statusword are mapped
    state: str = "NOT STARTED"  # the drive's state as the master last knew it while running
    enable_path: list[str] = field(default_factory=list)  # CiA 402 states passed through on the way up
    safe_state: str | None = None  # the state after the safe stop
    stopped_at_s: float | None = None  # stop_node: when the master stopped it (cycle phase seconds)
    lost_at_s: float | None = None
    lost_silent_ms: float | None = None
    heartbeat_timeout_ms: float | None = None
    emcy: list[dict[str, Any]] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    # each boot-up while running: {"at_s", "action", "recovered_at_s", "recovery_ms", "result"}
    reboots: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class Outcome:
    bus: str
    nodes: dict[str, NodeOutcome]
    setup: SetupReport | None = None
    run: MasterRun | None = None
    events: list[tuple[float, Event]] = field(default_factory=list)  # (cycle phase seconds, event)
    drills: list[tuple[float, str]] = field(default_factory=list)
    ended_by: str = "cycles"  # cycles | stop_all:<node> | stop() | set-up
    started: bool = False
    sync_completion_ns: int | None = None
    master_jitter_ns: int = 0  # the analysed bound of how late the master's SYNC may come
    bad_emcy: int = 0
    # the CAN controller off the bus: {"detected_s", "back_s", "first_sync_s", "off_ms", "recovery_ms"}
    bus_offs: list[dict[str, Any]] = field(default_factory=list)
    # SYNC instants the master let pass (its loop stalled): {"from_s", "to_s", "missed", "instants_s"}
    sync_gaps: list[dict[str, Any]] = field(default_factory=list)
    t0: float = 0.0  # clock time the cycle phase began: the origin of every *_s time above

    def out_of_service(self, node: str, t: float) -> bool:
        """The master had stopped the node, or found it lost, by clock time t."""
        n = self.nodes[node]
        marks = [m for m in (n.stopped_at_s, n.lost_at_s) if m is not None]
        return bool(marks) and t - self.t0 >= min(marks)
