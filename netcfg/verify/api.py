"""The entry points a program calls: a log file checked (verify_log), or frames it holds already (check_frames)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from netcfg.runtime import RuntimeConfig
from netcfg.verify.checker import DEFAULT_WINDOW_US, Checker
from netcfg.verify.frames import BRS, ERROR, EXTENDED, FD, PAYLOAD_COLUMNS, Batch, ChannelTable
from netcfg.verify.logs import read_log
from netcfg.verify.phases import Phase, cyclic_span, split, sync_ids

__all__ = ["check_frames", "verify_log"]


def verify_log(
    cfg: RuntimeConfig,
    log: Path,
    *,
    bus: str | Mapping[str, str] | None = None,
    log_format: str | None = None,
    window_us: int = DEFAULT_WINDOW_US,
    strict: bool = False,
    fast: bool = True,
    progress: Callable[[float], None] | None = None,
) -> dict[str, Any]:
    """Read the log in batches and check it; LogError when it cannot be read, VerifyError when the log and the
    configuration cannot be matched."""
    # a CANopen master's log: the analysis speaks of its cyclic phase, set-up and shut-down are phases of their own
    span = cyclic_span(cfg, read_log(log, log_format, fast=fast)[1]) if sync_ids(cfg) else None
    channels, batches = read_log(log, log_format, fast=fast, progress=progress)
    checker = Checker(cfg, channels.names, bus, window_us, strict)
    setup, shutdown = Phase(), Phase()
    origin: list[int] = []
    judged = batches if span is None else split(batches, span, setup, shutdown, origin, checker.note_services)
    for batch in judged:
        checker.feed(batch)
    report = checker.finish()
    if span is not None and origin:
        cyclic_end = min(span[1], checker.last_t) if checker.last_t is not None else span[1]
        services = [b["canopen"] for b in report["buses"] if "canopen" in b]
        report["phases"] = {
            "setup": setup.report(origin[0], services),
            "cyclic": {"from_us": span[0] - origin[0], "to_us": cyclic_end - origin[0]},
            "shutdown": shutdown.report(origin[0], services),
        }
    report["log"] = str(log)
    return report


def check_frames(
    cfg: RuntimeConfig,
    frames: Iterable[tuple[Any, ...]],
    window_us: int = DEFAULT_WINDOW_US,
) -> dict[str, Any]:
    """Frames as (end time in ns, bus name, identifier, extended, payload[, error frame[, CAN FD[, bit-rate
    switch]]]), in time order -> the
    report. For a program that holds its frames already (the simulator's trace, netcfg.sim.trace.TraceFrame);
    times are taken to the microsecond, as a log file would carry them."""
    table = ChannelTable()
    t: list[int] = []
    ch: list[int] = []
    ids: list[int] = []
    flags: list[int] = []
    lengths: list[int] = []
    payload = bytearray()
    for frame in frames:
        t_ns, channel, can_id, extended, data = frame[:5]
        t.append((t_ns + 500) // 1000)
        ch.append(table.index(channel))
        ids.append(can_id)
        error, fd, brs = (bool(x) for x in (*frame[5:8], False, False, False)[:3])
        flags.append((EXTENDED if extended else 0) | (ERROR if error else 0) | (FD if fd else 0) | (BRS if brs else 0))
        lengths.append(len(data))
        payload += bytes(data[:PAYLOAD_COLUMNS]).ljust(PAYLOAD_COLUMNS, b"\0")
    checker = Checker(cfg, table.names, window_us=window_us)
    checker.feed(Batch.of_columns(t, ch, ids, flags, lengths, bytes(payload)))
    return checker.finish()
