"""EtherCAT (IEC 61158 type 12): a master's cyclic frames through slaves in wire order, each slave's process data
from its ESI file or a CoE profile, distributed clocks, and the cycle's timing on the wire."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from netcfg.links.ethercat import ETHERCAT
from netcfg.protocols.base import JointEntries, Protocol, TaskCycle

if TYPE_CHECKING:
    from netcfg import model, runtime
    from netcfg.bus_analysis import Analysis
    from netcfg.diagnostics import Collector
    from netcfg.rules import BusRules


class EtherCatProtocol(Protocol):
    def rules(self) -> type[BusRules]:
        from netcfg.protocols.ethercat.resolve import EthercatRules

        return EthercatRules

    def task_cycle(self, bus: model.Bus, node: str) -> TaskCycle | None:
        """The master sends each cycle's frames on its own clock, and a DC slave's SYNC0 fires on the cycle's: a task
        of either may run in step with them (netcfg.protocols.ethercat.analysis.task_starts)."""
        from netcfg.protocols.ethercat.analysis import task_starts

        seg = bus.ethercat
        if seg is None:
            return None
        if node == seg.master:
            return TaskCycle(seg.cycle_ns, "EtherCAT cycle", seg.master_jitter_ns)
        early, late = task_starts(seg).get(node, (0, -1))
        return TaskCycle(seg.sync0_cycle_ns, "SYNC0", late - early) if late >= early else None

    def sent_as_tasks_end(self, bus: model.Bus) -> bool:
        """A PDO rides the master's cyclic frame: a task writes its data, the next frame takes it."""
        return False

    def analyze(self, m: model.Model, bus: model.Bus, diags: Collector, acc: Analysis) -> dict[str, Any]:
        from netcfg.protocols.ethercat.analysis import analyze_segment

        return analyze_segment(m, bus, diags, acc)

    def joint_entries(self, bus: model.Bus, node: str, axis: int) -> JointEntries | None:
        from netcfg.protocols.ethercat.joints import joint_entries

        return joint_entries(bus, node, axis)

    def assumptions(self, bus: model.Bus, fifo_nodes: tuple[str, ...]) -> list[str]:
        from netcfg.protocols.ethercat.analysis import ASSUMES

        return list(ASSUMES)

    def runtime_section(self, bus: model.Bus) -> dict[str, Any]:
        from netcfg.protocols.ethercat.runtime_section import runtime_section

        return {"ethercat": runtime_section(bus, bus.ethercat)}

    def sim_events(self, bus: runtime.Bus) -> tuple[tuple[str, int], ...]:
        return () if bus.ethercat is None else ((f"EtherCAT cycle of bus '{bus.name}'", bus.ethercat["cycle_ns"]),)


ETHERCAT_PROTOCOL = EtherCatProtocol("ethercat", ETHERCAT)
