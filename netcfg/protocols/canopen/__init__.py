"""CANopen (CiA 301) over a CAN link: node ids and the predefined connection set, PDO maps against device
dictionaries, the SYNC cycle and heartbeats. The SYNC cycle's analysis is added to the link's arbitration analysis."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from netcfg.links.can import CLASSICAL_CAN
from netcfg.protocols.base import Protocol, Unsaid

if TYPE_CHECKING:
    from netcfg import model, runtime
    from netcfg.bus_analysis import Analysis
    from netcfg.diagnostics import Collector
    from netcfg.links.base import Link
    from netcfg.rules import BusRules
    from netcfg.sim.can_bus import CanBus
    from netcfg.sim.run import SimRun
    from netcfg.timing.load import FrameTiming


class Canopen(Protocol):
    def not_over(self, link: Link) -> str:
        return (
            f"CANopen over {link.name} is not modelled: CANopen FD (CiA 1301) has PDOs of up to 64 bytes and USDO "
            "in place of SDO, while netcfg's CANopen (its PDO checks, EDS/DCF and live master) is CiA 301's on "
            "classical CAN; write link: can"
        )

    def rules(self) -> type[BusRules]:
        from netcfg.protocols.canopen.resolve import CanopenRules

        return CanopenRules

    def offsets_unused(self, bus: model.Bus) -> str | None:
        return "a CANopen bus is analysed without offsets: SYNC, the master's loop and PDO events release frames"

    def identifiers_fixed(self, bus: model.Bus) -> str | None:
        return "CiA 301 COB-IDs, the predefined connection set its devices expect"

    def dbc_unsaid(self, m: model.Model, bus: model.Bus) -> tuple[Unsaid, ...]:
        return (
            Unsaid(
                "the CANopen SYNC cycle (its synchronous window, the master's cycle): check of the DBC bounds each "
                "frame as check of the spec does, but does not judge the cycle",
                True,
            ),
        )

    def response_reference(self, bus: runtime.Bus) -> tuple[int, int] | None:
        # a synchronous TPDO's response counts from the SYNC before it (netcfg.timing.canopen_sync)
        return None if bus.canopen is None else (bus.canopen.sync_id, 0)

    def sim_master(self, bus: runtime.Bus) -> str | None:
        return None if bus.canopen is None else bus.canopen.sync_producer

    def sim_events(self, bus: runtime.Bus) -> tuple[tuple[str, int], ...]:
        return () if bus.canopen is None else ((f"SYNC of bus '{bus.name}'", bus.canopen.sync_period_ns),)

    def sim_driver(self, sc: SimRun, bus: runtime.Bus, can: CanBus) -> object | None:
        if bus.canopen is None:
            return None
        from netcfg.sim.canopen import CanopenMaster

        return CanopenMaster(sc, bus, can)

    def extend(
        self, m: model.Model, bus: model.Bus, timings: dict[str, FrameTiming], diags: Collector, acc: Analysis
    ) -> dict[str, Any]:
        from netcfg.bus_analysis import frame_times
        from netcfg.protocols.canopen.analysis import analyze_sync

        return {"sync": analyze_sync(m, bus, frame_times(timings), diags, acc)}


CANOPEN = Canopen("canopen", CLASSICAL_CAN)
