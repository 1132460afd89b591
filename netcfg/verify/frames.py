"""A batch of CAN frames as columns: the unit every log reader yields and the checker consumes.

Columns (numpy arrays of one length) keep the per-frame work in C: a reader fills them, the checker reduces them per
message with array operations. Times are integer microseconds, the resolution every text log format carries
(candump and ASC write 6 decimals); BLF's nanoseconds are rounded to it so that all formats give the same report.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from netcfg.links import pycan_frames

__all__ = ["BRS", "ERROR", "EXTENDED", "FD", "REMOTE", "Batch", "ChannelTable", "batch_from_messages"]

# bits of Batch.flags
EXTENDED = 1
FD = 2
ERROR = 4
REMOTE = 8
BRS = 16  # a CAN FD frame with bit-rate switch: its data phase at the data rate

PAYLOAD_COLUMNS = 8  # bytes kept per frame: classical CAN payloads whole, the first 8 of a CAN FD payload


@dataclass
class Batch:
    t_us: NDArray[np.int64]
    channel: NDArray[np.int32]  # index into the reader's ChannelTable
    can_id: NDArray[np.int64]
    flags: NDArray[np.uint8]
    length: NDArray[np.int16]  # payload bytes
    data: NDArray[np.uint8]  # (n, 8), zero-padded

    def __len__(self) -> int:
        return len(self.t_us)

    @staticmethod
    def of_columns(
        t: list[int], ch: list[int], ids: list[int], flags: list[int], lengths: list[int], payload: bytes
    ) -> Batch:
        """A batch from per-frame lists and the payloads, each padded to PAYLOAD_COLUMNS bytes, end to end."""
        return Batch(
            np.array(t, np.int64),
            np.array(ch, np.int32),
            np.array(ids, np.int64),
            np.array(flags, np.uint8),
            np.array(lengths, np.int16),
            np.frombuffer(payload, np.uint8).reshape(len(t), PAYLOAD_COLUMNS).copy(),
        )

    @staticmethod
    def of_rows(rows: Iterable[tuple[int, int, int, int, int, bytes]]) -> Batch:
        """A batch from one row a frame: (time in us, channel index, identifier, flags, payload length, payload)."""
        table = list(rows)
        if not table:
            return Batch.empty()
        t, ch, ids, flags, lengths, data = zip(*table)
        payload = b"".join(d[:PAYLOAD_COLUMNS].ljust(PAYLOAD_COLUMNS, b"\0") for d in data)
        return Batch.of_columns(list(t), list(ch), list(ids), list(flags), list(lengths), payload)

    @staticmethod
    def empty() -> Batch:
        return Batch(
            np.empty(0, np.int64),
            np.empty(0, np.int32),
            np.empty(0, np.int64),
            np.empty(0, np.uint8),
            np.empty(0, np.int16),
            np.empty((0, PAYLOAD_COLUMNS), np.uint8),
        )


class ChannelTable:
    """Channel names in order of first appearance; a frame carries the index."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self._index: dict[str, int] = {}

    def index(self, name: str) -> int:
        found = self._index.get(name)
        if found is None:
            found = self._index[name] = len(self.names)
            self.names.append(name)
        return found


def seconds_to_us(timestamp: float) -> int:
    """A python-can float timestamp (seconds) -> integer microseconds, rounded to the nearest."""
    return round(timestamp * 1_000_000)


def batch_from_messages(messages: Iterable[object], channels: ChannelTable) -> Batch:
    """python-can Messages -> a Batch (the reference path: every reader python-can has)."""
    t: list[int] = []
    ch: list[int] = []
    ids: list[int] = []
    flags: list[int] = []
    lengths: list[int] = []
    payload = bytearray()
    for msg in messages:
        t.append(seconds_to_us(msg.timestamp))  # type: ignore[attr-defined]
        channel = msg.channel  # type: ignore[attr-defined]
        ch.append(channels.index("" if channel is None else str(channel)))
        ids.append(int(msg.arbitration_id))  # type: ignore[attr-defined]
        fd, brs = pycan_frames.frame_format(msg)  # type: ignore[arg-type]
        flags.append(
            (EXTENDED if msg.is_extended_id else 0)  # type: ignore[attr-defined]
            | (FD if fd else 0)
            | (ERROR if msg.is_error_frame else 0)  # type: ignore[attr-defined]
            | (REMOTE if msg.is_remote_frame else 0)  # type: ignore[attr-defined]
            | (BRS if brs else 0)
        )
        data = bytes(msg.data or b"")  # type: ignore[attr-defined]
        # a remote frame carries a DLC but no data
        lengths.append(int(msg.dlc) if msg.is_remote_frame else len(data))  # type: ignore[attr-defined]
        payload += data[:PAYLOAD_COLUMNS].ljust(PAYLOAD_COLUMNS, b"\0")
    return Batch.of_columns(t, ch, ids, flags, lengths, bytes(payload))
