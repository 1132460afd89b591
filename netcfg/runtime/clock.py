"""The clock a master cycle runs on.

A master cycle (netcfg.runtime.canopen_master.MasterCycle) reads time and waits only through a Clock, and talks to
the network only through a python-can bus. Handed SystemClock and a real or virtual python-can bus it runs in real
time; handed netcfg's simulator clock and bus (whose recv(timeout) advances virtual time) the same code runs in
virtual time. Times are float seconds on the clock's own monotonic scale; only differences mean anything.
"""

from __future__ import annotations

import time
from typing import Protocol, runtime_checkable

__all__ = ["Clock", "CycleTiming", "SystemClock"]


@runtime_checkable
class Clock(Protocol):
    def now(self) -> float:
        """Seconds on a monotonic scale."""
        ...

    def sleep_until(self, t: float) -> None:
        """Return once now() >= t (at once when t is already past)."""
        ...


@runtime_checkable
class CycleTiming(Protocol):
    """What a master's processor adds when the master runs in virtual time (a simulator's hook): on real hardware
    the computation and the wake-up latency take their time by themselves."""

    def work_s(self, cycle: int) -> float:
        """Seconds the master computes in this cycle before its RxPDOs go out."""
        ...

    def late_s(self) -> float:
        """Seconds a wait ends after its target (the operating system's wake-up latency)."""
        ...


class SystemClock:
    """Real time: time.perf_counter, the finest monotonic clock Python has.

    time.sleep() wakes late by the operating system's timer slack and scheduling latency: tens of microseconds on an
    idle Linux machine, a millisecond or more under load or on Windows. A 20 ms control period kept by sleep alone
    would drift by that much every cycle. So sleep_until() sleeps until `spin_s` (0.5 ms) before the target and
    busy-waits the rest, which costs at most `spin_s` of one core per cycle and lands within a few microseconds.
    """

    def __init__(self, spin_s: float = 0.0005) -> None:
        if spin_s < 0:
            raise ValueError("spin_s must be >= 0")
        self.spin_s = spin_s

    def now(self) -> float:
        return time.perf_counter()

    def sleep_until(self, t: float) -> None:
        remaining = t - time.perf_counter()
        if remaining > self.spin_s:
            time.sleep(remaining - self.spin_s)
        while time.perf_counter() < t:
            pass
