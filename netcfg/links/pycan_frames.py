"""The CAN links' frames as python-can carries them: the one place netcfg speaks python-can's frame format.

Frames of netcfg's own (runtime.json's messages, the simulator's sources and traces, an actuator profile's frames)
say `fd` (a CAN FD frame, ISO 11898-1:2015 FDF bit) and `brs` (its bit-rate switch, the BRS bit, which only a CAN
FD frame has); python-can's Message says `is_fd` and `bitrate_switch` (python-can 4.x, can.Message). Every frame
netcfg hands to python-can or takes from it with those flags passes through `message` or `frame_format`.

The runtime hands its frames to python-can through it, and the runtime imports without the compiler: this module
imports no module of netcfg (tests/test_layers.py holds it to that; the link layer's registry loads no link until
asked for one), and python-can only when a frame is made.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import can


def message(
    arbitration_id: int,
    extended: bool,
    data: bytes | bytearray | None = None,
    *,
    fd: bool = False,
    brs: bool = False,
    remote: bool = False,
    dlc: int | None = None,
    timestamp: float = 0.0,
    channel: str | int | None = None,
    check: bool = False,
) -> can.Message:
    """A frame as python-can's Message: `fd`, `brs` as its is_fd, bitrate_switch; the rest python-can's own
    (`dlc` None: the data's length; `check`: python-can refuses what the frame's format cannot carry)."""
    import can

    return can.Message(
        timestamp=timestamp,
        arbitration_id=arbitration_id,
        is_extended_id=extended,
        is_remote_frame=remote,
        channel=channel,
        dlc=dlc,
        data=data,
        is_fd=fd,
        bitrate_switch=brs,
        check=check,
    )


def frame_format(msg: can.Message) -> tuple[bool, bool]:
    """(fd, brs) of a python-can frame: a CAN FD frame, and its bit-rate switch, which a classical frame has not
    (python-can keeps bitrate_switch apart from is_fd; ISO 11898-1:2015 has the BRS bit in FD frames only)."""
    fd = bool(msg.is_fd)
    return fd, fd and bool(msg.bitrate_switch)
