"""What a master cycle run records: one CycleRecord per iteration, and the statistics seed 000 reports over them
(Table 5's reading and writing times, section 5.2's period error), with a CSV export like the paper's storage."""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from netcfg.runtime.codec import Number

__all__ = ["CommandFn", "CycleRecord", "MasterRun", "PeriodStats", "Samples", "TimeStats"]

# --- the master cycle ---------------------------------------------------------------------------------------------

Samples = Mapping[str, Mapping[str, Number]]
CommandFn = Callable[[int, Samples], Mapping[str, Mapping[str, Number]] | None]


@dataclass(frozen=True)
class CycleRecord:
    """One iteration of the master cycle; times are the clock's seconds."""

    index: int
    sync_number: int  # SYNCs sent by this master so far, this one included
    start: float  # the iteration began (commands computed next)
    written: float  # the RxPDOs were sent
    sync_sent: float
    read_done: float  # all due TxPDOs in, or the read window over
    end: float  # the dynamic wait is over: the next iteration's start
    due: tuple[str, ...]  # TxPDOs due at this SYNC
    arrivals: Mapping[str, float] = field(compare=False)  # TxPDO -> clock time received
    values: Mapping[str, Mapping[str, Number]] = field(compare=False)  # TxPDO -> decoded fields
    missing: tuple[str, ...]  # due but not received within the read window
    late: int  # TxPDOs found queued before this SYNC went out (answers to an earlier SYNC)
    other: int  # other frames seen (SDO, EMCY, heartbeat, PDOs of other nodes)
    processing_s: float  # Pt: start -> samples stored
    waiting_s: float  # eq. (1): T - Pt - K (negative: the iteration overran)
    sync_ok: bool = True  # the interface took the SYNC (False: send raised can.CanError, e.g. bus-off)

    @property
    def period_s(self) -> float:
        return self.end - self.start

    @property
    def write_s(self) -> float:
        return self.written - self.start

    @property
    def read_s(self) -> float:
        return self.read_done - self.sync_sent


@dataclass(frozen=True)
class TimeStats:
    count: int
    mean_s: float
    std_s: float
    min_s: float
    max_s: float

    @classmethod
    def of(cls, values: Sequence[float]) -> TimeStats:
        """std is the population standard deviation (divided by n), as numpy's default and the simulator's
        netcfg.sim.stats.spread: a run's values are all the values, not a sample of a larger set."""
        if not values:
            return cls(0, math.nan, math.nan, math.nan, math.nan)
        return cls(len(values), statistics.fmean(values), statistics.pstdev(values), min(values), max(values))

    def ms(self) -> str:
        if not self.count:
            return "no values"
        return (
            f"mean {1e3 * self.mean_s:.4f} ms, std {1e3 * self.std_s:.4f} ms, min {1e3 * self.min_s:.4f} ms, "
            f"max {1e3 * self.max_s:.4f} ms (n = {self.count})"
        )


@dataclass(frozen=True)
class PeriodStats:
    """Period error statistics as in seed 000 section 5.2: each period's error (actual - T) and the whole run's
    error (its duration - n T; the paper's "gait cycle" of 8 s, whose mean over 220 runs was 1.266 ms)."""

    period_s: float
    errors: TimeStats  # actual period - T, per cycle
    run_s: float  # first start -> last end
    run_error_s: float  # run_s - n T

    def __str__(self) -> str:
        n = self.errors.count
        return (
            f"period error over {n} cycles of {1e3 * self.period_s:g} ms: {self.errors.ms()}\n"
            f"run of {n} cycles: {self.run_s:.6f} s, error {1e3 * self.run_error_s:+.4f} ms "
            f"(mean period {1e3 * self.run_s / max(n, 1):.5f} ms)"
        )


@dataclass(frozen=True)
class MasterRun:
    """What a MasterCycle run saw: per-cycle records, with counts and statistics over them."""

    bus: str
    period_s: float
    read_window_s: float
    k_s: float
    expected: tuple[str, ...]  # synchronous TxPDOs the master collects, runtime.json order
    producers: Mapping[str, str]  # TxPDO -> node
    fields: Mapping[str, tuple[str, ...]]  # TxPDO -> its fields, in frame order
    records: tuple[CycleRecord, ...]
    duplicates: Mapping[str, int]  # a TxPDO received twice within one read window
    bad_frames: Mapping[str, int]  # a TxPDO whose payload did not decode (wrong length)
    send_errors: Mapping[str, int]  # frames the bus refused to send

    @property
    def cycles(self) -> int:
        return len(self.records)

    @property
    def nodes(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(self.producers[m] for m in self.expected))

    def missing_by_node(self) -> dict[str, int]:
        counts = dict.fromkeys(self.nodes, 0)
        for rec in self.records:
            for name in rec.missing:
                counts[self.producers[name]] += 1
        return counts

    def missing_by_message(self) -> dict[str, int]:
        counts = dict.fromkeys(self.expected, 0)
        for rec in self.records:
            for name in rec.missing:
                counts[name] += 1
        return counts

    @property
    def missing(self) -> int:
        return sum(len(rec.missing) for rec in self.records)

    @property
    def late(self) -> int:
        return sum(rec.late for rec in self.records)

    def complete_samples(self, node: str) -> int:
        """Cycles in which every TxPDO of `node` due at that SYNC arrived in the read window."""
        own = {m for m in self.expected if self.producers[m] == node}
        return sum(1 for rec in self.records if own & set(rec.due) and not own & set(rec.missing))

    def period_stats(self) -> PeriodStats:
        errors = [rec.period_s - self.period_s for rec in self.records]
        run = self.records[-1].end - self.records[0].start if self.records else 0.0
        return PeriodStats(self.period_s, TimeStats.of(errors), run, run - self.cycles * self.period_s)

    def read_stats(self) -> TimeStats:
        """SYNC sent -> last due TxPDO received, over complete cycles (Table 5, "reading")."""
        return TimeStats.of([rec.read_s for rec in self.records if rec.due and not rec.missing])

    def write_stats(self) -> TimeStats:
        """Time to compute and send the RxPDOs (Table 5, "writing")."""
        return TimeStats.of([rec.write_s for rec in self.records])

    def columns(self) -> list[str]:
        head = [
            "cycle",
            "sync",
            "start_s",
            "sync_s",
            "write_ms",
            "read_ms",
            "processing_ms",
            "waiting_ms",
            "period_ms",
            "missing",
        ]
        for name in self.expected:
            head += [f"{name}.{f}" for f in self.fields[name]] + [f"{name}.arrival_ms"]
        return head

    def rows(self) -> list[list[str]]:
        """The CSV rows: times relative to the first cycle's start; empty cells for frames that did not arrive."""
        t0 = self.records[0].start if self.records else 0.0
        out = []
        for rec in self.records:
            row = [
                str(rec.index),
                str(rec.sync_number),
                f"{rec.start - t0:.6f}",
                f"{rec.sync_sent - t0:.6f}",
                f"{1e3 * rec.write_s:.4f}",
                f"{1e3 * rec.read_s:.4f}",
                f"{1e3 * rec.processing_s:.4f}",
                f"{1e3 * rec.waiting_s:.4f}",
                f"{1e3 * rec.period_s:.4f}",
                " ".join(rec.missing),
            ]
            for name in self.expected:
                values = rec.values.get(name, {})
                row += ["" if f not in values else repr(values[f]) for f in self.fields[name]]
                arrival = rec.arrivals.get(name)
                row.append("" if arrival is None else f"{1e3 * (arrival - rec.sync_sent):.4f}")
            out.append(row)
        return out

    def write_csv(self, path: str | Path) -> Path:
        """Store the samples as a comma-separated file, like the paper's storage process (section 4.4.3)."""
        path = Path(path)
        with path.open("w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh)
            writer.writerow(self.columns())
            writer.writerows(self.rows())
        return path

    def summary(self) -> str:
        missing = self.missing_by_node()
        lines = [
            f"{self.cycles} cycles on {self.bus}: T = {1e3 * self.period_s:g} ms, read window "
            f"{1e3 * self.read_window_s:g} ms, K = {1e3 * self.k_s:g} ms",
            "complete samples: " + ", ".join(f"{n} {self.complete_samples(n)}" for n in self.nodes),
            f"missing frames: {self.missing}"
            + (" (" + ", ".join(f"{n} {c}" for n, c in missing.items() if c) + ")" if self.missing else ""),
            str(self.period_stats()),
            f"reading (SYNC -> all TxPDOs): {self.read_stats().ms()}",
            f"writing (RxPDOs): {self.write_stats().ms()}",
        ]
        if self.late:
            lines.append(f"late TxPDOs (after their read window): {self.late}")
        for what, counts in (
            ("duplicate", self.duplicates),
            ("undecodable", self.bad_frames),
            ("unsent", self.send_errors),
        ):
            if any(counts.values()):
                lines.append(f"{what} frames: " + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
        return "\n".join(lines)
