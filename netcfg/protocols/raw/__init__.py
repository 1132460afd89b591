"""Raw frames over a CAN link, classical or FD: the spec's messages as they are, arbitrating by identifier, released
at their offsets, through priority or FIFO transmit queues. Everything is the link's: the resolution rules, the
arbitration analysis and what it assumes."""

from __future__ import annotations

from netcfg.links.can import CLASSICAL_CAN
from netcfg.links.canfd import CAN_FD
from netcfg.protocols.base import Protocol

CAN = Protocol("can", CLASSICAL_CAN)
CAN_FD_RAW = Protocol("can-fd", CAN_FD)
