"""ResponseScheduler: the one thread that sends the simulated drives' delayed answers (netcfg.runtime.drives)."""

from __future__ import annotations

import heapq
import itertools
import logging
import threading
from collections.abc import Callable

from netcfg.runtime.clock import Clock, SystemClock

log = logging.getLogger(__name__)


class ResponseScheduler:
    """One thread that runs actions at given times: the drives' delayed TPDO answers.

    `call_later(delay_s, action)` puts the action on a heap ordered by due time (clock.now() + delay_s); the thread
    sleeps on a condition variable until the earliest is due, runs every action that is due, and wakes early when an
    earlier one is added. It starts on the first call_later (a bench without delays starts no thread) and close() stops
    it, dropping what is still pending. Actions run on this thread one after the other, so each must be short (a few
    bus.send calls); one that raises is logged and does not stop the others.

    Waits are condition-variable timeouts in seconds, so `clock` must count real seconds (the drives run on threads
    in real time); an action runs at its due time plus the operating system's wake-up latency (tens of microseconds
    on an idle machine), never before it. It does not busy-wait: a spinning thread would hold the interpreter lock
    the dispatcher and the master need.
    """

    def __init__(self, clock: Clock | None = None, name: str = "netcfg-drive-responses") -> None:
        self.clock: Clock = clock or SystemClock()
        self.name = name
        self._cond = threading.Condition()
        self._heap: list[tuple[float, int, Callable[[], None]]] = []
        self._order = itertools.count()  # ties run in the order they were scheduled
        self._thread: threading.Thread | None = None
        self._closed = False
        self.dropped = 0  # actions still pending at close()

    def call_later(self, delay_s: float, action: Callable[[], None]) -> None:
        """Run `action` on the scheduler thread `delay_s` from now; ignored once the scheduler is closed."""
        due = self.clock.now() + delay_s
        with self._cond:
            if self._closed:
                return
            seq = next(self._order)
            heapq.heappush(self._heap, (due, seq, action))
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
                self._thread.start()
            elif self._heap[0][1] == seq:
                self._cond.notify()  # the new action is the earliest: the thread waits for it instead

    def close(self, timeout: float = 2.0) -> None:
        """Stop the thread; pending actions are dropped (counted in `dropped`)."""
        with self._cond:
            self._closed = True
            self.dropped += len(self._heap)
            self._heap.clear()
            self._cond.notify()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    @property
    def pending(self) -> int:
        with self._cond:
            return len(self._heap)

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._closed:
                    if not self._heap:
                        self._cond.wait()
                        continue
                    wait = self._heap[0][0] - self.clock.now()
                    if wait <= 0:
                        break
                    self._cond.wait(wait)
                if self._closed:
                    return
                now = self.clock.now()
                due = []
                while self._heap and self._heap[0][0] <= now:
                    due.append(heapq.heappop(self._heap)[2])
            for action in due:  # outside the lock: call_later from another thread must not wait for a send
                try:
                    action()
                except Exception:
                    log.exception("%s: a scheduled action failed", self.name)
