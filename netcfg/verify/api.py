"""The entry points a program calls: a log file checked (verify_log), or frames it holds already (check_frames)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

from netcfg.runtime import RuntimeConfig
from netcfg.runtime.actuator_plan import reply_commands
from netcfg.verify.checker import DEFAULT_WINDOW_US, Checker
from netcfg.verify.fault_phases import FaultScan, add_fault_phases, excused_spans
from netcfg.verify.frames import BRS, ERROR, EXTENDED, FD, Batch, ChannelTable
from netcfg.verify.host_clock import HostClock, host_finding
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
    report = _judge(
        cfg,
        lambda first: read_log(log, log_format, fast=fast, progress=None if first else progress),
        bus,
        window_us,
        strict,
    )
    report["log"] = str(log)
    return report


def _judge(
    cfg: RuntimeConfig,
    read: Callable[[bool], tuple[ChannelTable, Iterable[Batch]]],
    bus: str | Mapping[str, str] | None,
    window_us: int,
    strict: bool,
) -> dict[str, Any]:
    """The frames `read(first read?)` gives, judged: verify's one path, for a log file and for frames in memory."""
    # a CANopen master's log: the analysis speaks of its cyclic phase, set-up and shut-down are phases of their own;
    # faults in it (a reboot, a lost node, an EMCY, no SYNC) are phases too (netcfg.verify.fault_phases)
    span, faults, scan, clock = None, [], None, None
    if sync_ids(cfg):
        first, batches = read(True)
        probe = Checker(cfg, first.names, bus, window_us, strict)  # the channel -> bus mapping of the checker
        scan = FaultScan(cfg, probe.buses_of)
        clock = HostClock(probe.buses)
        span = cyclic_span(cfg, _scanned(batches, scan, clock, probe))
        faults = scan.finish(span)
    elif reply_commands(cfg):  # an actuator master's log: replies timed from their commands, on whose clock?
        first, batches = read(True)
        probe = Checker(cfg, first.names, bus, window_us, strict)
        clock = HostClock(probe.buses)
        for batch in batches:
            _stamps(batch, clock, probe)
    channels, batches = read(False)
    checker = Checker(cfg, channels.names, bus, window_us, strict)
    if clock is not None and clock.host:
        checker.host_clock = host_finding(cfg)  # lateness on a host's clock is named the host's
    if faults and scan is not None:
        checker.excuse(excused_spans(faults, scan.end_us or 0))
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
    if clock is not None:
        report["timestamps"] = clock.report()
    if scan is not None:
        add_fault_phases(report, faults, span, origin[0] if origin else (checker.origin_t or 0), scan.end_us or 0)
    return report


def _scanned(batches: Iterable[Batch], scan: FaultScan, clock: HostClock, probe: Checker) -> Iterator[Batch]:
    """The first read: the fault phases' evidence and whose clock stamped the log, batch by batch."""
    for batch in batches:
        scan.take(batch)
        _stamps(batch, clock, probe)
        yield batch


def _stamps(batch: Batch, clock: HostClock, probe: Checker) -> None:
    """The batch's frames (error frames aside) to the judge of whose clock stamped the log."""
    keep = (batch.flags & ERROR) == 0
    clock.take(batch.t_us[keep], probe.buses_of(batch.channel)[keep], batch.flags[keep], batch.length[keep])


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

    def rows() -> Iterator[tuple[int, int, int, int, int, bytes]]:
        for frame in frames:
            t_ns, channel, can_id, extended, data = frame[:5]
            error, fd, brs = (bool(x) for x in (*frame[5:8], False, False, False)[:3])
            flags = (EXTENDED if extended else 0) | (ERROR if error else 0) | (FD if fd else 0) | (BRS if brs else 0)
            yield (t_ns + 500) // 1000, table.index(channel), can_id, flags, len(data), bytes(data)

    batch = Batch.of_rows(rows())
    return _judge(cfg, lambda _first: (table, [batch]), None, window_us, False)
