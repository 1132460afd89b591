"""Release instants of free-running periodic traffic, vectorised over every source of a bus.

Source i releases at local instants off_i + k * P_i (k = 0, 1, ...) on its producer's clock, mapped to global
time through the clock's phase and drift, plus a release jitter drawn uniformly in [0, J_i]. Releases after
the producer's crash instant never happen; they are counted in `cut` (source -> instances).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from netcfg.sim.engine import PPB

NEVER = 1 << 62


class PeriodicStreams:
    def __init__(
        self,
        sources: Sequence[int],
        periods: Sequence[int],
        offsets: Sequence[int],
        phases: Sequence[int],
        drifts_ppb: Sequence[int],
        jitters: Sequence[int],
        until: Sequence[int],
        rng: np.random.Generator,
        cut: dict[int, int] | None = None,
    ) -> None:
        self.src = np.asarray(sources, dtype=np.int64)
        self.period = np.asarray(periods, dtype=np.int64)
        self.offset = np.asarray(offsets, dtype=np.int64)
        self.phase = np.asarray(phases, dtype=np.int64)
        self.drift = np.asarray(drifts_ppb, dtype=np.int64)
        self.jitter = np.asarray(jitters, dtype=np.int64)
        self.until = np.asarray(until, dtype=np.int64)
        self.rng = rng
        self.cut = cut

    def __call__(self, t0: int, t1: int) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.src)
        if n == 0:
            return np.empty(0, np.int64), np.empty(0, np.int64)
        scale = 1.0 + self.drift / PPB
        lo = np.floor(((t0 - self.phase) / scale - self.offset) / self.period).astype(np.int64) - 1
        hi = np.ceil(((t1 - self.phase) / scale - self.offset) / self.period).astype(np.int64) + 1
        lo = np.maximum(lo, 0)
        counts = np.maximum(hi - lo + 1, 0)
        total = int(counts.sum())
        which = np.repeat(np.arange(n), counts)
        first = np.repeat(np.cumsum(counts) - counts, counts)
        k = lo[which] + (np.arange(total) - first)
        local = self.offset[which] + k * self.period[which]
        base = self.phase[which] + local + local * self.drift[which] // PPB
        due = (base >= t0) & (base < t1)
        keep = due & (base < self.until[which])
        if self.cut is not None:  # releases a crashed sender never makes: counted as lost
            for s, n in zip(*np.unique(self.src[which[due & ~keep]], return_counts=True)):
                self.cut[int(s)] = self.cut.get(int(s), 0) + int(n)
        base, which = base[keep], which[keep]
        jit = self.jitter[which]
        if jit.any():
            base = base + (self.rng.random(len(base)) * (jit + 1)).astype(np.int64)
        return base, self.src[which]
