"""The link layer: one object per physical bus (`LINKS`), asked for frame timing, arbitration and the error terms.

A bus's link is named by model.Bus.link; `of(bus)` is the one lookup. A new link is one module with one `Link`
subclass and one line below.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from netcfg.links.base import Link
from netcfg.links.can import CLASSICAL_CAN
from netcfg.links.canfd import CAN_FD
from netcfg.links.ethercat import ETHERCAT
from netcfg.links.ethernet import ETHERNET

if TYPE_CHECKING:
    from netcfg import model

__all__ = ["LINKS", "Link", "of"]

LINKS: dict[str, Link] = {link.name: link for link in (CLASSICAL_CAN, CAN_FD, ETHERNET, ETHERCAT)}


def of(bus: model.Bus) -> Link:
    return LINKS[bus.link]
