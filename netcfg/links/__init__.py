"""The link layer: one object per physical bus (`LINKS`), asked for frame timing, arbitration and the error terms.

A bus's link is named by model.Bus.link; `of(bus)` is the one lookup. A new link is one module with one `Link`
subclass and one line in `_registry` below.

The registry loads on first use (PEP 562, as netcfg.runtime's names do), so that importing one module of the layer
does not load the others: the links and their resolution rules need the compiler, while netcfg.links.pycan_frames
(the CAN links' frames as python-can carries them) imports nothing of netcfg, and the runtime, which imports
without the compiler, hands its frames to python-can through it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from netcfg.links.base import Link

    LINKS: dict[str, Link]

__all__ = ["LINKS", "Link", "of"]

_LINKS: dict[str, Link] = {}


def _registry() -> dict[str, Link]:
    if not _LINKS:
        from netcfg.links.can import CLASSICAL_CAN
        from netcfg.links.canfd import CAN_FD
        from netcfg.links.ethercat import ETHERCAT
        from netcfg.links.ethernet import ETHERNET

        _LINKS.update({link.name: link for link in (CLASSICAL_CAN, CAN_FD, ETHERNET, ETHERCAT)})
    return _LINKS


class OnALink(Protocol):
    """A bus as the model or runtime.json has it: both name its link."""

    @property
    def link(self) -> str: ...


def of(bus: OnALink) -> Link:
    return (_LINKS or _registry())[bus.link]


def __getattr__(name: str) -> Any:
    if name == "LINKS":
        value: Any = _registry()
    elif name == "Link":
        from netcfg.links.base import Link as value
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value  # later look-ups find it directly
    return value
