"""The protocol layer: one object per protocol of the spec language (`PROTOCOLS`), over the link it runs on.

Every command asks a bus's protocol (`of(bus)`) what the bus can do (offsets, identifier tuning), how it is
resolved and analysed, instead of deciding by its name. A new protocol is one package with one `Protocol` and one
line below; docs/adding-a-protocol.md shows the files.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from netcfg.protocols.base import Protocol
from netcfg.protocols.canopen import CANOPEN
from netcfg.protocols.ethercat import ETHERCAT_PROTOCOL
from netcfg.protocols.ftt import FTT
from netcfg.protocols.raw import CAN, CAN_FD_RAW
from netcfg.protocols.udp import UDP

if TYPE_CHECKING:
    from netcfg import model, runtime

__all__ = ["PROTOCOLS", "Protocol", "of", "over", "release_offsets"]

PROTOCOLS: dict[str, Protocol] = {p.name: p for p in (CAN, CAN_FD_RAW, CANOPEN, FTT, UDP, ETHERCAT_PROTOCOL)}


def of(bus: model.Bus | runtime.Bus) -> Protocol:
    """The protocol of a bus of the model or of runtime.json (the simulator's and verify's view)."""
    return PROTOCOLS[bus.protocol]


def over(protocol: str, link: str | None) -> Protocol | str:
    """The protocol a spec's bus names (`protocol:`, and `link:` where it differs from the protocol's own), or why
    netcfg does not model that protocol over that link."""
    from netcfg.links import LINKS

    named = PROTOCOLS[protocol]
    return named if link is None else named.over(LINKS[link])


def release_offsets(m: model.Model, bus: model.Bus) -> dict[str, tuple[str, int]]:
    """Messages released at a fixed offset of their sender's clock -> (sender, offset), where the bus's protocol
    uses offsets (Protocol.offsets_unused says why it does not)."""
    if of(bus).offsets_unused(bus) is not None:
        return {}
    from netcfg.links.arbitration import offset_releases

    return offset_releases(m, bus)
