"""Raw frames over a CAN link, classical or FD: the spec's messages as they are, arbitrating by identifier, released
at their offsets, through priority or FIFO transmit queues. Everything is the link's: the resolution rules, the
arbitration analysis and what it assumes."""

from __future__ import annotations

from netcfg.links.base import Link
from netcfg.links.can import CLASSICAL_CAN
from netcfg.links.canfd import CAN_FD
from netcfg.protocols.base import Protocol


class Raw(Protocol):
    carries_actuators = True  # raw frames are what an actuator's own protocol sends

    def over(self, link: Link) -> Protocol | str:
        """Raw frames go over either CAN link: `protocol: can` with `link: can-fd` is the can-fd protocol."""
        twin = next((p for p in (CAN, CAN_FD_RAW) if p.link is link), None)
        return twin if twin is not None else super().over(link)


CAN = Raw("can", CLASSICAL_CAN)
CAN_FD_RAW = Raw("can-fd", CAN_FD)
