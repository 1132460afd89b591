"""End-to-end latency of flows: from the first producer's activation to the last consumer's use.

Two models, reported side by side where both apply (seed 002, Table 3 and Figure 4):

* unsynchronised: every node runs on its own clock. A task that consumes data waits up to one of its periods
  for its next activation (0 for a task started by the message itself); a message sent by the task that
  produced the data goes out as it ends (on CAN its node's tx_delay later) and takes between its nominal frame
  time and its worst-case response time; a message with its own period, different from its producer's, first
  waits up to one period. A sporadic message goes at most once per minimum inter-arrival time, so its sender
  takes other data on only with the runs that send it (Rates.send_spacing).
* synchronised (FTT-CAN): the master's schedule fixes when every synchronous message is sent and every
  triggered task starts, so each step takes the first instance at or after the moment its data is ready,
  and the latency range comes out of the schedule itself, over every instance of the macro-cycle.

A step may hold several items in parallel; the data of all of them is needed, so the step ends with the last
(at the earliest, each item along its own path: its data's age counts from a stamp no newer than its inputs').
A reader that joins data of different first-step items takes the oldest, and may first take it only once the
other items have data at least as new: the wait for their next release (their offsets' distance on one clock or
EC grid, else up to a period), but never longer than the oldest data's own renewal.

This module holds the free-running model (unsynchronised) and names the analysis' whole interface; the FTT-CAN
model is netcfg.timing.flow_ftt's, the CANopen one flow_canopen's, the tasks' and messages' rates flow_rates' and
the bounds of one step flow_steps'.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import lcm

from netcfg import model
from netcfg.timing import clocks
from netcfg.timing.flow_canopen import SyncTimes, synchronised_canopen
from netcfg.timing.flow_ftt import FttTimes, synchronised
from netcfg.timing.flow_inputs import step_inputs
from netcfg.timing.flow_rates import Rates
from netcfg.timing.flow_steps import (
    Delivery,
    TaskTimes,
    clock_tolerance,
    message_period,
    queue_delay,
    same_rate,
    sampling,
    sending_tasks,
    sent_by_producer,
    start_delay,
    start_spread,
    task_period,
    task_response,
)

__all__ = [  # the analysis as netcfg.analyze, netcfg.tune, netcfg.resolve and the emitters use it
    "Delivery",
    "FlowLatency",
    "FttTimes",
    "SyncTimes",
    "same_rate",
    "sending_tasks",
    "synchronised",
    "synchronised_canopen",
    "unsynchronised",
]

_MAX_PHASES = 10_000  # releases of one item in two items' common period that are examined one by one


@dataclass(frozen=True)
class FlowLatency:
    name: str
    unsync: tuple[int, int | None]
    sync: tuple[int, int] | None
    delivery_unsync: tuple[int, int | None] | None  # to the last message's reception
    delivery_sync: tuple[int, int] | None


def _add(a: int | None, b: int | None) -> int | None:
    return None if a is None or b is None else a + b


def unsynchronised(
    m: model.Model,
    flow: model.Flow,
    chained: dict[str, Delivery],
    task_ns: TaskTimes | None = None,
    ftt: FttTimes | None = None,
) -> tuple[tuple[int, int | None], tuple[int, int | None] | None]:
    """Free-running steps. With `ftt`, the bus runs its FTT-CAN schedule: synchronous messages go out in their own
    ECs, never at once when their producer finishes (they wait for their slot as any message with its own period
    does), and the first step's synchronous messages and triggered tasks keep to the EC grid."""
    scheduled = frozenset(ftt.entries) if ftt is not None else frozenset()
    lo, hi = 0, 0  # type: int, int | None
    refresh: int | None = None  # how often the data reaching this step is renewed
    unknown = False  # ... at no known rate
    item_lo: dict[str, int] = {}  # the step before's items: each one's earliest
    item_hi: dict[str, int | None] = {}  # ... and latest
    delivery: tuple[int, int | None] | None = None
    prev: model.FlowStep | None = None
    ppm = clock_tolerance(m)
    rates = Rates(m, chained, task_ns, scheduled)
    releases = {ref: _release(rates, flow.steps[0].kind, ref, ftt, ppm) for ref in flow.steps[0].refs}
    streams: dict[str, tuple[str, ...]] = {ref: (ref,) for ref in flow.steps[0].refs}  # item -> the stream it carries

    def consumers(name: str) -> tuple[str, ...]:
        return m.messages[name].consumers

    def producer(name: str) -> str:
        return m.messages[name].producer

    for i, step in enumerate(flow.steps):
        last = i == len(flow.steps) - 1
        outs: list[tuple[int, int | None]] = []
        periods: list[int | None] = []  # how often each item renews its data (None: unknown)
        carried: dict[str, tuple[str, ...]] = {}
        for ref in step.refs:
            # of a join, per stream it reads: (wait for the rest, renewal); None where no rate bounds it
            heads: list[tuple[int | None, int | None]] = []
            base = 0  # its inputs' earliest: the age of its data, counted from a stamp no newer than theirs
            inputs: tuple[str, ...] = ()
            if i:
                assert prev is not None
                inputs = step_inputs(prev, step.kind, ref, consumers, producer)
                base = max(item_lo[r] for r in inputs)
                read = sorted({streams[r] for r in inputs})
                carried[ref] = read[0] if len(read) == 1 else tuple(sorted({o for s in read for o in s}))
                if len(read) > 1:
                    heads = [
                        (
                            _latest([_gap(a, b, releases, ppm) for b in read if b != a]),
                            releases[a[0]].renewal if i == 1 and len(a) == 1 else None,
                        )
                        for a in read
                    ]
            if step.kind == "message":
                msg = m.messages[ref]
                d = chained[ref]
                own_rate = msg.kind == "periodic" and i and (ref in scheduled or not sent_by_producer(m, msg, prev))
                wait = _read_wait(not own_rate, message_period(msg), refresh, heads, ppm) if i else 0
                tx = 0 if own_rate else queue_delay(m, msg, prev)
                if prev is not None and rates.shared(msg) and any(r in sending_tasks(m, msg) for r in prev.refs):
                    # its data leaves with the next send, by whichever sender
                    gap = rates.renewal(msg)
                    wait = _add(wait, None if gap is None else clocks.longest_real(gap, ppm))
                outs.append((base + tx + d.best_ns, _add(_add(_add(hi, wait), tx), d.worst_ns)))
                periods.append(rates.renewal(msg))
            else:
                task = m.task(ref)
                period = task_period(m, task)
                # a message starts it rx_delay after its frame; free-running, or the flow's first (whose start is
                # the stamp), at once
                after = start_delay(m, task) if task.on_message is not None and i else 0
                starter = _outside_starter(m, task, prev)
                if starter is not None:  # it samples (and renews) the flow's data as often as that message comes
                    period = rates.start_spacing(starter)
                event = task.on_message is not None and starter is None  # started by the data itself
                if i and not event and not last:
                    period = rates.sending_runs(task, flow.steps[i + 1], period)
                spread = start_spread(m, task, chained) if starter is None and not event else 0
                wait = _read_wait(event, period, refresh, heads, ppm, spread) if i else 0
                if event and not heads and _may_start_first(rates, task, inputs, item_lo, item_hi, after):
                    # it takes the other items' freshest data as its message starts it: this stamp's may come
                    # later, and then it takes the one before, each stamp reaching them within their latest
                    wait = None if wait is None or not refresh else max(wait, clocks.longest_real(refresh, ppm))
                start_hi = _add(_add(hi, wait), after)
                # at the earliest, its message's frame and rx_delay; the other items it reads need only be in by then
                start_lo = max(base, item_lo[task.on_message] + after) if event else base  # type: ignore[index]
                lossy = bool(i) and not heads and len(inputs) > 1 and any(rates.drops(x) for x in inputs)
                if lossy:
                    # it takes the oldest of its items' freshest data, and one of them may have sent nothing of
                    # this stamp's: that one's next may be a whole renewal later
                    wait = None if wait is None or not refresh else max(wait, clocks.longest_real(refresh, ppm))
                    start_hi = _add(_add(hi, wait), after)
                first = releases[flow.steps[0].refs[0]] if len(flow.steps[0].refs) == 1 else None
                if i and not heads and first is not None and period == task.period_ns and _clocked(task):
                    # on the first task's clock it starts a fixed distance after each of that task's starts (but a
                    # stamp one item dropped reaches it only with that item's next: no earlier latest then)
                    on_grid = _clock_distances(first, task, start_lo, hi, ppm)
                    if on_grid is not None:
                        start_lo = max(start_lo, on_grid[0])
                        if not lossy:
                            start_hi = on_grid[1] if start_hi is None else min(start_hi, on_grid[1])
                end_hi = _add(start_hi, task_response(task, task_ns))
                outs.append((start_lo, start_hi) if last else (start_lo + task.bcet_ns, end_hi))
                periods.append(period if starter is not None else period or 0)
        item_lo = {ref: o[0] for ref, o in zip(step.refs, outs)}
        item_hi = {ref: o[1] for ref, o in zip(step.refs, outs)}
        lo = max(o[0] for o in outs)
        hi = None if any(o[1] is None for o in outs) else max(o[1] for o in outs)  # type: ignore[type-var]
        if step.kind == "message":
            delivery = (lo, hi)
        # an event-driven task passes its input's rate on (one started from outside the flow, its message's);
        # a stamp renews no faster than its slowest step so far; once one renews at no known rate, neither does it
        unknown = unknown or None in periods
        refresh = None if unknown else max(max(p or 0 for p in periods), refresh or 0) or None
        if i:
            streams = carried
        prev = step
    return (lo, hi), delivery


def _clocked(task: model.Task) -> bool:
    """A task that runs on its node's own clock, at its period."""
    return task.period_ns is not None and task.trigger is None and task.on_message is None and task.sync_bus is None


def _clock_distances(
    first: _Release, task: model.Task, lo: int, hi: int | None, ppm: int
) -> tuple[int, int] | None:
    """The earliest and latest start of a task that reads data in between lo and hi after the flow's first task
    started, when both run on one node's clock: its starts lie a fixed distance after each of the first task's
    (their offsets and periods), within +-ppm in real time; the data is read at its first start after it is in.
    None when they are not on one clock, hi is unbounded, or their common period holds too many of the first
    task's starts to examine."""
    period = task.period_ns
    if first.grid != ("clock", task.node) or not first.period or period is None or hi is None:
        return None
    common = lcm(first.period, period) // first.period
    if common > _MAX_PHASES:
        return None

    def at_or_after(phase: int, x: int) -> int:
        return phase + max(0, -(-(x - phase) // period)) * period

    earliest, latest = [], []
    for k in range(common):
        phase = (task.offset_ns - first.offset - k * first.period) % period
        d = at_or_after(phase, clocks.shortest_real(lo, ppm))
        while clocks.longest_real(d, ppm) < lo:  # the first start that may find the data in
            d += period
        earliest.append(clocks.shortest_real(d, ppm))
        d = at_or_after(phase, hi)
        while clocks.shortest_real(d, ppm) <= hi:  # the first start that surely finds it in
            d += period
        latest.append(clocks.longest_real(d, ppm))
    return min(earliest), max(latest)


def _may_start_first(
    rates: Rates,
    task: model.Task,
    inputs: tuple[str, ...],
    item_lo: dict[str, int],
    item_hi: dict[str, int | None],
    after: int,
) -> bool:
    """A task its message starts, which also reads other items of the step before, may start before one of
    those has this stamp's data: that one's latest comes after the message's earliest (and rx_delay), unless it
    is surely queued ahead of the message."""
    on = task.on_message
    assert on is not None
    start = item_lo[on] + after
    for x in inputs:
        latest = item_hi[x]
        if x != on and (latest is None or latest > start) and not rates.queued_ahead(x, on):
            return True
    return False


def _outside_starter(m: model.Model, task: model.Task, prev: model.FlowStep | None) -> model.Message | None:
    """The message that starts a task when it is not an item of the step before (the flow's first task, or one
    that reads the flow's data whenever another message comes); None otherwise."""
    if task.on_message is None or (prev is not None and task.on_message in prev.refs):
        return None
    return m.messages[task.on_message]


def _read_wait(
    event: bool,
    own: int | None,
    refresh: int | None,
    heads: list[tuple[int | None, int | None]],
    ppm: int,
    spread: int | None = 0,
) -> int | None:
    """How long data waits for a reader that samples every `own`, its starts `spread` about their instants (None:
    unbounded), or at once on an `event`. A join (`heads`: per stream it reads, the longest wait for the other
    streams' data at least as new, and how often that stream is renewed, None: no faster than `refresh`) takes the
    oldest of its streams' data, so it also waits for the rest; but it never takes a stream's data older than one
    renewal, whatever it waits for."""
    if not heads:
        if not event and own is None and not refresh:  # neither it nor its input at a known rate
            return None
        if not event and spread is None:  # it samples at instants no bound holds: only the input's renewal does
            return clocks.longest_real(refresh, ppm) if refresh else None
        return 0 if event else sampling(own, refresh, ppm, spread or 0)
    waits = []
    for rest, renewal in heads:
        cap = renewal if renewal is not None else clocks.longest_real(refresh, ppm) if refresh else None
        wait = (
            None if event or not own or rest is None or spread is None
            else rest + clocks.longest_real(own, ppm) + spread
        )
        waits.append(cap if wait is None else wait if cap is None else min(wait, cap))
    return _latest(waits)


def _latest(spans: list[int | None]) -> int | None:
    """The longest of some spans; None (unbounded) if one is."""
    return None if None in spans else max(x for x in spans if x is not None)


@dataclass(frozen=True)
class _Release:
    """When a first-step item releases its data (starts a stamp): on a grid of `period` shared by the items of the
    same `grid` (one node's clock, or the FTT-CAN master's ECs), within [offset + early, offset + late] of each
    period; `renewal`: the longest real time from any instant to its next release."""

    grid: tuple[str, str] | None
    period: int
    offset: int
    early: int
    late: int
    renewal: int | None  # None: no rate bounds it


def _release(rates: Rates, kind: str, ref: str, ftt: FttTimes | None, ppm: int) -> _Release:
    m, task_ns = rates.m, rates.task_ns
    if ftt is not None:  # the master's ECs: a synchronous message is queued at its window, a task at its TM
        s = ftt.schedule
        entry = ref if kind == "message" else m.task(ref).trigger
        if entry is not None and entry in ftt.entries and (kind == "task" or ref in ftt.frame_ns):
            period, init = ftt.entries[entry]
            if kind == "message":
                ecs = range(s.macro_cycle)
                early = min(s.window_start(k) for k in ecs)
                late = max(s.window_start(k) + s.window_delay(k) for k in ecs)
            else:
                nominal = s.tm_ns + start_delay(m, m.task(ref))  # at the TM's end: shorter stuffed, or resent
                early, late = nominal - s.tm_early_ns, nominal + s.tm_delay_ns
            return _Release(("ftt", ""), period * s.ec_ns, init * s.ec_ns, early, late, period * s.ec_ns + late - early)
    if kind == "message":
        msg = m.messages[ref]
        every = rates.renewal(msg)
        senders = sending_tasks(m, msg)
        variation = max(((task_response(m.task(t), task_ns) or 0) - m.task(t).bcet_ns for t in senders), default=0)
        renewal = None if every is None else clocks.longest_real(every, ppm) + msg.jitter_ns + variation
        clocked = (
            msg.kind == "periodic" and not senders and msg.slowest_ns is None and m.buses[msg.bus].is_can
            and msg.period_ns == msg.interval_ns
        )
        grid = ("clock", msg.producer) if clocked else None
        return _Release(grid, msg.interval_ns or 0, msg.offset_ns or 0, 0, msg.jitter_ns, renewal)
    task = m.task(ref)
    starter = _outside_starter(m, task, None)
    every = task_period(m, task) if starter is None else rates.start_spacing(starter)
    clocked = task.period_ns is not None and task.trigger is None and task.on_message is None and task.sync_bus is None
    grid = ("clock", task.node) if clocked else None
    renewal = None if every is None else clocks.longest_real(every, ppm)
    return _Release(grid, every or 0, task.offset_ns, 0, 0, renewal)


def _gap(a: tuple[str, ...], b: tuple[str, ...], releases: dict[str, _Release], ppm: int) -> int | None:
    """The longest real time from a release of stream a to the next release of stream b: b's data that is at least
    as new as a's. Two first-step items on one grid keep their offsets' distances (over their common period);
    otherwise b may have just been released, and comes again after its renewal (a joined stream, after its
    slowest item's)."""
    if len(a) == 1 and len(b) == 1:
        ra, rb = releases[a[0]], releases[b[0]]
        if ra.grid is not None and ra.grid == rb.grid and ra.period and rb.period:
            common = lcm(ra.period, rb.period) // ra.period
            if common <= _MAX_PHASES:
                tol = ppm if ra.grid[0] == "clock" else 0  # a node's clock: its distances within +-ppm in real time
                gap = 0
                for k in range(common):  # each release of a in the common period
                    distance = (rb.offset - ra.offset - k * ra.period) % rb.period
                    if clocks.shortest_real(distance, tol) + rb.early < ra.late:  # a late may pass b's release
                        distance += rb.period
                    gap = max(gap, clocks.longest_real(distance, tol) + rb.late - ra.early)
                return gap
    return _latest([releases[r].renewal for r in b])
