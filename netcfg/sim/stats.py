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
        "p99": round(float(np.percentile(x, 99, method="inverted_cdf")) / 1000, 3),
        "max": round(float(x.max()) / 1000, 3),
    }


def spread(x: np.ndarray) -> dict[str, float]:
    """min, mean, standard deviation and max of values already in the unit wanted (periods, errors)."""
    return {
        "min": round(float(x.min()), 3),
        "mean": round(float(x.mean()), 3),
        "std": round(float(x.std()), 3),
        "max": round(float(x.max()), 3),
    }
