"""What a protocol over a link owns, as one object every command asks: its resolution rules, its analysis of a bus,
what that analysis assumes, and what the bus can do under it (offsets, identifier tuning); what the artifacts take of
it (its own frames, its schedule, what a DBC cannot say, its runtime.json section), what verify expects of a log of
it, and its part of a simulation (its driver, gate, master, events, whole run). The default is a protocol that adds
nothing to its link: raw frames, arbitrating by identifier, released at their offsets, run free in the simulator."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from netcfg.links.base import Link

if TYPE_CHECKING:
    from netcfg import model, runtime
    from netcfg.bus_analysis import Analysis, BusFrames
    from netcfg.diagnostics import Collector
    from netcfg.rules import BusRules
    from netcfg.sim.can_bus import CanBus
    from netcfg.sim.run import SimRun
    from netcfg.sim.whole_run import WholeRunScenario
    from netcfg.timing.ftt_schedule import SrtEntry
    from netcfg.timing.load import FrameTiming


@dataclass(frozen=True)
class OwnFrame:
    """A frame the protocol itself sends on a bus besides the spec's messages (FTT-CAN's trigger message): the DBC
    lists it, and every node that hears it gets a C header."""

    name: str
    id: int
    extended: bool
    size: int
    sender: str
    receivers: tuple[str, ...]
    period_ns: int
    field: str  # the one unsigned field spanning its payload
    comment: str
    fd: bool = False  # a CAN FD frame with bit-rate switch (FTT-CAN's trigger message on a CAN FD link)


@dataclass(frozen=True)
class Unsaid:
    """Something of a bus's timing its DBC cannot say; bounds_kept: check of the DBC still gives every message the
    spec's bound (what is lost is judged beside the bounds)."""

    what: str
    bounds_kept: bool


# side -> interface -> (the PDO, the entry's name, bits, signed): Protocol.joint_entries
JointEntries = dict[str, dict[str, tuple[str, str, int, bool]]]


@dataclass(frozen=True)
class TaskCycle:
    """A bus's cycle that tasks may run on: every `period_ns`, each task its offset after the cycle's start."""

    period_ns: int
    name: str  # as messages say it: "SYNC", "EtherCAT cycle"
    jitter_ns: int = 0  # how far apart the node's tasks may start in it (a master's send jitter, SYNC0's precision)


class Protocol:
    # a node speaking an actuator's own protocol (netcfg.devices.actuator_profile) may sit on a bus of it: only where
    # the protocol adds nothing to the link's frames (no SYNC, no schedule, no identifier scheme of its own)
    carries_actuators = False
    dbc_never_says: tuple[Unsaid, ...] = ()  # what a DBC cannot say of any bus of the protocol

    def __init__(self, name: str, link: Link, twin_of: Protocol | None = None) -> None:
        self.name = name  # as the spec's `protocol:` says it
        self.link = link  # the link that name stands for
        # the same protocol over each link it runs on (CANopen over CAN and CAN FD): one list its twins share
        self.family: list[Protocol] = twin_of.family if twin_of is not None else []
        self.family.append(self)

    def over(self, link: Link) -> Protocol | str:
        """The protocol as it runs over `link` (a spec's `link:`): its twin on that link, or why netcfg does not
        model it there."""
        twin = next((p for p in self.family if p.link is link), None)
        return twin if twin is not None else self.not_over(link)

    def not_over(self, link: Link) -> str:
        """Why netcfg does not model the protocol over `link` (the error at a spec's `link:` key)."""
        return f"{self.name} runs on {self.link.name} here; netcfg does not model it over {link.name}"

    def sent_as_tasks_end(self, bus: model.Bus) -> bool:
        """Whether a task on a message's producer sends it as it finishes (netcfg.resolve.flows' sent_by); False
        where the protocol's own cycle carries every message, taking the data it finds when it passes."""
        return True

    def task_cycle(self, bus: model.Bus, node: str) -> TaskCycle | None:
        """The cycle a task of `node` may run on (`sync: true`, its offset after each cycle's start), or None where
        the bus gives that node none."""
        return None

    def rules(self) -> type[BusRules]:
        """The resolver's hooks for a bus of this protocol: the link's rules unless the protocol adds its own."""
        return self.link.rules()

    def analyze(self, m: model.Model, bus: model.Bus, diags: Collector, acc: Analysis) -> dict[str, Any]:
        """The bus's row of the report (DESIGN.md's `buses[]`), its problems added to `diags`."""
        from netcfg.links.arbitration import analyze_arbitrated

        return analyze_arbitrated(m, bus, diags, acc, self)

    def assumptions(self, bus: model.Bus, fifo_nodes: tuple[str, ...]) -> list[str]:
        """What the bounds of a bus of this protocol rest on, in the user's terms."""
        from netcfg.links.arbitration import assumptions

        return assumptions(bus, fifo_nodes)

    def offsets_unused(self, bus: model.Bus) -> str | None:
        """None when a periodic message's offset places its releases on its sender's clock, as the CAN offset
        analysis (timing.can_offsets) takes them; else why the analysis of this bus cannot use an offset."""
        return self.link.offsets_unused()

    def identifiers_fixed(self, bus: model.Bus) -> str | None:
        """None when the bus's identifiers are free priorities that `netcfg tune` may reorder; else why not."""
        return self.link.identifiers_fixed()

    def offset_ignored(self, m: model.Model, bus: model.Bus, msg: model.Message) -> tuple[str, str] | None:
        """(why, what to do) when the analysis that bounds `msg` cannot use the offset the spec gave it; None when it
        has none or it is used (release_offsets takes it)."""
        if msg.offset_ns is None or msg.offset_auto or msg.implicit:  # SYNC and heartbeats: netcfg's own
            return None
        if (why := self.offsets_unused(bus)) is not None:
            return why, "its bounds hold for any offset; drop it"
        from netcfg.timing import flows

        if senders := flows.sending_tasks(m, msg):
            return (
                f"task '{senders[0]}' sends it as it finishes (a step before it in a flow), so the task's end "
                "releases it",
                f"drop the offset, or give the task '{senders[0]}' the offset instead",
            )
        return None

    # -- what the artifacts and the run-time side ask of a bus of this protocol
    def own_frames(self, bus: model.Bus) -> tuple[OwnFrame, ...]:
        """The frames the protocol sends on the bus besides the spec's messages."""
        return ()

    def scheduled(self, bus: model.Bus) -> dict[str, SrtEntry]:
        """The schedule's entry (FTT id, period and init in cycles) of each message and trigger the protocol
        schedules, by name, as the analysis built it; {}: the protocol schedules nothing (the C headers ask)."""
        return {}

    def dbc_unsaid(self, m: model.Model, bus: model.Bus) -> tuple[Unsaid, ...]:
        """What of the bus's timing under this protocol a DBC cannot say (netcfg.emit.dbc.unsaid): by default what
        it can never say on any bus of it (dbc_never_says)."""
        return self.dbc_never_says

    def runtime_section(self, bus: model.Bus) -> dict[str, Any]:
        """runtime.json's keys of the protocol's own on the bus's entry (netcfg.emit.runtime_json), e.g. FTT-CAN's
        `ftt` (its schedule); {}: none (every bus has `ftt: null`)."""
        return {}

    def build_notes(self, bus: model.Bus) -> tuple[str, ...]:
        """What the files `netcfg build` writes for the bus cannot carry of it under this protocol over its link
        (build prints them with the DBC's notes); (): nothing."""
        return ()

    def run_refused(self, bus: runtime.Bus) -> str | None:
        """Why `netcfg run`'s live master (and the simulator's SDO mode, which runs it) cannot drive the bus, as the
        error to print; None: it can."""
        return None

    # -- what netcfg.verify expects of a recorded log of a bus of this protocol (runtime.json's bus)
    def log_frames(self, bus: runtime.Bus) -> tuple[runtime.Message, ...]:
        """The frames the protocol sends besides runtime.json's messages, as messages the log is checked for."""
        return ()

    def response_reference(self, bus: runtime.Bus) -> tuple[int, int] | None:
        """(identifier, us): the frame a response on the bus is measured from (CANopen's SYNC, FTT-CAN's trigger
        message), and what is added back to its logged end to reach the analysis' reference; None: each frame's
        response is its own."""
        return None

    # -- what the simulator asks of a bus of this protocol (runtime.json's bus): its drivers read runtime.json and see
    #    the run through netcfg.sim.run.SimRun, never the scenario
    def sim_master(self, bus: runtime.Bus) -> str | None:
        """The node whose cycle a synchronised run starts at 0, on a clock that does not drift (FTT-CAN's master,
        CANopen's SYNC producer); None: the protocol has none."""
        return None

    def sim_events(self, bus: runtime.Bus) -> tuple[tuple[str, int], ...]:
        """(what, period in ns) of the events the protocol's driver makes on the bus (an FTT-CAN elementary cycle, a
        SYNC), for the estimate of a run's work (netcfg.sim.limits)."""
        return ()

    def sim_gated(self, msg: runtime.Message) -> bool:
        """A synchronised run holds the message's frames until the driver's gate lets them go (FTT-CAN's
        asynchronous window, netcfg.sim.can_bus's gate)."""
        return False

    def sim_driver(self, sc: SimRun, bus: runtime.Bus, can: CanBus) -> object | None:
        """The bus's driver in a synchronised run (FTT-CAN's master, CANopen's master cycle), built once its
        messages' sources are on `can`; None: the bus's frames run free."""
        return None

    def sim_whole_run(self, sc: WholeRunScenario) -> Callable[[], None] | None:
        """The run computed whole, as arrays, where the protocol's whole-run path covers it (called instead of the
        event path; netcfg.sim.whole_run.Undecided sends it back there); None: not covered."""
        return None

    def joint_entries(self, bus: model.Bus, node: str, axis: int) -> JointEntries | None:
        """For a protocol whose drives' process data is no message (EtherCAT's image): what of node's axis carries
        each joint interface, by side ("command", "state") and interface ("position", ...), as (PDO, entry name,
        bits, signed); None: a joint on the bus names its messages' signals."""
        return None

    # -- hooks the arbitration analysis of a CAN bus calls (netcfg.links.arbitration)
    def answers(self, m: model.Model, bus: model.Bus) -> dict[str, tuple[str, int]]:
        """Each message of the bus that a node sends in answer to another message of the bus -> (that message,
        the shortest time from its frame's end to the answer's queueing): the arbitration analysis holds each pair
        as one transaction (timing.can_transactions). None by default: every message is released on its own."""
        return {}

    def overhead(self, bus: model.Bus) -> tuple[int, int] | None:
        """(time on the wire, period) in ns of a frame the protocol adds to the spec's messages every period."""
        return None

    def bound_messages(
        self, m: model.Model, bus: model.Bus, frames: BusFrames, diags: Collector, acc: Analysis
    ) -> dict[str, Any] | None:
        """The protocol's own bounds of the bus's messages, written into `frames.rows` with their verdicts, and its
        report section; None: the arbitration analysis' bounds are the messages' (the caller writes them)."""
        return None

    def check_tx_queues(self, m: model.Model, bus: model.Bus, rows: list[dict[str, Any]], diags: Collector) -> None:
        """What the protocol's analyses require of the nodes' FIFO transmit queues (`rows`: tx_queues)."""

    def extend(
        self, m: model.Model, bus: model.Bus, timings: dict[str, FrameTiming], diags: Collector, acc: Analysis
    ) -> dict[str, Any]:
        """Sections the protocol adds to the bus's report row after the messages' bounds."""
        return {}

    def check_overload(
        self, m: model.Model, bus: model.Bus, timings: dict[str, FrameTiming], worst: float, diags: Collector
    ) -> None:
        """An error when the bus's worst-case load (`worst`, the messages' share) exceeds its capacity."""
        from netcfg.links.arbitration import check_overload

        check_overload(m, bus, timings, worst, diags)
