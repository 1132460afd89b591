"""One configured message as the checker (netcfg.verify.checker) follows it: its running figures and histograms
(MessageState), the checks on each batch of its frames (size, gap, early, late, range, jitter), those at the end of
the log (never_seen, trailing gaps, rate), and its part of the report.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from netcfg.runtime import Message, columns
from netcfg.timing.load import FrameTiming

MAX_VIOLATIONS = 1000  # kept in detail; more are counted
HIST_BINS = 60

# a finding: (kind, the message or None, log time in us, what was found), counted and kept by the checker
Finding = Callable[[str, "MessageState | None", int, str], None]


@dataclass
class Spread:
    """A quantity's running figures over the log, in us: least, largest, sum and count, and a histogram over fixed
    bins with an underflow and an overflow bin (kept only where the checker gives it edges)."""

    least: int | None = None
    largest: int | None = None
    total: int = 0
    n: int = 0
    counts: NDArray[np.int64] = field(default_factory=lambda: np.zeros(HIST_BINS + 2, np.int64))
    edges: NDArray[np.float64] | None = None

    def add(self, values: NDArray[np.int64]) -> None:
        """A batch's values (at least one)."""
        least, largest = int(values.min()), int(values.max())
        self.least = least if self.least is None else min(self.least, least)
        self.largest = largest if self.largest is None else max(self.largest, largest)
        self.total += int(values.sum())
        self.n += len(values)
        if self.edges is not None:
            self.counts += hist(values, self.edges)

    def summary(self) -> dict[str, Any] | None:
        """min, mean and max for the report; None before any value."""
        if not self.n:
            return None
        return {"min": self.least, "mean": round(self.total / self.n, 3), "max": self.largest}


@dataclass
class MessageState:
    """One configured message as the checker follows it: running figures, histograms and what was found."""

    msg: Message
    bus: int
    timing: FrameTiming  # the frame as check times it (netcfg.timing.load.frame_timing)
    period_us: float | None  # periodic: the period; sporadic: None
    min_gap_us: float | None  # sporadic: the least admissible interval
    slack_us: float  # analysed jitter + worst-case response - best transmission time
    wcrt_us: float | None
    response_ref: str | None  # "sync": response measured from the last SYNC of the bus; "tm"; "command" (a reply)
    ref_key: int | None = None  # the reference's key in the checker (None: the bus's own, SYNC or TM)
    ref_delay_us: float = 0.0  # a synchronous TPDO is queued its drive's tx_delay after the SYNC: its bound's start
    count: int = 0
    last_t: int | None = None
    first_t: int | None = None
    intervals: Spread = field(default_factory=Spread)  # between frames
    dev_max: int = 0  # largest |interval - period| outside gaps
    missing: int = 0
    responses: Spread = field(default_factory=Spread)  # from the frame a response is measured from
    violations: int = 0
    warnings: int = 0
    range_out: dict[str, list[Any]] = field(default_factory=dict)  # signal -> [count, first_t, worst value]
    bad_size: list[int] = field(default_factory=list)  # [count, first_t, length]
    jitter_out: list[Any] | None = None  # intervals outside period +- slack: [count, first_t, worst, its t, its iv]
    excused: list[tuple[int, int]] = field(default_factory=list)  # spans of fault phases that silence it
    excused_missing: int = 0  # periods missing inside them: the fault's, not violations

    def _excused(self, start: NDArray[np.int64], end: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Which gaps [start, end] overlap a fault phase that silences this message (netcfg.verify.fault_phases)."""
        hit = np.zeros(len(start), bool)
        for lo, hi in self.excused:
            hit |= (start <= hi) & (end >= lo)
        return hit


    def take(
        self,
        t: NDArray[np.int64],
        length: NDArray[np.int16],
        data: NDArray[np.uint8],
        odd: NDArray[np.bool_],
        refs: NDArray[np.int64] | None,
        ref_offset: int,
        violation: Finding,
    ) -> None:
        """A batch's frames of this message: size, intervals (gaps, early frames) and, from `refs` (the frames a
        response is measured from, the last before the batch first; ref_offset added to each), responses."""
        st, m = self, self.msg
        if st.first_t is None:
            st.first_t = int(t[0])
        st.count += len(t)
        # payload length; a CAN FD message's frames carry its padded length (odd: FD or remote, as expected for it)
        # a remote message's frames are remote frames, their DLC the length they ask for (no payload)
        wrong = ~odd if m.remote else (length != m.frame_size) if m.fd else (length != m.size) | odd
        if wrong.any():
            if not st.bad_size:
                st.bad_size = [0, int(t[wrong][0]), int(length[wrong][0])]
            st.bad_size[0] += int(wrong.sum())
        # intervals, the previous batch's last frame included
        prev = np.concatenate([[st.last_t], t]) if st.last_t is not None else t
        st.last_t = int(t[-1])
        iv = np.diff(prev)
        if len(iv):
            st.intervals.add(iv)
            ends = prev[1:]
            if st.period_us is not None:
                st._periodic(iv, ends, violation)
            elif st.min_gap_us is not None:
                early = iv < st.min_gap_us - st.slack_us
                for k in np.flatnonzero(early)[:MAX_VIOLATIONS]:
                    violation(
                        "early",
                        st,
                        int(ends[k]),
                        f"{iv[k] / 1000:.3f} ms after the previous frame; the analysis assumes at least "
                        f"{st.min_gap_us / 1000:.3f} ms (less {st.slack_us:.0f} us jitter), "
                        f"{(st.min_gap_us - st.slack_us - iv[k]):.0f} us sooner",
                    )
        # response from the SYNC (TM) before each frame
        if st.response_ref is not None and refs is not None and len(refs):
            at = np.searchsorted(refs, t, side="left") - 1
            ok = at >= 0
            resp = t[ok] - refs[at[ok]] + ref_offset
            if len(resp):
                st.responses.add(resp)
                if st.wcrt_us is not None:
                    when = t[ok]
                    bound = st.wcrt_us + st.ref_delay_us
                    for k in np.flatnonzero(resp > bound)[:MAX_VIOLATIONS]:
                        after = f" (its drive's tx_delay {st.ref_delay_us:.0f} + {st.wcrt_us:.0f})"
                        violation(
                            "late",
                            st,
                            int(when[k]),
                            f"{resp[k]:.0f} us after {_reference(st.response_ref)}; the analysed worst case is "
                            f"{bound:.0f} us{after if st.ref_delay_us else ''}, {resp[k] - bound:.0f} us late",
                        )
        if m.signals and not wrong.all():
            st._ranges(t[~wrong], data[~wrong])

    def _periodic(self, iv: NDArray[np.int64], ends: NDArray[np.int64], violation: Finding) -> None:
        st, period = self, self.period_us
        assert period is not None
        periods = periods_spanned(iv, period, st.slack_us)
        gaps = periods >= 2
        if st.excused and gaps.any():
            faults = gaps & st._excused(ends - iv, ends)
            st.excused_missing += int((periods[faults] - 1).sum())
            judged = gaps & ~faults
        else:
            judged = gaps
        for k in np.flatnonzero(judged)[:MAX_VIOLATIONS]:
            missing = int(periods[k] - 1)
            st.missing += missing
            violation(
                "gap",
                st,
                int(ends[k]),
                f"{missing} period{'s' if missing > 1 else ''} missing: {iv[k] / 1000:.3f} ms since the previous "
                f"frame, period {period / 1000:g} ms",
            )
        if judged.sum() > MAX_VIOLATIONS:
            st.missing += int((periods[judged] - 1)[MAX_VIOLATIONS:].sum())
        dev = np.abs(iv[~gaps] - period)
        if len(dev):
            st.dev_max = max(st.dev_max, int(np.ceil(dev.max())))
        if st.response_ref == "sync":  # a synchronous TPDO follows the SYNC: its response is the check
            return
        beyond = np.where(gaps, 0, np.abs(iv - period) - st.slack_us)
        outside = beyond > 0
        if outside.any():
            k = int(np.argmax(beyond))
            if st.jitter_out is None:
                st.jitter_out = [0, int(ends[outside][0]), 0.0, 0, 0]
            st.jitter_out[0] += int(outside.sum())
            if beyond[k] > st.jitter_out[2]:
                st.jitter_out[2:] = [float(beyond[k]), int(ends[k]), int(iv[k])]


    def _ranges(self, t: NDArray[np.int64], data: NDArray[np.uint8]) -> None:
        """Signals decoded as the codec decodes them (byte order, sign, float, multiplexing: netcfg.runtime.columns),
        each in the frames that carry it; a signal beyond the bytes a batch keeps (PAYLOAD_COLUMNS) is not seen."""
        st = self
        signals = [s for s in st.msg.signals if columns.fits(s, data.shape[1])]
        carried = columns.present_rows(signals, data)
        for sig in signals:
            if sig.minimum is None and sig.maximum is None:
                continue
            value = columns.physical(sig, columns.take(sig, data))
            low = carried[sig.name] & (value < sig.minimum if sig.minimum is not None else False)
            high = carried[sig.name] & (value > sig.maximum if sig.maximum is not None else False)
            out = low | high
            if out.any():
                rec = st.range_out.setdefault(sig.name, [0, int(t[out][0]), None])
                rec[0] += int(out.sum())
                lo = float(value[low].min()) if low.any() else None
                hi = float(value[high].max()) if high.any() else None
                for v in (lo, hi):
                    if v is not None and (rec[2] is None or _excess(sig, v) > _excess(sig, rec[2])):
                        rec[2] = v

    def close(
        self, end: int | None, span: int, ppm: float, since: Callable[[int], int], violation: Finding, jitter: Finding
    ) -> None:
        """End of the log (its last frame at `end`, `span` after the first judged one): a message never seen, trailing
        gaps, too few frames for the period (a sender's clock `ppm` slow at most), and what the batches found
        (`jitter`: the finding for intervals outside the analysed jitter, a violation or a warning). `since` turns a
        log time into report time."""
        st, m = self, self.msg
        if st.count == 0:
            # a periodic message is due within its period and slack of the log's start; a sporadic one may
            # rightly never come (its rate is a bound, not a promise)
            if m.kind == "periodic" and st.period_us is not None and span > st.period_us + st.slack_us:
                violation("never_seen", st, end or 0, f"no frame with id {id_text(m.id, m.extended)}")
            return
        if st.period_us is not None and end is not None and st.last_t is not None:
            trailing = int(periods_spanned(np.array([end - st.last_t]), st.period_us, st.slack_us)[0]) - 1
            if trailing >= 1 and st._excused(np.array([st.last_t]), np.array([end]))[0]:
                st.excused_missing += trailing
            elif trailing >= 1:
                st.missing += trailing
                violation(
                    "gap",
                    st,
                    end,
                    f"{trailing} period{'s' if trailing > 1 else ''} missing at the end of the log: last frame "
                    f"{(end - st.last_t) / 1000:.3f} ms before it, period {st.period_us / 1000:g} ms",
                )
        if st.period_us is not None and st.first_t is not None and st.last_t is not None:
            st._rate(ppm, violation)
        if st.jitter_out is not None:
            count, first, worst, worst_t, worst_iv = st.jitter_out
            assert st.period_us is not None
            detail = (
                f"{count} of {st.intervals.n} intervals outside the analysed {st.period_us / 1000:g} ms +- "
                f"{st.slack_us:.0f} us (jitter + worst-case response - transmission time), from "
                f"{since(first) / 1e6:.6f} s; the worst {worst_iv / 1000:.3f} ms at "
                f"{since(worst_t) / 1e6:.6f} s, "
                f"{worst:.0f} us beyond"
            )
            jitter("jitter", st, first, detail)
        if st.bad_size:
            count, first, length = st.bad_size
            violation(
                "size",
                st,
                first,
                f"{count} data frame(s) with {length} bytes; the message is a remote frame" if m.remote else
                f"{count} frame(s) with {length} bytes (or CAN FD / remote); the message has {m.size}",
            )
        for name, (count, first, worst) in st.range_out.items():
            sig = next(s for s in m.signals if s.name == name)
            violation(
                "range",
                st,
                first,
                f"signal {name} outside [{_number(sig.minimum)}, {_number(sig.maximum)}] in {count} frame(s), "
                f"worst {worst:g}{' ' + sig.unit if sig.unit else ''}",
            )

    def _rate(self, ppm: float, violation: Finding) -> None:
        """Fewer frames than the period needs over the message's span, beyond the gaps already counted: a sender
        whose period is longer than configured. The sender's clock may run slow by the clock tolerance."""
        st = self
        assert st.period_us is not None and st.first_t is not None and st.last_t is not None
        span = st.last_t - st.first_t
        needed = int(np.floor((span * (1 - ppm / 1e6) - st.slack_us) / st.period_us)) + 1
        short = needed - st.count - st.missing - st.excused_missing
        if short > 0:
            violation(
                "rate",
                st,
                st.last_t,
                f"{st.count} frames over {span / 1e6:.6f} s; a {st.period_us / 1000:g} ms period needs at least "
                f"{needed} ({short} more than the gaps explain; mean period {span / max(st.count - 1, 1) / 1000:.3f} "
                f"ms, clock tolerance {ppm:g} ppm)",
            )

    def report(self) -> dict[str, Any]:
        st, m = self, self.msg
        period, response = st.intervals.summary(), st.responses.summary()
        return {
            "name": m.name,
            "bus": m.bus,
            "id": m.id,
            "extended": m.extended,
            "kind": m.kind,
            "count": st.count,
            "period_us": period,
            "nominal_period_us": None if st.period_us is None else round(st.period_us, 3),
            "jitter_us": st.dev_max if period is not None and st.period_us is not None else None,
            "analysed_jitter_us": round(st.slack_us, 3) if st.period_us is not None and not st.response_ref else None,
            "response_us": response,
            "response_from": st.response_ref,
            "wcrt_us": st.wcrt_us,
            "missing": st.missing,
            "missing_in_faults": st.excused_missing,
            "within_analysis": None if st.count == 0 and m.kind == "on-demand" else st.violations == 0,
            "warnings": st.warnings,
            "histograms": {
                "period": _hist_doc(st.intervals.counts, st.intervals.edges),
                "response": _hist_doc(st.responses.counts, st.responses.edges),
            },
        }


def periods_spanned(iv: NDArray[np.int64], period: float, slack: float) -> NDArray[np.int64]:
    """How many periods each interval spans, for counting missing frames: the nearest whole number (a log cannot
    tell a frame later than half a period from a missing one), but no more than the fewest the analysis allows
    (frames k periods apart are k * period +- slack apart), so a late frame within the analysed jitter is never
    counted as a missing one."""
    nearest = np.floor(iv / period + 0.5)
    fewest = np.ceil((iv - slack) / period)
    return np.maximum(np.minimum(nearest, fewest), 1).astype(np.int64)



def hist(values: NDArray[Any], edges: NDArray[np.float64]) -> NDArray[np.int64]:
    """Counts per bin, with an underflow and an overflow bin at the ends."""
    idx = np.searchsorted(edges, values, side="right")
    return np.bincount(idx, minlength=len(edges) + 1).astype(np.int64)


def _hist_doc(counts: NDArray[np.int64], edges: NDArray[np.float64] | None) -> dict[str, Any] | None:
    if edges is None or not counts.any():
        return None
    return {"edges_us": [round(float(e), 3) for e in edges], "counts": [int(c) for c in counts]}


def _excess(sig: Any, v: float) -> float:
    low = sig.minimum - v if sig.minimum is not None else 0.0
    high = v - sig.maximum if sig.maximum is not None else 0.0
    return max(low, high)


def _number(x: float | None) -> str:
    return "-" if x is None else f"{x:g}"


def _reference(ref: str) -> str:
    """What a response is measured from, in words: SYNC, TM, or a reply's command."""
    return "its command" if ref == "command" else ref.upper()


def id_text(can_id: int, extended: bool) -> str:
    return f"0x{can_id:08X}" if extended else f"0x{can_id:03X}"
