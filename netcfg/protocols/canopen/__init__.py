"""CANopen (CiA 301) over a CAN link: node ids and the predefined connection set, PDO maps against device
dictionaries, the SYNC cycle and heartbeats. The SYNC cycle's analysis is added to the link's arbitration analysis."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from netcfg import links
from netcfg.links.can import CLASSICAL_CAN
from netcfg.links.canfd import CAN_FD
from netcfg.protocols.base import Protocol, TaskCycle, Unsaid

if TYPE_CHECKING:
    from netcfg import model, runtime
    from netcfg.bus_analysis import Analysis
    from netcfg.diagnostics import Collector
    from netcfg.links.base import Link
    from netcfg.rules import BusRules
    from netcfg.sim.can_bus import CanBus
    from netcfg.sim.run import SimRun
    from netcfg.timing.load import FrameTiming


# what netcfg does not do of CANopen FD (CiA 1301), said where a command meets it
USDO_REFUSAL = (
    "bus '{bus}' is CANopen FD (link: can-fd): netcfg's live master configures devices by SDO (CiA 301), which "
    "CANopen FD (CiA 1301) replaces by the universal SDO (USDO), and netcfg has no USDO client; configure the devices "
    "with a CANopen FD tool, then hold their traffic against the analysis with netcfg verify (or simulate in PDO "
    "mode), or run the bus over link: can"
)


class Canopen(Protocol):
    dbc_never_says = (
        Unsaid(
            "the CANopen SYNC cycle (its synchronous window, the master's cycle): check of the DBC bounds each "
            "frame as check of the spec does, but does not judge the cycle",
            True,
        ),
    )

    def not_over(self, link: Link) -> str:
        return (
            f"CANopen over {link.name} is not modelled: CANopen runs over CAN (CiA 301, link: can) or CAN FD "
            "(CANopen FD, CiA 1301, link: can-fd)"
        )

    def build_notes(self, bus: model.Bus) -> tuple[str, ...]:
        if not links.of(bus).data_phase:
            return ()
        return (
            f"canopen/ (bus {bus.name}, CANopen FD): the EDS/DCF and concise DCF files are CiA 306's, with each "
            "PDO's communication and mapping objects as CiA 301 defines them (a mapping object holds up to 64 "
            "entries, CiA 301 7.5.2.36, and a CANopen FD PDO up to 64 bytes); CANopen FD's own objects (the USDO "
            "server and client parameters, the extended EMCY) and CANopen FD's device-description keys are not "
            "written: complete them with the device's CANopen FD tool",
            f"canopen/bus.yml (bus {bus.name}, CANopen FD): ros2_canopen's master configures its devices by SDO, "
            "which CANopen FD replaces by USDO: the file describes the bus's PDOs and COB-IDs, and its master "
            "cannot configure CANopen FD devices",
        )

    def run_refused(self, bus: runtime.Bus) -> str | None:
        return USDO_REFUSAL.format(bus=bus.name) if bus.link == CAN_FD.name else None

    def task_cycle(self, bus: model.Bus, node: str) -> TaskCycle | None:
        """Every node on the bus receives its SYNC: a task there may run on it."""
        return None if bus.canopen is None else TaskCycle(bus.canopen.sync_period_ns, "SYNC")

    def rules(self) -> type[BusRules]:
        from netcfg.protocols.canopen.resolve import CanopenRules

        return CanopenRules

    def offsets_unused(self, bus: model.Bus) -> str | None:
        return "a CANopen bus is analysed without offsets: SYNC, the master's loop and PDO events release frames"

    def identifiers_fixed(self, bus: model.Bus) -> str | None:
        return "CiA 301 COB-IDs, the predefined connection set its devices expect"

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
# CANopen FD's process data (CiA 1301): the same protocol over the CAN FD link, PDOs of up to 64 bytes in CAN FD
# frames (resolve.py, pdo.py); what it does not do of CANopen FD is refused where it is met (run_refused, build_notes)
CANOPEN_FD = Canopen("canopen", CAN_FD, twin_of=CANOPEN)
