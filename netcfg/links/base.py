"""What a link (the physical bus: classical CAN, CAN FD, switched Ethernet) owns: how long its frames take, whether
they arbitrate by identifier, how bit errors reach them, and what its analysis assumes of the wire. Every command
asks the bus's link (`netcfg.links.of`) instead of deciding by the protocol's name."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:
    from netcfg import model
    from netcfg.rules import BusRules
    from netcfg.timing.load import FrameTiming


class Link:
    name: ClassVar[str] = ""
    title: ClassVar[str] = ""  # as the user says it
    arbitrates: ClassVar[bool] = True  # frames arbitrate bit by bit on their identifier (ISO 11898-1)
    data_phase: ClassVar[bool] = False  # a second, faster bit rate for the data field (CAN FD)
    switched: ClassVar[bool] = False  # frames go through switches to nodes' addresses (IP), not to every node

    def rules(self) -> type[BusRules]:
        """What the link requires of a bus and its frames at resolution (bit rate, payload, identifiers)."""
        from netcfg.rules import BusRules

        return BusRules

    def frame_timing(self, msg: model.Message, bus: model.Bus) -> FrameTiming:
        """One message's frame on this link: its bits and worst-case and best-case times on the wire."""
        raise NotImplementedError

    def bits_per_second(self, bus: model.Bus, timings: dict[str, FrameTiming]) -> float | None:
        """The bits the bus's frames put on the wire per second where they outnumber the nominal rate's share
        (a data phase above it); None when the utilisation at the nominal rate counts them."""
        return None

    def offsets_unused(self) -> str | None:
        """Why the link's analysis cannot place a message's releases at its offset; None: it can."""
        return None

    def identifiers_fixed(self) -> str | None:
        """Why a message's identifier is no priority `tune` may choose on this link; None: it is."""
        return None
