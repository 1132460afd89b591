"""Full-duplex switched Ethernet (seed 001): frames do not arbitrate, they queue at each switch's egress port; a bit
error drops a frame rather than repeating it, so the CAN error model does not apply."""

from __future__ import annotations

from typing import TYPE_CHECKING

from netcfg.links.base import Link
from netcfg.timing.load import FrameTiming, udp_timing

if TYPE_CHECKING:
    from netcfg import model


class Ethernet(Link):
    name = "ethernet"
    title = "Ethernet"
    arbitrates = False
    switched = True

    def frame_timing(self, msg: model.Message, bus: model.Bus) -> FrameTiming:
        return udp_timing(msg, bus.bitrate)

    def offsets_unused(self) -> str | None:
        return "the Ethernet analysis takes every sender's releases at any phase"

    def identifiers_fixed(self) -> str | None:
        return "an Ethernet message's id names it and gives it no priority: the switches queue frames in order"


ETHERNET = Ethernet()
