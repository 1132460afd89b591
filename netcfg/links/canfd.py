"""CAN FD (ISO 11898-1:2015): an arbitration bit rate and a data bit rate, payloads up to 64 bytes padded to the
next valid length, classical frames (`fd: false`) on the same bus. Identifiers follow the classical CAN rules."""

from __future__ import annotations

from netcfg import model
from netcfg.links.can import CanRules, ClassicalCan
from netcfg.rules import BusRules, Resolution
from netcfg.spec import schema
from netcfg.spec.source import Path
from netcfg.timing.frames import CAN_MAX_PAYLOAD, CANFD_LENGTHS, CANFD_MAX_PAYLOAD, canfd_padded_size
from netcfg.timing.load import FrameTiming


class CanFdRules(CanRules):
    name = "can-fd"
    bounded_rate = "the CAN FD arbitration phase runs"
    faster_rate = " (the faster rate is 'data_bitrate')"

    def resolve_bus(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        super().resolve_bus(b, bus, path)
        if b.data_bitrate is None:
            self.r.err(
                "data-bitrate",
                f"CAN FD bus '{b.name}' needs 'data_bitrate', the rate of the data phase (e.g. 'data_bitrate: 5M')",
                path,
            )
            return
        if b.data_bitrate < b.bitrate:
            self.r.err(
                "data-bitrate",
                f"the data phase cannot be slower than arbitration: data_bitrate {b.data_bitrate} bit/s is below "
                f"bitrate {b.bitrate} bit/s",
                (*path, "data_bitrate"),
            )
        bus.data_bitrate = b.data_bitrate

    def check_payload(self, m: schema.Message, size: int, path: Path) -> None:
        where = (*path, "size") if m.size is not None else path
        if m.fd is False:
            if size > CAN_MAX_PAYLOAD:
                self.r.err(
                    "payload",
                    f"message '{m.name}': {size} bytes do not fit a classical frame (at most 8); drop 'fd: false' or "
                    "split the message",
                    where,
                )
            return
        if size > CANFD_MAX_PAYLOAD:
            self.r.err(
                "payload",
                f"message '{m.name}': {size} bytes do not fit a CAN FD frame (at most 64); split the message",
                where,
            )
            return
        padded = canfd_padded_size(size)
        if padded != size:
            lengths = ", ".join(str(n) for n in CANFD_LENGTHS[CAN_MAX_PAYLOAD + 1 :])
            self.r.warn(
                "fd-padding",
                f"message '{m.name}': a CAN FD frame carries 0-8, {lengths} bytes; its {size} bytes go in a "
                f"{padded}-byte frame with {padded - size} padding bytes (timed and sent as {padded})",
                where,
            )

    def frame_format(self, m: schema.Message, path: Path) -> tuple[bool, bool]:
        fd = m.fd is not False
        if not fd and m.brs:
            self.r.err("brs", "bit-rate switch exists only in CAN FD frames; drop 'brs' or 'fd: false'", (*path, "brs"))
        return fd, fd and m.brs is not False


class OverCanLinks(CanRules):
    """The rules of a protocol that runs over either CAN link: on a bus whose link is CAN FD (`link: can-fd`), the
    CAN FD link's rules judge its bit rates, payloads and frame formats; elsewhere classical CAN's."""

    def __init__(self, r: Resolution) -> None:
        super().__init__(r)
        self._fd = CanFdRules(r)

    def link_rules(self, bus: model.Bus) -> BusRules:
        return self._fd if bus.link == CanFd.name else self

    def resolve_bus(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        if bus.link == CanFd.name:
            self._fd.resolve_bus(b, bus, path)
        else:
            super().resolve_bus(b, bus, path)


class CanFd(ClassicalCan):
    name = "can-fd"
    title = "CAN FD"
    data_phase = True

    def rules(self) -> type[BusRules]:
        return CanFdRules

    def bits_per_second(self, bus: model.Bus, timings: dict[str, FrameTiming]) -> float | None:
        # the data phase sends more bits per second than the nominal rate: counted frame by frame
        return sum(
            timings[msg.name].bits_worst * 1e9 / msg.interval_ns
            for msg in bus.messages
            if msg.interval_ns and msg.kind != "on-demand"
        )


CAN_FD = CanFd()
