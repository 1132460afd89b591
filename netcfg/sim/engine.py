"""The event core: integer-nanosecond virtual time, a heap of callbacks, and drifting node clocks.

Events at the same instant run in (priority, insertion) order. EARLY is for things that happen "at" an instant
(releases, deliveries, the tasks a delivery starts); TASKS for the activations of periodic tasks, which so read
whatever was delivered at their instant, whichever event was queued first; LATE for decisions taken once
everything at that instant has happened, such as CAN arbitration when the bus goes idle, so a frame queued at
exactly that instant joins it.
"""

from __future__ import annotations

import hashlib
import heapq
from collections.abc import Callable
from dataclasses import dataclass
from itertools import count
from typing import Any

import numpy as np

EARLY = 0
TASKS = 1
LATE = 2

PPB = 1_000_000_000
NEVER = 1 << 62  # an instant after every run


def drift_ns(local_ns: Any, drift_ppb: Any) -> Any:
    """What a clock drifting by drift_ppb adds to local_ns (NodeClock.to_global): local_ns * drift_ppb // PPB,
    exactly, for integers or int64 arrays alike, without forming the product, which in int64 overflows at the
    largest --drift (100,000 ppm) once local time passes 92 s."""
    return (local_ns // PPB) * drift_ppb + (local_ns % PPB) * drift_ppb // PPB


class Simulator:
    def __init__(self, seed: int = 0) -> None:
        self.now = 0
        self.seed = seed
        self.rng = np.random.default_rng(seed)  # the sources not given a generator of their own (see random())
        self._queue: list[tuple[int, int, int, Callable[..., Any], Any]] = []
        self._seq = count()
        self.until = 0  # the end of the current run_until: loops that batch work must not pass it
        self.stop: Callable[[], object] | None = None  # the current run_until's stop(), for the same loops

    def at(self, t: int, fn: Callable[..., Any], arg: Any = None, priority: int = EARLY) -> None:
        """Call fn(arg) at virtual time t (never before now)."""
        now = self.now
        heapq.heappush(self._queue, (t if t > now else now, priority, next(self._seq), fn, arg))

    def random(self, source: str) -> np.random.Generator:
        """The generator of one random source (a task's execution times, a node's clock, ...), seeded from the
        run's seed and the source's name: its draws do not depend on when other sources draw, so a computation
        that takes a source's draws all at once gets the same numbers as one taking them event by event, and a
        change to one task of a spec leaves every other source's draws as they were."""
        key = hashlib.sha256(source.encode()).digest()
        words = tuple(int.from_bytes(key[i : i + 4], "little") for i in range(0, 16, 4))
        return np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=words))

    def skip_to(self, t: int) -> None:
        """Drop every queued event and set now = t: the run up to t was computed another way (netcfg.sim.whole_run)."""
        self._queue.clear()
        self.now = max(self.now, t)

    def run_until(self, t_end: int, stop: Callable[[], object] | None = None) -> None:
        """Run every event before t_end (or until stop() turns true after an event); then now = t_end."""
        queue = self._queue
        pop = heapq.heappop
        self.until = t_end
        self.stop = stop
        while queue and queue[0][0] < t_end:
            t, _, _, fn, arg = pop(queue)
            self.now = t
            fn(arg)
            if stop is not None and stop():
                return
        if t_end > self.now:
            self.now = t_end


@dataclass(frozen=True)
class NodeClock:
    """A node's local clock: global = phase + local * (1 + drift), drift in parts per billion.

    Free-running periodic activities are defined in local time, so two nodes with different drifts slide
    against each other as they do on real robots (seed 002, section 5: "drifts in the local clocks")."""

    phase_ns: int = 0
    drift_ppb: int = 0

    def to_global(self, local_ns: int) -> int:
        return self.phase_ns + local_ns + drift_ns(local_ns, self.drift_ppb)
