"""Classical CAN (ISO 11898-1): the link and its rules (the bit rate, the 8-byte payload and unique identifiers on the
bus). The protocols over CAN (CANopen, FTT-CAN) build on these rules."""

from __future__ import annotations

from netcfg import model
from netcfg.links.base import Link
from netcfg.rules import BusRules
from netcfg.spec import schema
from netcfg.spec.source import Path
from netcfg.timing.frames import CAN_MAX_PAYLOAD
from netcfg.timing.load import FrameTiming, frame_timing

MAX_CAN_BITRATE = 1_000_000  # classical CAN, ISO 11898-1


class CanRules(BusRules):
    name = "can"
    # what the 1 Mbit/s bound is called, and what the error adds: CAN FD bounds its arbitration phase alone
    bounded_rate = "classical CAN runs"
    faster_rate = ""

    def resolve_bus(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        if b.bitrate > MAX_CAN_BITRATE:
            self.r.err(
                "bitrate",
                f"{self.bounded_rate} at most 1 Mbit/s; bus '{b.name}' says {b.bitrate} bit/s{self.faster_rate}",
                (*path, "bitrate"),
            )

    def check_payload(self, m: schema.Message, size: int, path: Path) -> None:
        if size > CAN_MAX_PAYLOAD:
            self.r.err(
                "payload",
                f"message '{m.name}': {size} bytes do not fit a classical CAN frame (at most 8); split the message"
                + (", or make the bus 'protocol: can-fd' (up to 64 bytes)" if type(self) is CanRules else ""),
                (*path, "size") if m.size is not None else path,
            )

    def reserved_ids(self, bus: model.Bus) -> dict[tuple[bool, int], str]:
        """(extended, identifier) -> what the protocol itself sends with it."""
        return {}

    def check_message_id(self, bus: model.Bus, m: model.Message) -> None:
        """A rule the protocol adds for one message's identifier once it is known to be unique."""

    def id_source_node(self, m: model.Message) -> str | None:
        """The node whose node id the protocol derived `m`'s identifier from (None: written or chosen otherwise)."""
        return None

    def check_identifiers(self, bus: model.Bus) -> None:
        """Every data frame's identifier is its own, and so is every remote frame's among the remote frames: a
        remote frame asks for the data frame of its identifier (ISO 11898-1, 10.3: the RTR bit, dominant in the data
        frame, decides their arbitration), so that pair is the one identifier two messages of a bus share."""
        reserved = self.reserved_ids(bus)
        taken = {(ext, can_id, False): what for (ext, can_id), what in reserved.items()}
        owner: dict[tuple[bool, int, bool], model.Message] = {}
        for m in bus.messages:
            if m.id < 0:
                continue
            id_key = (m.extended, m.id, m.remote)
            if id_key in owner and self._follows_shared_node_id(m, owner[id_key]):
                continue  # both identifiers follow from one duplicated node id: that is the one error
            clash = taken.get(id_key) or (reserved.get((m.extended, m.id)) if m.remote else None)
            if clash is not None:
                self.r.err(
                    "duplicate-id",
                    f"identifier 0x{m.id:03X} of '{m.name}' collides with {clash}; pick a free one",
                    self.r.key_or_item(m.path, "id"),
                )
                continue
            taken[id_key] = f"'{m.name}'"
            owner[id_key] = m
            self.check_message_id(bus, m)
            self.check_id_range(m)

    def _follows_shared_node_id(self, a: model.Message, b: model.Message) -> bool:
        nodes = (self.id_source_node(a), self.id_source_node(b))
        return all(n is not None and n in self.r.shared_node_ids for n in nodes)

    def check_id_range(self, m: model.Message) -> None:
        """A node's `id_range` holds every identifier it sends with (implicit protocol frames aside)."""
        node = self.r.spec_nodes.get(m.producer)
        if node is None or node.id_range is None or m.implicit is not None:
            return
        lo, hi = node.id_range
        if not lo <= m.id <= hi:
            self.r.err(
                "id-range",
                f"identifier 0x{m.id:03X} of '{m.name}' is outside node '{m.producer}''s id_range "
                f"0x{lo:03X}..0x{hi:03X}; pick one inside it (netcfg tune does) or widen the range",
                self.r.key_or_item(m.path, "id"),
            )


class ClassicalCan(Link):
    name = "can"
    title = "classical CAN"

    def rules(self) -> type[BusRules]:
        return CanRules

    def frame_timing(self, msg: model.Message, bus: model.Bus) -> FrameTiming:
        return frame_timing(msg, bus.bitrate, bus.data_bitrate)


CLASSICAL_CAN = ClassicalCan()
