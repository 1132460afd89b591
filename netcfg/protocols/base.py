"""What a protocol over a link owns, as one object every command asks: its resolution rules, its analysis of a bus,
what that analysis assumes, and what the bus can do under it (offsets, identifier tuning). The default is a protocol
that adds nothing to its link: raw frames, arbitrating by identifier, released at their offsets."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from netcfg.links.base import Link

if TYPE_CHECKING:
    from netcfg import model
    from netcfg.bus_analysis import Analysis
    from netcfg.diagnostics import Collector
    from netcfg.rules import BusRules
    from netcfg.timing.load import FrameTiming


# side -> interface -> (the PDO, the entry's name, bits, signed): Protocol.joint_entries
JointEntries = dict[str, dict[str, tuple[str, str, int, bool]]]


class Protocol:
    # a node speaking an actuator's own protocol (netcfg.devices.actuator_profile) may sit on a bus of it: only where
    # the protocol adds nothing to the link's frames (no SYNC, no schedule, no identifier scheme of its own)
    carries_actuators = False

    def __init__(self, name: str, link: Link) -> None:
        self.name = name  # as the spec's `protocol:` says it
        self.link = link  # the link that name stands for

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

    def joint_entries(self, bus: model.Bus, node: str, axis: int) -> JointEntries | None:
        """For a protocol whose drives' process data is no message (EtherCAT's image): what of node's axis carries
        each joint interface, by side ("command", "state") and interface ("position", ...), as (PDO, entry name,
        bits, signed); None: a joint on the bus names its messages' signals."""
        return None

    # -- hooks the arbitration analysis of a CAN bus calls (netcfg.links.arbitration)
    def overhead(self, bus: model.Bus) -> tuple[int, int] | None:
        """(time on the wire, period) in ns of a frame the protocol adds to the spec's messages every period."""
        return None

    def bound_messages(
        self,
        m: model.Model,
        bus: model.Bus,
        rows: list[dict[str, Any]],
        timings: dict[str, FrameTiming],
        worst: float,
        diags: Collector,
        acc: Analysis,
    ) -> dict[str, Any] | None:
        """The protocol's own bounds of the bus's messages, written into `rows` with their verdicts, and its report
        section; None: the arbitration analysis' bounds are the messages' (the caller writes them)."""
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
