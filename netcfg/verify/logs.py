"""Reading CAN logs as a stream of Batches: python-can's readers for every format, a vectorised candump reader.

python-can's readers (candump .log, Vector .asc and .blf, PCAN .trc, its .csv and SQLite .db, ASAM .mf4) are the
reference: `read_log(..., fast=False)` uses them for every format. They build one Python object per frame, about
50-150 thousand frames per second. candump -L files are the common case for long recordings, so they also have a
vectorised reader (numpy over whole blocks of lines) that gives the same frames; a block with any line it does not
recognise (CAN FD, remote or error frames, odd spacing) is handed to python-can's reader, so nothing is guessed.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from netcfg.verify.frames import EXTENDED, PAYLOAD_COLUMNS, Batch, ChannelTable, batch_from_messages

__all__ = ["FORMATS", "LogError", "log_format", "read_log"]

# --log-format names -> the suffix python-can knows the format by
FORMATS = {
    "candump": ".log",
    "log": ".log",
    "asc": ".asc",
    "blf": ".blf",
    "trc": ".trc",
    "csv": ".csv",
    "sqlite": ".db",
    "db": ".db",
    "mf4": ".mf4",
}
BATCH_FRAMES = 1 << 18  # frames per batch: a few MB of columns, whatever the log's length
_BLOCK_BYTES = 1 << 20  # candump text per block: about 27,000 lines; larger blocks are no faster and cost memory


class LogError(Exception):
    """The log cannot be read (exit code 2)."""


def log_format(path: Path, given: str | None) -> str:
    """The python-can suffix of a log: from --log-format, else from the file name."""
    if given is not None:
        key = given.lower().lstrip(".")
        if key not in FORMATS:
            raise LogError(f"--log-format {given!r}: use one of {', '.join(sorted(set(FORMATS)))}")
        return FORMATS[key]
    suffix = path.suffix.lower()
    if suffix not in FORMATS.values():
        raise LogError(
            f"{path}: cannot tell the log format from the suffix {suffix or '(none)'!r}; "
            f"give --log-format ({', '.join(sorted(set(FORMATS)))})"
        )
    return suffix


def read_log(
    path: Path,
    fmt: str | None = None,
    fast: bool = True,
    progress: Callable[[float], None] | None = None,
) -> tuple[ChannelTable, Iterator[Batch]]:
    """Open a log; -> (its channel names, filled in while reading; the frames in batches). LogError when the file
    cannot be opened or is not the format it claims. progress(fraction) is called between batches when the size
    is known."""
    suffix = log_format(path, fmt)
    if not path.is_file():
        raise LogError(f"{path}: no such file")
    channels = ChannelTable()
    if fast and suffix == ".log":
        return channels, _guard(path, _candump_batches(path, channels, progress))
    return channels, _guard(path, _python_can_batches(path, suffix, channels, progress))


def _guard(path: Path, batches: Iterator[Batch]) -> Iterator[Batch]:
    """Turns whatever a reader raises on a damaged file into LogError naming the file."""
    try:
        yield from batches
    except LogError:
        raise
    except (NotImplementedError, ImportError) as exc:  # e.g. MF4 without python-can's optional asammdf
        raise LogError(f"{path}: python-can cannot read this format here: {exc}") from exc
    except (OSError, ValueError, IndexError, KeyError, TypeError, EOFError, struct.error, zlib.error) as exc:
        raise LogError(f"{path}: not a readable log ({type(exc).__name__}: {exc})") from exc
    except Exception as exc:  # python-can's readers raise their own types on damaged files (e.g. BLFParseError)
        if type(exc).__module__.startswith("can"):
            raise LogError(f"{path}: not a readable log ({type(exc).__name__}: {exc})") from exc
        raise


def _python_can_batches(
    path: Path, suffix: str, channels: ChannelTable, progress: Callable[[float], None] | None
) -> Iterator[Batch]:
    import can
    from can.io.player import MESSAGE_READERS

    reader_class: Any = MESSAGE_READERS[suffix]
    size = path.stat().st_size
    with reader_class(str(path)) as reader:
        pending: list[can.Message] = []
        for msg in reader:
            pending.append(msg)
            if len(pending) == BATCH_FRAMES:
                yield batch_from_messages(pending, channels)
                pending = []
                if progress is not None:
                    progress(_position(reader, size))
        if pending:
            yield batch_from_messages(pending, channels)


def _position(reader: Any, size: int) -> float:
    try:
        return min(1.0, reader.file.tell() / size) if size else 1.0
    except (AttributeError, OSError, ValueError):
        return 0.0


# --- candump -L, vectorised -------------------------------------------------------------------------------------

_HEX = np.full(256, 255, np.uint8)
for _i, _c in enumerate(b"0123456789ABCDEF"):
    _HEX[_c] = _i
for _i, _c in enumerate(b"abcdef"):
    _HEX[_c] = 10 + _i
_POW10 = np.array([10**k for k in range(19)], np.int64)
_DECIMAL = np.full(256, 255, np.uint8)
_DECIMAL[48:58] = np.arange(10)
_PAD = 32
_MAX_CHANNEL = 16  # interface names longer than this go to python-can's reader


def _candump_batches(path: Path, channels: ChannelTable, progress: Callable[[float], None] | None) -> Iterator[Batch]:
    size = path.stat().st_size
    done = 0
    line = 1  # of the block's first line, for error messages
    with path.open("rb") as f:
        tail = b""
        while True:
            block = f.read(_BLOCK_BYTES)
            if not block:
                break
            done += len(block)
            block = tail + block
            cut = block.rfind(b"\n") + 1
            tail, block = block[cut:], block[:cut]
            if block:
                yield from _split(_candump_block(block, channels, path, line))
                line += block.count(b"\n")
            if progress is not None and size:
                progress(done / size)
        if tail.strip():
            yield from _split(_candump_block(tail + b"\n", channels, path, line))


def _split(batch: Batch) -> Iterator[Batch]:
    for start in range(0, len(batch), BATCH_FRAMES):
        s = slice(start, start + BATCH_FRAMES)
        yield Batch(batch.t_us[s], batch.channel[s], batch.can_id[s], batch.flags[s], batch.length[s], batch.data[s])


def _candump_block(block: bytes, channels: ChannelTable, path: Path, line: int) -> Batch:
    """Whole lines of a candump -L file (the first is line `line`) -> frames; python-can's reader for a block the
    fast path does not cover, and LogError naming the first line it cannot read."""
    parsed = _parse_plain(block, channels)
    if parsed is not None:
        return parsed
    import can

    try:
        return batch_from_messages(can.CanutilsLogReader(io.StringIO(block.decode("ascii"))), channels)
    except (ValueError, IndexError, KeyError, TypeError) as exc:
        for number, text in enumerate(block.splitlines(), line):
            try:
                list(can.CanutilsLogReader(io.StringIO(text.decode("ascii"))))
            except (ValueError, IndexError, KeyError, TypeError):
                shown = text[:60].decode("ascii", "replace")
                raise LogError(
                    f"{path}:{number}: not a candump -L line: {shown!r}; expected '(SECONDS) INTERFACE ID#DATA'"
                ) from exc
        raise


def _parse_plain(block: bytes, channels: ChannelTable) -> Batch | None:
    """Lines `(SECONDS.FRACTION) IFACE ID#HEXDATA[ R|T]` of classical data frames; None when any line is otherwise."""
    buf = np.frombuffer(block + bytes(_PAD), np.uint8)  # windows past the last line read zeros
    ends = np.flatnonzero(buf == 10)
    starts = np.empty_like(ends)
    starts[0] = 0
    starts[1:] = ends[:-1] + 1
    n = len(ends)
    if not n or not (buf[starts] == 40).all():  # "(" opens every line (no blank lines, no comments)
        return None
    closes = np.flatnonzero(buf == 41)
    dots = np.flatnonzero(buf == 46)
    hashes = np.flatnonzero(buf == 35)
    if len(closes) != n or len(dots) != n or len(hashes) != n:  # "##" (CAN FD) or anything unusual
        return None
    spaces = np.flatnonzero(buf == 32)
    first = np.searchsorted(spaces, closes)
    if first.max(initial=0) >= len(spaces) or not (spaces[first] == closes + 1).all():
        return None
    second = first + 1
    if second.max(initial=0) >= len(spaces):
        return None
    iface_end = spaces[second]
    if not ((iface_end < hashes) & (dots < closes) & (dots > starts) & (hashes < ends)).all():
        return None
    # timestamp: integer seconds, then 1..9 decimals
    int_len = dots - starts - 1
    frac_len = closes - dots - 1
    # more than 6 decimals: python-can's float rounds them, which only its own reader reproduces
    if int_len.min() < 1 or int_len.max() > 12 or frac_len.min() < 1 or frac_len.max() > 6:
        return None
    seconds = _number(buf, starts + 1, int_len, _DECIMAL)
    fraction = _number(buf, dots + 1, frac_len, _DECIMAL)
    if seconds is None or fraction is None:
        return None
    ns = fraction * _POW10[9 - frac_len]
    t_us = seconds * 1_000_000 + (ns + 500) // 1000  # rounded to the microsecond, as seconds_to_us
    # identifier: 3 hex digits (11-bit) or 8 (29-bit; an error frame has bit 29 set: python-can's reader takes it)
    id_len = hashes - iface_end - 1
    if not np.isin(id_len, (3, 8)).all():
        return None
    can_id = _number(buf, iface_end + 1, id_len, _HEX)
    if can_id is None:
        return None
    extended = id_len == 8
    if (can_id[extended] >= 1 << 29).any() or (can_id[~extended] >= 1 << 11).any():
        return None
    # data: hex pairs up to the line end or the direction flag " R"/" T"
    data_start = hashes + 1
    after = np.searchsorted(spaces, data_start)
    next_space = np.where(after < len(spaces), spaces[np.minimum(after, len(spaces) - 1)], ends)
    data_end = np.minimum(next_space, ends)
    hex_len = data_end - data_start
    if (hex_len % 2).any() or hex_len.max(initial=0) > 2 * PAYLOAD_COLUMNS:
        return None
    trailer = ends - data_end
    if not np.isin(trailer, (0, 2)).all():
        return None
    if (trailer == 2).any():
        flag = buf[data_end[trailer == 2] + 1]
        if not np.isin(flag, (ord("R"), ord("T"))).all():
            return None
    length = (hex_len // 2).astype(np.int16)
    data = np.zeros((n, PAYLOAD_COLUMNS), np.uint8)
    for k in range(int(length.max(initial=0))):
        have = length > k
        hi = _HEX[buf[data_start + 2 * k]]  # the padding keeps every index inside the block
        lo = _HEX[buf[data_start + 2 * k + 1]]
        if (((hi | lo) == 255) & have).any():
            return None
        data[:, k] = ((hi << 4) | lo) * have
    channel = _channels(buf, closes + 2, iface_end - closes - 2, channels)
    if channel is None:
        return None
    flags = np.where(extended, EXTENDED, 0).astype(np.uint8)
    return Batch(t_us, channel, can_id, flags, length, data)


def _number(
    buf: NDArray[np.uint8], first: NDArray[np.int64], length: NDArray[np.int64], digit_of: NDArray[np.uint8]
) -> NDArray[np.int64] | None:
    """The numbers written at buf[first : first + length] (digits by digit_of's table, base 10 or 16), one column of
    digits at a time; None when a character is not a digit."""
    base = 10 if digit_of is _DECIMAL else 16
    value = np.zeros(len(first), np.int64)
    uniform = bool((length == length[0]).all())
    for k in range(int(length.max(initial=0))):
        digit = digit_of[buf[first + k]]
        if uniform:
            if (digit == 255).any():
                return None
            value = value * base + digit
        else:
            have = length > k
            if ((digit == 255) & have).any():
                return None
            value = np.where(have, value * base + digit, value)
    return value


def _channels(
    buf: NDArray[np.uint8], start: NDArray[np.int64], length: NDArray[np.int64], table: ChannelTable
) -> NDArray[np.int32] | None:
    """Interface names -> ChannelTable indexes (python-can's reader keeps the name as written)."""
    if length.min() < 1 or length.max() > _MAX_CHANNEL:
        return None
    names = np.zeros((len(start), _MAX_CHANNEL), np.uint8)
    for k in range(int(length.max())):
        names[:, k] = buf[start + k] * (length > k)
    keys = np.ascontiguousarray(names).view(np.dtype((np.void, _MAX_CHANNEL))).ravel()
    if (keys == keys[0]).all():  # the common case: one interface
        unique, inverse = keys[:1], np.zeros(len(keys), np.int64)
    else:
        unique, inverse = np.unique(keys, return_inverse=True)
    index = np.array([table.index(bytes(u).rstrip(b"\0").decode("ascii")) for u in unique], np.int32)
    return index[inverse]
