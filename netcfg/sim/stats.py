"""Summaries of simulated times (integer ns in, microseconds out), shared by every report of the simulator."""

from __future__ import annotations

import numpy as np


def stats_us(x: np.ndarray) -> dict[str, float] | None:
    """min, mean, p99 (nearest rank: the ceil(0.99 n)-th smallest sample) and max in us; None without samples."""
    if len(x) == 0:
        return None
    return {
        "min": round(float(x.min()) / 1000, 3),
        "mean": round(float(x.mean()) / 1000, 3),
        "p99": round(nearest_rank(x, 99) / 1000, 3),
        "max": round(float(x.max()) / 1000, 3),
    }


def nearest_rank(x: np.ndarray, percent: int) -> int:
    """The ceil(percent * n / 100)-th smallest of integer samples (np.percentile's "inverted_cdf"). Counted in a
    histogram when the samples span a range of the order of their number, as response times and latencies in ns
    do: np.partition takes 30 ms on 900,000 response times that are mostly one value, the histogram 3 ms."""
    n = len(x)
    k = -(-percent * n // 100)
    lo = int(x.min())
    if int(x.max()) - lo <= 4 * n + 4096:
        return lo + int(np.searchsorted(np.cumsum(np.bincount(x - lo)), k))
    return int(np.partition(x, k - 1)[k - 1])


def spread(x: np.ndarray) -> dict[str, float]:
    """min, mean, standard deviation and max of values already in the unit wanted (periods, errors)."""
    return {
        "min": round(float(x.min()), 3),
        "mean": round(float(x.mean()), 3),
        "std": round(float(x.std()), 3),
        "max": round(float(x.max()), 3),
    }
