"""FTT-CAN over a CAN link (seed 002): a master's trigger message opens every elementary cycle, whose synchronous
window it schedules and whose asynchronous window arbitrates as CAN. The windows' analysis replaces the messages'
bounds of the link's arbitration analysis, which stays in the report as their plain-CAN figure. Beside the analysis:
the SRT tables (srt.py), runtime.json's section (runtime_section.py), the trigger message a log holds (log.py) and
the simulator's master and whole run (sim.py, sim_whole_run.py), which read runtime.json alone."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from netcfg.links.can import CLASSICAL_CAN
from netcfg.links.canfd import CAN_FD
from netcfg.protocols.base import OwnFrame, Protocol, Unsaid

if TYPE_CHECKING:
    from netcfg import model, runtime
    from netcfg.bus_analysis import Analysis, BusFrames
    from netcfg.diagnostics import Collector
    from netcfg.links.base import Link
    from netcfg.rules import BusRules
    from netcfg.sim.can_bus import CanBus
    from netcfg.sim.run import SimRun
    from netcfg.sim.whole_run import WholeRunScenario
    from netcfg.timing.ftt_schedule import SrtEntry
    from netcfg.timing.load import FrameTiming


class Ftt(Protocol):
    dbc_never_says = (
        Unsaid(
            "the FTT-CAN elementary cycle and its windows: check of the DBC analyses its frames as free-running "
            "CAN, trigger message included, so its bounds are not the bus's",
            False,
        ),
    )

    def not_over(self, link: Link) -> str:
        return (
            f"FTT-CAN over {link.name} is not modelled: its trigger message and windows are CAN frames arbitrating "
            "by identifier; write link: can or link: can-fd"
        )

    def rules(self) -> type[BusRules]:
        from netcfg.protocols.ftt.resolve import FttRules

        return FttRules

    def identifiers_fixed(self, bus: model.Bus) -> str | None:
        return (
            "the master schedules the synchronous window, where offset: auto places the messages, and tune's "
            "search is not the asynchronous window's analysis"
        )

    def offset_ignored(self, m: model.Model, bus: model.Bus, msg: model.Message) -> tuple[str, str] | None:
        if msg.window == "sync":  # the schedule takes a synchronous message's offset as its first EC
            return None
        ignored = super().offset_ignored(m, bus, msg)
        if ignored is None and msg.window == "async" and msg.offset_ns is not None and not msg.offset_auto:
            return (
                "FTT-CAN's asynchronous window is analysed with every release at any phase",
                "drop the offset, or make it synchronous (window: sync), where the offset is its first EC",
            )
        return ignored

    def assumptions(self, bus: model.Bus, fifo_nodes: tuple[str, ...]) -> list[str]:
        from netcfg.protocols.ftt.analysis import ASSUMES

        return [*super().assumptions(bus, fifo_nodes), *ASSUMES]

    def overhead(self, bus: model.Bus) -> tuple[int, int] | None:
        from netcfg.protocols.ftt.analysis import bus_tm_and_ec

        return bus_tm_and_ec(bus)  # the trigger message, once per EC

    def bound_messages(
        self, m: model.Model, bus: model.Bus, frames: BusFrames, diags: Collector, acc: Analysis
    ) -> dict[str, Any] | None:
        from netcfg.protocols.ftt.analysis import bound_messages

        return bound_messages(m, bus, frames, diags, acc)

    def check_tx_queues(self, m: model.Model, bus: model.Bus, rows: list[dict[str, Any]], diags: Collector) -> None:
        from netcfg.protocols.ftt.analysis import check_tx_queues

        check_tx_queues(m, bus, rows, diags)

    def own_frames(self, bus: model.Bus) -> tuple[OwnFrame, ...]:
        assert bus.ftt is not None  # an FTT-CAN bus: the resolver filled its section
        master = bus.ftt.master
        return (
            OwnFrame(  # the trigger message, at every EC start; its payload is the EC-schedule
                name=f"{bus.name}_TM",
                id=bus.ftt.tm_id,
                extended=bus.ftt.tm_extended,
                size=bus.ftt.tm_size,
                sender=master,
                receivers=tuple(sorted(n for n in bus.nodes if n != master)),
                period_ns=bus.ftt.ec_ns,
                field="ec_schedule",  # bit i (little-endian over the tm_size bytes) announces FTT id i
                comment="FTT-CAN trigger message: bit i of ec_schedule = FTT id i due in this elementary cycle",
                fd=bus.ftt.tm_fd,
            ),
        )

    def scheduled(self, bus: model.Bus) -> dict[str, SrtEntry]:
        sched = bus.ftt_schedule
        assert sched is not None  # the analysis built it
        return {e.name: e for e in sched.entries}

    def runtime_section(self, bus: model.Bus) -> dict[str, Any]:
        from netcfg.protocols.ftt.runtime_section import runtime_section

        return {"ftt": runtime_section(bus)}

    def log_frames(self, bus: runtime.Bus) -> tuple[runtime.Message, ...]:
        from netcfg.protocols.ftt.log import trigger_message

        return (trigger_message(bus),)

    def response_reference(self, bus: runtime.Bus) -> tuple[int, int] | None:
        from netcfg.protocols.ftt.log import response_reference

        return response_reference(bus)

    def sim_master(self, bus: runtime.Bus) -> str | None:
        return None if bus.ftt is None else bus.ftt.master

    def sim_events(self, bus: runtime.Bus) -> tuple[tuple[str, int], ...]:
        return () if bus.ftt is None else ((f"elementary cycle of bus '{bus.name}'", bus.ftt.ec_ns),)

    def sim_gated(self, msg: runtime.Message) -> bool:
        return msg.window != "sync"  # the master sends the synchronous ones in their window

    def sim_driver(self, sc: SimRun, bus: runtime.Bus, can: CanBus) -> object | None:
        from netcfg.protocols.ftt.sim import FttMaster

        return FttMaster(sc, bus, can)

    def sim_whole_run(self, sc: WholeRunScenario) -> Callable[[], None] | None:
        from functools import partial

        from netcfg.protocols.ftt import sim_whole_run  # only here: its classes cost every run's start

        plan = sim_whole_run.plan(sc)
        return None if plan is None else partial(sim_whole_run.run, sc, plan)

    def check_overload(
        self, m: model.Model, bus: model.Bus, timings: dict[str, FrameTiming], worst: float, diags: Collector
    ) -> None:
        from netcfg.protocols.ftt.analysis import check_overload

        check_overload(m, bus, timings, worst, diags)


FTT = Ftt("ftt-can", CLASSICAL_CAN)
# the same protocol over the CAN FD link (`link: can-fd`): every frame of the EC, trigger message included (tm.py),
# is timed at the link's two rates
FTT_FD = Ftt("ftt-can", CAN_FD, twin_of=FTT)
