"""Simulation traces in the log formats CAN tools read: candump -L (.log) and Vector ASC (.asc).

Both files are written by python-can's own writers (can.CanutilsLogWriter, can.ASCWriter), so they are exactly what
python-can, can-utils and CANalyzer-style viewers expect to read. Timestamps are the simulation clock: t_ns / 1e9
seconds, counted from the start of the simulation (t = 0), in both formats.

Channels: candump names the interface in every line, so a frame's channel name is written as it is (python-can turns
a purely numeric name N into canN). ASC numbers its channels from 1: the channel names are numbered 1..n in the order
in which they first appear in the frames.

Error frames carry no identifier or data in either format; those fields of an error TraceFrame are not written.
"""

from __future__ import annotations

import io
import re
from collections.abc import Iterable
from pathlib import Path
from typing import NamedTuple, TextIO, cast

import can

from netcfg.links import pycan_frames

__all__ = ["SUPPORTED_SUFFIXES", "TraceFrame", "write_trace"]

SUPPORTED_SUFFIXES = (".log", ".asc")
_FORMATS = {"log": ".log", "candump": ".log", "asc": ".asc"}

# ASCWriter stamps the header with the wall clock ("date ...") and the first event's local time ("Begin Triggerblock
# ..."), so two runs never give the same file. Those two header lines are pinned to the simulation's epoch, written
# in ASCWriter.FORMAT_DATE ("%a %b %d %H:%M:%S.mmm %Y"): t = 0 read as 1970-01-01 00:00:00 UTC.
_ASC_EPOCH = "Thu Jan 01 00:00:00.000 1970"
_ASC_DATE_LINE = re.compile(r"(date|Begin Triggerblock) .*\n")
_ASC_START = "Start of measurement"


class TraceFrame(NamedTuple):
    """One frame seen on a bus; t_ns is its end-of-frame instant in simulation nanoseconds."""

    t_ns: int
    channel: str
    can_id: int
    extended: bool
    data: bytes
    error: bool = False
    fd: bool = False  # a CAN FD frame (data padded to a CAN FD length); brs: with bit-rate switch
    brs: bool = False


class _AscSink(io.TextIOBase):
    """The text stream ASCWriter writes into: passes every line through to the file, except that it pins the header
    dates (see _ASC_EPOCH) and keeps a single "Start of measurement" line.

    write_trace starts the measurement with an explicit event at t = 0, so that ASC times count from the start of the
    simulation rather than from the first frame (ASCWriter's default); ASCWriter answers the first event by writing its
    own "Start of measurement" line before it, and the explicit one would repeat it.
    """

    def __init__(self, out: TextIO) -> None:
        super().__init__()
        self._out = out
        self._started = False

    def write(self, s: str) -> int:
        date = _ASC_DATE_LINE.fullmatch(s)
        if date:
            self._out.write(f"{date[1]} {_ASC_EPOCH}\n")
        elif not s.rstrip("\n").endswith(_ASC_START):
            self._out.write(s)
        elif not self._started:
            self._started = True
            self._out.write(s)
        return len(s)

    def close(self) -> None:
        if not self.closed:
            self._out.close()
        super().close()


def _suffix(path: Path, fmt: str | None) -> str:
    key = (fmt if fmt is not None else path.suffix).lower().lstrip(".")
    if key not in _FORMATS:
        given = f"format {fmt!r}" if fmt is not None else f"file suffix {path.suffix!r} of {path.name}"
        raise ValueError(
            f"unsupported trace {given}: use one of {', '.join(SUPPORTED_SUFFIXES)} (candump -L log, Vector ASC)"
        )
    return _FORMATS[key]


def write_trace(frames: Iterable[TraceFrame], path: str | Path, fmt: str | None = None) -> int:
    """Write frames (in time order) to a candump -L log or a Vector ASC file; returns how many were written.

    fmt is "log"/"candump" or "asc" (a leading dot is allowed); without it the file's suffix decides. The same frames
    always give a byte-identical file. Frames must not go back in time: both writers would silently move such a frame
    to the previous timestamp, so that is refused with ValueError.
    """
    path = Path(path)
    suffix = _suffix(path, fmt)
    out = path.open("w", encoding="ascii", newline="\n")
    writer: can.CanutilsLogWriter | can.ASCWriter
    channels: dict[str, int] = {}
    if suffix == ".asc":
        writer = can.ASCWriter(cast(TextIO, _AscSink(out)))
        writer.log_event(_ASC_START, 0.0)
    else:
        writer = can.CanutilsLogWriter(out)
    count = 0
    last_ns = 0
    with writer:
        for frame in frames:
            if frame.t_ns < last_ns:
                raise ValueError(
                    f"trace frame {count} at {frame.t_ns} ns comes before the previous one at {last_ns} ns;"
                    " write frames in time order"
                )
            last_ns = frame.t_ns
            if suffix == ".asc":
                channel: str | int = channels.setdefault(frame.channel, len(channels))  # ASCWriter prints it + 1
            elif not frame.channel or any(c.isspace() for c in frame.channel):
                raise ValueError(f"candump channel (interface) names have no spaces; got {frame.channel!r}")
            else:
                channel = frame.channel
            if frame.error:
                msg = can.Message(timestamp=frame.t_ns / 1e9, channel=channel, is_error_frame=True)
            else:
                msg = pycan_frames.message(
                    frame.can_id,
                    frame.extended,
                    frame.data,
                    fd=frame.fd,
                    brs=frame.brs,
                    dlc=len(frame.data),
                    timestamp=frame.t_ns / 1e9,
                    channel=channel,
                    check=True,  # python-can refuses identifiers and payloads the frame's format cannot carry
                )
            writer.on_message_received(msg)
            count += 1
    return count
