"""Release instants of free-running periodic traffic, vectorised over every source of a bus.

Source i releases at local instants off_i + floor(k * P_i) (k = 0, 1, ...) on its producer's clock, mapped to
global time through the clock's phase and drift, plus a release jitter drawn uniformly in [0, J_i]. The period
P_i is exact: an integer number of nanoseconds, or a fraction of them (a rate given in hertz, such as 15 kHz's
66,666 2/3 ns, keeps its long-run rate instead of a rounded period's). Releases after the producer's crash instant
never happen; they are counted in `cut` (source -> instances).

Jitter takes one random draw per release of every source as soon as one source has jitter (none otherwise).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction

import numpy as np

from netcfg.sim.engine import NEVER, PPB, drift_ns


class PeriodicStreams:
    def __init__(
        self,
        sources: Sequence[int],
        periods: Sequence[int | Fraction],
        offsets: Sequence[int],
        phases: Sequence[int],
        drifts_ppb: Sequence[int],
        jitters: Sequence[int],
        until: Sequence[int],
        rng: np.random.Generator,
        cut: dict[int, int] | None = None,
    ) -> None:
        exact = [Fraction(p) for p in periods]
        self.src = np.asarray(sources, dtype=np.int64)
        self.num = np.asarray([p.numerator for p in exact], dtype=np.int64)  # period = num / den ns
        self.den = np.asarray([p.denominator for p in exact], dtype=np.int64)
        self.whole = bool((self.den == 1).all())
        self.offset = np.asarray(offsets, dtype=np.int64)
        self.phase = np.asarray(phases, dtype=np.int64)
        self.drift = np.asarray(drifts_ppb, dtype=np.int64)
        self.jitter = np.asarray(jitters, dtype=np.int64)
        self.until = np.asarray(until, dtype=np.int64)
        self.rng = rng
        self.cut = cut
        self._scale = 1.0 + self.drift / PPB
        self._period = self.num / self.den  # only to bound k; the instants themselves are exact
        self._jittered = bool(self.jitter.any())
        self._index = np.arange(len(self.src))
        if len(self.src) == 1:
            self._one = (int(self.phase[0]), float(self._scale[0]), int(self.offset[0]), float(self._period[0]))

    @property
    def chunk_free(self) -> bool:
        """The releases do not depend on how time is cut into [t0, t1) calls: no random draws (jitter), and no crash
        instant whose releases after it are counted per call."""
        return not self._jittered and not bool((self.until < NEVER).any())

    def __call__(self, t0: int, t1: int) -> tuple[np.ndarray, np.ndarray]:
        """Every release whose nominal instant falls in [t0, t1): (instants, sources), source by source in the
        order they were given, each in time order (jitter may put an instant a little after t1)."""
        n = len(self.src)
        if n == 0:
            return np.empty(0, np.int64), np.empty(0, np.int64)
        # k from a little before t0 to a little after t1 on each source's clock
        which: np.ndarray | None = None
        if n == 1:  # plain floats, and the parameters broadcast: nothing to gather
            phase, scale, offset, period = self._one
            lo = max(math.floor(((t0 - phase) / scale - offset) / period) - 1, 0)
            k = np.arange(lo, math.ceil(((t1 - phase) / scale - offset) / period) + 2)
        else:
            t = np.array((t0, t1), dtype=np.float64)[:, None]
            x = ((t - self.phase) / self._scale - self.offset) / self._period
            lo_k = np.maximum(np.floor(x[0]).astype(np.int64) - 1, 0)
            counts = np.maximum(np.ceil(x[1]).astype(np.int64) + 2 - lo_k, 0)
            total = int(counts.sum())
            which = np.repeat(self._index, counts)
            k = np.arange(total) - np.repeat(np.cumsum(counts) - counts - lo_k, counts)

        def each(a: np.ndarray) -> np.ndarray:
            """A per-source parameter for every candidate release (one source's broadcasts as it is)."""
            return a if which is None else a[which]

        local = each(self.offset) + (k * each(self.num) if self.whole else k * each(self.num) // each(self.den))
        base = each(self.phase) + local + drift_ns(local, each(self.drift))
        due = (base >= t0) & (base < t1)
        keep = due & (base < each(self.until))
        if self.cut is not None:  # releases a crashed sender never makes: counted as lost
            gone = np.broadcast_to(each(self.src), base.shape)[due & ~keep]
            for s, c in zip(*np.unique(gone, return_counts=True)):
                self.cut[int(s)] = self.cut.get(int(s), 0) + int(c)
        base = base[keep]
        if which is not None:
            which = which[keep]
        if self._jittered:
            jit = each(self.jitter)
            if len(base) and jit.any():
                base = base + (self.rng.random(len(base)) * (jit + 1)).astype(np.int64)
        return base, np.full(len(base), self.src[0]) if which is None else self.src[which]
