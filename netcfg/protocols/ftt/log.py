"""What a recorded log of an FTT-CAN bus holds besides runtime.json's messages, as netcfg.verify checks it: the
master's trigger message (TM), once per elementary cycle, from whose start a synchronous message's response counts."""

from __future__ import annotations

from netcfg.protocols.ftt.tm import TM_EXTENDED, tm_fd
from netcfg.runtime import Bus, Message
from netcfg.timing.frames import frame_bits


def trigger_message(bus: Bus) -> Message:
    """FTT-CAN's trigger message as a message of the bus: sent by the master once per elementary cycle."""
    ftt = bus.ftt
    assert ftt is not None  # an FTT-CAN bus: runtime.json's schema requires its section
    return Message(
        name=f"{bus.name}_TM",
        bus=bus.name,
        protocol=bus.protocol,
        link=bus.link,
        producer=ftt.master,
        consumers=(),
        id=ftt.tm_id,
        extended=TM_EXTENDED,
        size=ftt.tm_size,
        fd=tm_fd(bus.link),
        brs=tm_fd(bus.link),
        kind="periodic",
        period_ns=ftt.ec_ns,
        interval_ns=ftt.ec_ns,
        offset_ns=0,
        deadline_ns=None,
        jitter_ns=0,
        rate_hz=None,
        window=None,
        ftt_id=None,
        udp=None,
        pdo=None,
        signals=(),
        implicit="TM",
        wcrt_ns=None,
    )


def response_reference(bus: Bus) -> tuple[int, int]:
    """(the TM's identifier, us): a log stamps a frame's end, and FTT-CAN's analysis counts from the EC's start,
    where the trigger message starts: its shortest transmission (no stuff bits) is added back, so a reported late
    frame is surely late."""
    ftt = bus.ftt
    assert ftt is not None
    fd = tm_fd(bus.link)
    return ftt.tm_id, frame_bits(ftt.tm_size, TM_EXTENDED, fd, fd, "nominal").ns(bus.bitrate, bus.data_bitrate) // 1000
