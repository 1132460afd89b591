"""UDP over switched Ethernet (seed 001): one datagram per message with a one-byte application id, each message's
path through the switches' egress queues analysed end to end."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from netcfg.links.ethernet import ETHERNET
from netcfg.protocols.base import Protocol

if TYPE_CHECKING:
    from netcfg import model
    from netcfg.bus_analysis import Analysis
    from netcfg.diagnostics import Collector
    from netcfg.rules import BusRules


class Udp(Protocol):
    def rules(self) -> type[BusRules]:
        from netcfg.protocols.udp.resolve import UdpRules

        return UdpRules

    def analyze(self, m: model.Model, bus: model.Bus, diags: Collector, acc: Analysis) -> dict[str, Any]:
        from netcfg.protocols.udp.analysis import analyze_ethernet

        return analyze_ethernet(m, bus, diags, acc)

    def assumptions(self, bus: model.Bus, fifo_nodes: tuple[str, ...]) -> list[str]:
        from netcfg.protocols.udp.analysis import ASSUMES

        return list(ASSUMES)


UDP = Udp("ethernet-udp", ETHERNET)
