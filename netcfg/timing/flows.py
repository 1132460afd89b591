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
"""

from __future__ import annotations

from bisect import bisect_left
from dataclasses import dataclass, field
from math import lcm
from typing import TYPE_CHECKING

from netcfg import model
from netcfg.timing import clocks
from netcfg.timing.flow_inputs import step_inputs
from netcfg.timing.frames import arbitration_key

if TYPE_CHECKING:  # only in annotations: a spec without FTT-CAN or CANopen loads neither analysis
    from netcfg.timing.canopen_sync import MasterLoop
    from netcfg.timing.ftt import Schedule


@dataclass(frozen=True)
class Delivery:
    """From the moment a message is queued to its reception: (best, worst); worst None when unbounded."""

    best_ns: int
    worst_ns: int | None


@dataclass(frozen=True)
class FttTimes:
    schedule: Schedule
    frame_ns: dict[str, tuple[int, int]]  # message -> (nominal, worst) frame time
    entries: dict[str, tuple[int, int]]  # synchronous message or trigger -> (period, init) in ECs


@dataclass(frozen=True)
class FlowLatency:
    name: str
    unsync: tuple[int, int | None]
    sync: tuple[int, int] | None
    delivery_unsync: tuple[int, int | None] | None  # to the last message's reception
    delivery_sync: tuple[int, int] | None


def _add(a: int | None, b: int | None) -> int | None:
    return None if a is None or b is None else a + b


TaskTimes = dict[str, int | None]  # node.task -> worst-case response time on its processor (None: unbounded)


def task_response(task: model.Task, task_ns: TaskTimes | None) -> int | None:
    """From a task's activation to its end: its response time on its processor (its WCET when not analysed)."""
    if task_ns is None or task.ref not in task_ns:
        return task.wcet_ns
    return task_ns[task.ref]


def task_period(m: model.Model, task: model.Task) -> int | None:
    """How long a free-running task may take to come round again: the slowest admissible activation period."""
    if task.on_message is not None:
        return 0
    if task.trigger is not None:
        trigger = m.triggers[task.trigger]
        return trigger.slowest_ns or trigger.period_ns
    return task.period_ns


def start_delay(m: model.Model, task: model.Task) -> int:
    """How long after the frame that starts it a task starts: its node's rx_delay after a CAN frame (its trigger
    message, a SYNC, its message), as netcfg.sim starts it; an Ethernet delivery already includes it (Tpost)."""
    if task.on_message is not None:
        return m.nodes[task.node].rx_delay_ns if m.buses[m.messages[task.on_message].bus].is_can else 0
    return m.nodes[task.node].rx_delay_ns if task.trigger is not None or task.sync_bus is not None else 0


def message_period(msg: model.Message) -> int | None:
    """How long a periodic message may take to be sent again: the slowest period of a period_range, else its period
    (a sporadic message: its minimum inter-arrival time, all that is known)."""
    return msg.slowest_ns or msg.period_ns or msg.interval_ns


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
                own_rate = msg.kind == "periodic" and i and (ref in scheduled or not _sent_by_producer(m, msg, prev))
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
                wait = _read_wait(event, period, refresh, heads, ppm) if i else 0
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


@dataclass(frozen=True)
class Runs:
    """How a task's starts (or a message's deliveries) follow one another: n of them apart, between
    n * fastest - spread and n * slowest + spread (nominal spacings, the spread in real time)."""

    fastest: int
    slowest: int
    spread: int


@dataclass(frozen=True)
class Rates:
    """How often a model's tasks start and its messages are renewed, from each message's delivery and each task's
    response; `scheduled`: the messages an FTT-CAN schedule sends in their windows (their senders' ends do not
    move them, and `chained` holds their windows' delivery)."""

    m: model.Model
    chained: dict[str, Delivery]
    task_ns: TaskTimes | None = None
    scheduled: frozenset[str] = frozenset()

    def activations(self, task: model.Task, seen: frozenset[str] = frozenset()) -> Runs | None:
        """A task's starts: on its own clock or trigger at its period, or at its message's deliveries; None when
        no rate bounds them."""
        if task.on_message is not None:
            return self.arrivals(self.m.messages[task.on_message], seen)
        slowest = task_period(self.m, task)
        if not slowest:
            return None
        fastest = self.m.triggers[task.trigger].interval_ns if task.trigger is not None else slowest
        return Runs(fastest, slowest, 0)

    def arrivals(self, msg: model.Message, seen: frozenset[str] = frozenset()) -> Runs | None:
        """A message's deliveries: its releases, moved by its release jitter (the spec's and its senders'
        response variation, unless a schedule sends it) and by its delivery's variation."""
        every, d = self.renewal(msg, seen), self.chained.get(msg.name)
        variation = 0 if msg.name in self.scheduled else self.send_variation(msg)
        if every is None or not msg.interval_ns or d is None or d.worst_ns is None or variation is None:
            return None
        jitter = 0 if msg.name in self.scheduled else msg.jitter_ns
        return Runs(msg.interval_ns, every, jitter + variation + d.worst_ns - d.best_ns)

    def start_spacing(self, msg: model.Message) -> int | None:
        """How far apart the starts of a task this message starts may be; None when no rate bounds them."""
        runs = self.arrivals(msg)
        return None if runs is None else runs.slowest + runs.spread

    def send_variation(self, msg: model.Message) -> int | None:
        """How much later than its fastest a task that sends the message as it ends may end: its response less
        its BCET (the slowest sender's); None when one's response is unbounded."""
        out = 0
        for ref in sending_tasks(self.m, msg):
            task = self.m.task(ref)
            busy = task_response(task, self.task_ns)
            if busy is None:
                return None
            out = max(out, busy - task.bcet_ns)
        return out

    def renewal(self, msg: model.Message, seen: frozenset[str] = frozenset()) -> int | None:
        """The longest nominal time between two of a message's releases; None when no rate bounds it. A sporadic
        message that tasks send as they end goes at most once per minimum inter-arrival time, so a run may send
        nothing and the next release comes with the next run that does (send_spacing; the senders' response
        variation and the spec's jitter come on top, as for any task-sent message); one sent on its own is taken
        at its minimum inter-arrival time (all that is known, as netcfg.sim releases it)."""
        if msg.kind != "sporadic":
            return message_period(msg)
        senders = sending_tasks(self.m, msg)
        if not senders:
            return msg.interval_ns
        if len(senders) == 1:
            return self.send_spacing(msg, self.m.task(senders[0]), seen)
        # several: after any send, each sender's first run to end the minimum inter-arrival time later sends
        # (unless another did in between); it starts up to one of its spacings (and spread) after that time less
        # its BCET, and ends up to its response later (the senders' starts are not one sequence: counted whole)
        if msg.name in seen or msg.interval_ns is None:
            return None
        gaps = []
        for ref in senders:
            task = self.m.task(ref)
            runs, busy = self.activations(task, seen | {msg.name}), task_response(task, self.task_ns)
            if runs is not None and busy is not None:
                gaps.append(msg.interval_ns + runs.slowest + runs.spread + busy - task.bcet_ns)
        return min(gaps, default=None)

    def send_spacing(self, msg: model.Message, sender: model.Task, seen: frozenset[str] = frozenset()) -> int | None:
        """The longest nominal time between the starts of two runs of `sender` in a row that send `msg` as they
        end. A sporadic message goes at most once per minimum inter-arrival time I: a run that ends sooner than I
        after the last send sends nothing (netcfg.sim skips it), and the data it read waits for the next run that
        does. After a send by run a, run a + n starts no sooner than n * fastest - spread after a's start and ends
        no sooner than its BCET after that, while run a ended up to its response R after its start: run a + n
        surely sends once n * fastest - spread + BCET >= R + I. A task started by a message has no period of its
        own: its runs follow that message's deliveries. With several senders another's sends may hold this one's
        off for ever: None, as when no rate bounds the runs."""
        if msg.name in seen:  # a loop of messages starting the tasks that send each other: no rate is known
            return None
        runs = self.activations(sender, seen | {msg.name})
        if runs is None:
            return None
        if msg.kind == "sporadic" and msg.interval_ns and len(sending_tasks(self.m, msg)) > 1:
            return None
        n = self._runs_to_send(msg, sender, runs)
        return None if n is None else n * runs.slowest + runs.spread

    def shared(self, msg: model.Message) -> bool:
        """Several tasks send a sporadic message: a run's data may leave with another's send (the message carries
        the freshest output of the step before), or wait for one when another sent too recently."""
        return msg.kind == "sporadic" and bool(msg.interval_ns) and len(sending_tasks(self.m, msg)) > 1

    def skips_sends(self, msg: model.Message, sender: model.Task) -> bool:
        """Some run of `sender` may send nothing of the sporadic message it sends as it ends (send_spacing)."""
        if msg.kind != "sporadic" or not msg.interval_ns:
            return False
        runs = self.activations(sender)
        return runs is None or len(sending_tasks(self.m, msg)) > 1 or self._runs_to_send(msg, sender, runs) != 1

    def _runs_to_send(self, msg: model.Message, sender: model.Task, runs: Runs) -> int | None:
        """How many runs after one that sends a sporadic message the sender surely sends it again (1: every
        run); None when that is not bounded (its response unbounded, or its runs not spaced at all)."""
        if msg.kind != "sporadic" or not msg.interval_ns:
            return 1
        busy = task_response(sender, self.task_ns)
        fastest = clocks.shortest_real(runs.fastest, clock_tolerance(self.m))
        if busy is None or fastest <= 0:
            return None
        need = msg.interval_ns + busy - sender.bcet_ns + runs.spread
        return max(1, -(-need // fastest))

    def drops(self, name: str) -> bool:
        """A message some of whose data never goes out: a sporadic one a run of its sender may skip."""
        msg = self.m.messages.get(name)
        return msg is not None and any(self.skips_sends(msg, self.m.task(t)) for t in sending_tasks(self.m, msg))

    def queued_ahead(self, first: str, then: str) -> bool:
        """A message is delivered before another whenever both carry the same data: the same tasks queue both on
        one CAN bus as they end, every run (no send skipped), in a transmit queue by priority, and it wins
        arbitration (resent after an error, it still goes first)."""
        a, b = self.m.messages[first], self.m.messages[then]
        senders = sending_tasks(self.m, a)
        if not senders or senders != sending_tasks(self.m, b) or a.bus != b.bus or not self.m.buses[a.bus].is_can:
            return False
        if {first, then} & self.scheduled or self.m.nodes[a.producer].tx_queue.fifo:
            return False
        if any(self.skips_sends(msg, self.m.task(t)) for msg in (a, b) for t in senders):
            return False
        return arbitration_key(a.id, a.extended) < arbitration_key(b.id, b.extended)

    def sending_runs(self, task: model.Task, nxt: model.FlowStep, period: int | None) -> int | None:
        """How often a task that reads data it did not start with takes it on to the next step: every `period`,
        but a sporadic message it sends leaves only with the runs that send it (send_spacing), and the data a
        run that sent nothing read waits for the next that does (None: no rate bounds them)."""
        if nxt.kind != "message":
            return period
        for name in nxt.refs:
            msg = self.m.messages[name]
            if msg.kind == "sporadic" and task.ref in sending_tasks(self.m, msg) and not self.shared(msg):
                gap = self.send_spacing(msg, task)
                period = None if gap is None or period is None else max(period, gap)
        return period


def _read_wait(
    event: bool, own: int | None, refresh: int | None, heads: list[tuple[int | None, int | None]], ppm: int
) -> int | None:
    """How long data waits for a reader that samples every `own`, or at once on an `event`. A join (`heads`: per
    stream it reads, the longest wait for the other streams' data at least as new, and how often that stream is
    renewed, None: no faster than `refresh`) takes the oldest of its streams' data, so it also waits for the rest;
    but it never takes a stream's data older than one renewal, whatever it waits for."""
    if not heads:
        if not event and own is None and not refresh:  # neither it nor its input at a known rate
            return None
        return 0 if event else _sampling(own, refresh, ppm)
    waits = []
    for rest, renewal in heads:
        cap = renewal if renewal is not None else clocks.longest_real(refresh, ppm) if refresh else None
        wait = None if event or not own or rest is None else rest + clocks.longest_real(own, ppm)
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
                early = s.tm_ns + start_delay(m, m.task(ref))
                late = early + s.tm_delay_ns
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


MAX_FLOW_CYCLES = 2_000  # SYNC cycles of a CANopen flow's pattern walked one by one (twice: runs wrap around)
_MAX_PHASES = 10_000  # releases of one item in two items' common period that are examined one by one


def clock_tolerance(m: model.Model) -> int:
    """The clock tolerance a flow's waits count: flows cross nodes and buses, so the largest any CAN bus states
    (the default where there is none)."""
    return max((b.clock_tolerance_ppm for b in m.buses.values() if b.is_can), default=clocks.DEFAULT_TOLERANCE_PPM)


def _sampling(consumer_period: int | None, refresh: int | None, ppm: int) -> int:
    """Worst sampling delay of a free-running consumer: up to one of its periods, and never more than the
    input's renewal period (a slower consumer always reads data renewed within that period: its age counts).
    Both periods run on a node's own clock, so in real time they may be `ppm` longer."""
    candidates = [p for p in (consumer_period, refresh) if p]
    if not candidates:
        return 0
    wait = min(candidates)
    return clocks.longest_real(wait, ppm)


def _sent_by_producer(m: model.Model, msg: model.Message, prev: model.FlowStep | None) -> bool:
    """True when the task before the message in the flow sends it as it finishes (same rate)."""
    if prev is None or prev.kind != "task":
        return False
    return any(m.task(ref).node == msg.producer and same_rate(m, m.task(ref), msg) for ref in prev.refs)


def queue_delay(m: model.Model, msg: model.Message, prev: model.FlowStep | None) -> int:
    """How long after the task before it a CAN message it sends as it ends is queued: its producer's tx_delay, as
    netcfg.sim queues it (on Ethernet the path delay already holds it, as Tpre)."""
    if prev is None or prev.kind != "task" or not m.buses[msg.bus].is_can:
        return 0
    senders = sending_tasks(m, msg)
    return m.nodes[msg.producer].tx_delay_ns if any(ref in senders for ref in prev.refs) else 0


def same_rate(m: model.Model, task: model.Task, msg: model.Message) -> bool:
    """A task runs at a message's rate: its period is the message's nominal, fastest or slowest one. A task that
    a message starts runs at that message's rate (as often as it comes)."""
    if task.on_message is not None:
        starter = m.messages[task.on_message]
        rates = {starter.period_ns, starter.interval_ns, message_period(starter)} - {None}
    else:
        rates = {task_period(m, task)}
    return bool(rates & {msg.period_ns, msg.interval_ns, message_period(msg)})


def sending_tasks(m: model.Model, msg: model.Message) -> tuple[str, ...]:
    """The tasks (node.task) that send a message as they finish, for the simulator and masters (runtime.json's
    sent_by), as netcfg.resolve.flows decides them."""
    return m.sent_by.get(msg.name, ())


def synchronised(
    m: model.Model, flow: model.Flow, ftt: FttTimes, chained: dict[str, Delivery], task_ns: TaskTimes | None = None
) -> tuple[tuple[int, int], tuple[int, int] | None] | None:
    """Latency range over every start instance in the macro-cycle; None when some step is not time-triggered."""
    s = ftt.schedule
    ec = s.ec_ns

    def sync_msg(ref: str) -> bool:
        return ref in ftt.entries and ref in ftt.frame_ns

    def send_time(ref: str, k: int) -> int:
        return k * ec + s.window_start(k)

    def due(ref: str, k: int) -> bool:
        period, init = ftt.entries[ref]
        return (k - init) % period == 0

    def next_send(ref: str, t: int) -> int:
        k = t // ec - 1
        while not (due(ref, k) and send_time(ref, k) >= t):
            k += 1
        return k

    def frame_end(ref: str, k: int) -> tuple[int, int]:
        """A synchronous message's frame in EC k: its earliest end, and its latest (resends within the window)."""
        best, worst = s.completion(ref, k, ftt.frame_ns)
        return k * ec + best, k * ec + worst + s.slots[k % s.macro_cycle].allowance_ns

    def first_use(on: str, prev: dict[str, tuple[int, int]], after: int, path: int) -> int:
        """The start of a task that `on`, one of several synchronous items of the step before, starts (`after` its
        frame), with every item's data of this path in (prev: item -> its EC and frame end on this path): at the
        first frame of `on` from its own that comes after each other item's, in a later EC, later in the window
        or later in time. The best path (0) takes the first that may (at its earliest end), the worst path (1) the
        first that must (at its latest)."""
        k = prev[on][0]
        while True:
            if due(on, k):
                early, late = (end + after for end in frame_end(on, k))
                msgs = s.slots[k % s.macro_cycle].messages
                if all(
                    (ko == k and other in msgs and msgs.index(other) < msgs.index(on))
                    or ko < k
                    or end <= (late if path == 0 else early)
                    for other, (ko, end) in prev.items()
                    if other != on
                ):
                    return early if path == 0 else late
            k += 1

    def next_activation(task: model.Task, t: int) -> int:
        """Its first start at or after t: its trigger message's end in a due EC, plus its node's rx_delay."""
        period, init = ftt.entries[task.trigger]  # type: ignore[index]
        after = s.tm_ns + start_delay(m, task)
        k = -(-(t - after) // ec)
        while (k - init) % period:
            k += 1
        return k * ec + after

    ppm = clock_tolerance(m)
    rates = Rates(m, chained, task_ns, frozenset(ftt.entries))

    def free_wait(i: int, ref: str) -> int:
        """An asynchronous message its producer's task in the step before does not send as it ends goes out at
        its own rate: the data may wait up to one of its periods for the next frame."""
        msg = m.messages[ref]
        return 0 if not i or _sent_by_producer(m, msg, flow.steps[i - 1]) else _sampling(message_period(msg), None, ppm)

    first = flow.steps[0]
    for step in flow.steps:
        for ref in step.refs:
            if step.kind == "task":
                task = m.task(ref)
                if (task.trigger is None and task.on_message is None) or task_response(task, task_ns) is None:
                    return None
            elif ref not in chained:
                return None

    def starts_of(head: str) -> list[int]:
        """Every activation / transmission of one item of the first step, over two macro-cycles (the second only
        to see which start's data the next use actually takes)."""
        starts = []
        for k in range(2 * s.macro_cycle):
            if first.kind == "task":
                task = m.task(head)
                if task.trigger is not None and due(task.trigger, k):
                    starts.append(k * ec + s.tm_ns + start_delay(m, task))
            elif sync_msg(head) and due(head, k):
                starts.append(send_time(head, k))
        return starts

    def from_head(head: str, starts: list[int]) -> tuple[tuple[int, int], tuple[int, int] | None] | None:
        """The latency range counted from the starts of one item of the first step; the step's other items are
        taken at their next instance from then on."""
        runs = []
        hold = 0  # how much later a start must be to supersede this one (0: the next start)
        for start in starts:
            lo = hi = start
            got: tuple[int, int] | None = None
            uses: Uses | None = None
            prev_inst: dict[str, tuple[int, int]] = {}  # the step before's synchronous items: their ECs, both paths
            prev_out: dict[str, tuple[int, int]] = {}  # ... and their frames' ends, on both paths
            for i, step in enumerate(flow.steps):
                last = i == len(flow.steps) - 1
                outs = []
                inst: dict[str, tuple[int, int]] = {}
                for ref in step.refs:
                    if step.kind == "message" and sync_msg(ref):
                        k_lo, k_hi = next_send(ref, lo), next_send(ref, hi)
                        inst[ref] = (k_lo, k_hi)
                        outs.append((frame_end(ref, k_lo)[0], frame_end(ref, k_hi)[1]))
                    elif step.kind == "message":
                        d = chained[ref]
                        if d.worst_ns is None:
                            return None
                        wait = free_wait(i, ref)
                        tx = 0 if wait else queue_delay(m, m.messages[ref], flow.steps[i - 1] if i else None)
                        outs.append((lo + tx + d.best_ns, hi + wait + tx + d.worst_ns))
                        if i and not wait and may_skip(flow.steps[i - 1], m.messages[ref]):
                            # a later start's data reaches the message surely only once it is sent again
                            hold = max(hold, (m.messages[ref].interval_ns or 0) + hi - lo)
                    else:
                        task = m.task(ref)
                        if task.trigger is not None:
                            a_lo, a_hi = next_activation(task, lo), next_activation(task, hi)
                        elif task.on_message in prev_inst and len(prev_inst) > 1:
                            # started by one of several synchronous items: by that message's first frame once
                            # the others' data of this path is in
                            on, after = task.on_message, start_delay(m, task)
                            a_lo, a_hi = (
                                first_use(on, {r: (ks[p], prev_out[r][p]) for r, ks in prev_inst.items()}, after, p)
                                for p in (0, 1)
                            )
                        else:  # started by a message
                            a_lo, a_hi = lo + start_delay(m, task), hi + start_delay(m, task)
                        if task.trigger is not None:  # its trigger message may end late, sent again after errors
                            a_hi += s.tm_delay_ns
                        busy = task_response(task, task_ns) or 0  # bounded: checked above
                        outs.append((a_lo, a_hi) if last else (a_lo + task.bcet_ns, a_hi + busy))
                lo, hi = max(o[0] for o in outs), max(o[1] for o in outs)
                if last and len(step.refs) == 1 and m.task(step.refs[0]).trigger is not None:
                    uses = last_uses(m.task(step.refs[0]), lo, hi)
                prev_inst = inst if len(inst) == len(step.refs) else {}
                prev_out = dict(zip(step.refs, outs)) if prev_inst else {}
                if step.kind == "message":
                    got = (lo, hi)
                if i == 0 and superseded(head, start, starts, lo):
                    break  # its next instance is there, however late, before the others' at their earliest
            else:
                runs.append((start, lo, hi, got, uses))
        return _freshest(runs, s.macro_cycle * ec, hold)  # None if no start's data is ever used

    def last_uses(task: model.Task, lo: int, hi: int) -> Uses:
        """The activations of the flow's last task, triggered, that this start's data may reach between its fastest
        path (lo) and its slowest (hi), each as (earliest, latest) start: at its trigger message's end, up to
        tm_delay late (resent after errors). A mix of fast and slow steps may reach any of them, each at its latest."""
        out, at = [], lo
        while at <= hi - s.tm_delay_ns:
            out.append((at, at + s.tm_delay_ns))
            at = next_activation(task, at + 1)
        return tuple(out)

    def may_skip(prev: model.FlowStep, msg: model.Message) -> bool:
        """A sporadic message the task before sends as it ends, whose sends may come closer than its minimum
        inter-arrival time: netcfg.sim then skips one, and the data waits for the next (send_spacing)."""
        if prev.kind != "task":
            return False
        senders = [m.task(r) for r in prev.refs if r in sending_tasks(m, msg)]
        return any(rates.skips_sends(msg, t) for t in senders)

    def superseded(head: str, start: int, starts: list[int], ready: int) -> bool:
        """Of a first step with several items: the head's next instance (at its slowest) comes before the step's
        other items have an instance at least as new (at their fastest), so this one is never the oldest used."""
        if len(first.refs) == 1:
            return False
        later = [t for t in starts if t > start]
        if not later:
            return False
        nxt = later[0]
        if first.kind == "message":
            return frame_end(head, next_send(head, nxt))[1] < ready
        task = m.task(head)
        return nxt + s.tm_delay_ns + (task_response(task, task_ns) or 0) < ready

    # a step of several items passes on the oldest of their data: the flow's age counts from whichever item's
    # instance is the oldest one used, so every item of the first step is a start in turn (an item none of whose
    # starts is ever the oldest used adds nothing)
    heads = {head: starts_of(head) for head in first.refs}
    if not all(heads.values()):
        return None
    done = [r for r in (from_head(head, starts) for head, starts in heads.items()) if r is not None]
    if not done:
        return None
    lat_lo, lat_hi = min(r[0][0] for r in done), max(r[0][1] for r in done)
    got = [r[1] for r in done if r[1] is not None]
    got_range = (min(g[0] for g in got), max(g[1] for g in got)) if got else None
    # the first step's start may come late: a triggered task's with its trigger message, resent after bit errors,
    # and a synchronous message's too when that TM ends after its window's start (queued at the TM's end)
    late = s.tm_delay_ns if first.kind == "task" else max(s.window_delay(k) for k in range(s.macro_cycle))
    if not late:
        return (lat_lo, lat_hi), got_range

    def anchored(until: int) -> bool:
        """A step after the start, up to `until`, keeps to its own time (a synchronous message, a triggered task, a
        message sent at its own rate): the data it passes on comes no later, so the flow may be that much
        shorter. Steps that only follow their predecessor (chained messages, message-activated tasks) move with
        the start; but with several items in the first step, the others keep to their own time: a task started by
        one of them takes the late one's data at that one's frame."""
        return len(first.refs) > 1 or any(
            (step.kind == "message" and (sync_msg(ref) or free_wait(i, ref)))
            or (step.kind == "task" and m.task(ref).trigger is not None)
            for i, step in enumerate(flow.steps[: until + 1])
            if i
            for ref in step.refs
        )

    if anchored(len(flow.steps) - 1):
        lat_lo = max(0, lat_lo - late)  # an age is never negative, however late the start
    if got_range is not None:
        delivered = max(i for i, step in enumerate(flow.steps) if step.kind == "message")
        if anchored(delivered):
            got_range = (max(0, got_range[0] - late), got_range[1])
    return (lat_lo, lat_hi), got_range


Uses = tuple[tuple[int, int], ...]  # activations of a flow's triggered last task: (earliest start, latest start)
# start, end (best), end (worst), last message's delivery, the last task's activations it may reach (None: the task
# follows its input, each activation its own)
Run = tuple[int, int, int, tuple[int, int] | None, Uses | None]


def _freshest(
    runs: list[Run], cycle_end: int, hold: int = 0
) -> tuple[tuple[int, int], tuple[int, int] | None] | None:
    """Data age: a use takes the freshest data, so of several starts that reach the same use only the last counts:
    the last of those at least `hold` apart (a later start's data may not be passed on before then).
    `runs` cover two cycles; only the starts of the first are measured (the second shows which start is last).
    Where the last task is triggered (its activations known), a start's data is used by every activation it may
    reach before the one the next start surely reaches (at its slowest), each at its latest: a fast start followed
    by a slow one (or by a late trigger message), and a mix of fast and slow steps, included. Otherwise, and for
    the delivery range, a start's fastest execution is used when the next start, also fast, reaches a later use
    (likewise the slowest); each execution that is used counts for both ends of the range: a fast start whose slow
    twin is superseded is still used, and may carry the flow's oldest data. (There, executions between the
    fastest and the slowest are not examined separately.)"""
    lat_lo: int | None = None
    lat_hi = 0
    del_lo: int | None = None
    del_hi = 0
    starts = [run[0] for run in runs]
    for k, (start, lo, hi, got, uses) in enumerate(runs):
        if start >= cycle_end:
            break
        j = bisect_left(starts, start + hold, k + 1)
        if j == len(runs) and not hold:
            break
        nxt = runs[j] if j < len(runs) else None  # None: no start surely supersedes it
        used = [
            (end, delivered)
            for end, later, delivered in (
                (lo, nxt[1] if nxt else None, got[0] if got else None),
                (hi, nxt[2] if nxt else None, got[1] if got else None),
            )
            if later is None or later > end
        ]
        ends = [end for end, _ in used]
        if uses is not None:  # (then every run's are: they share the last task)
            sure = nxt[4][-1][0] if nxt is not None and nxt[4] else None  # the next start's data is in by then
            open_uses = [u for u in uses if sure is None or u[0] < sure]
            ends = [open_uses[0][0], open_uses[-1][1]] if open_uses else []
        for end in ends:
            lat_lo = end - start if lat_lo is None else min(lat_lo, end - start)
            lat_hi = max(lat_hi, end - start)
        for _, delivered in used:
            if delivered is not None:
                del_lo = delivered - start if del_lo is None else min(del_lo, delivered - start)
                del_hi = max(del_hi, delivered - start)
    if lat_lo is None:
        return None
    return (lat_lo, lat_hi), (None if del_lo is None else (del_lo, del_hi))


@dataclass(frozen=True)
class SyncTimes:
    """A CANopen bus's SYNC cycle as flows need it (from the SYNC-cycle analysis and the response times)."""

    period_ns: int
    sync: Delivery  # SYNC queued -> received (nominal frame, worst-case response)
    every: dict[str, int]  # synchronous TPDO -> every how many SYNCs
    frame_ns: dict[str, int]  # message -> nominal frame time
    completion_ns: list[int | None]  # per cycle of the SYNC-cycle analysis: the last synchronous TPDO's end
    master: MasterLoop | None = None  # the SYNC producer's cycle; None: an ideal master (no jitter, no SYNC task)
    release_delay_ns: dict[str, int] = field(default_factory=dict)  # message -> its producer's queueing delay
    # messages the SYNC producer queues in the FIFO transmit queue SYNC goes through: one written before a SYNC
    # is queued leaves the queue before that SYNC does, so its consumers have it by that SYNC's reception
    ahead_of_sync: frozenset[str] = frozenset()
    # RxPDOs the SYNC producer's loop writes only every n-th cycle (a period of n SYNC periods)
    every_nth_write: frozenset[str] = frozenset()


def synchronised_canopen(
    m: model.Model,
    flow: model.Flow,
    bus: str,
    st: SyncTimes,
    chained: dict[str, Delivery],
    task_ns: TaskTimes | None = None,
) -> tuple[tuple[int, int], tuple[int, int] | None] | None:
    """SYNC-driven CANopen (seed 000): SYNC tasks run a fixed offset after each SYNC, synchronous TPDOs sample at
    SYNC and are done by the cycle's completion; other messages go out when their producer has the data.
    Cycle k's SYNC is queued within the master's jitter of k * period, so drives receive it between the SYNC frame's
    best and worst delivery after that; the master's own SYNC tasks start within its jitter of k * period + offset
    (MasterLoop: its loop keeps that instant, it does not wait for its SYNC's reception). None when some step is
    neither SYNC-driven nor chained."""
    period = st.period_ns
    jitter = st.master.jitter_ns if st.master is not None else 0
    master = st.master.node if st.master is not None else None
    s_best = st.sync.best_ns
    s_worst = None if st.sync.worst_ns is None else st.sync.worst_ns + jitter
    if s_worst is None:
        return None

    def activation(task: model.Task) -> tuple[int, int]:
        """Earliest and latest start of a SYNC task after k * period."""
        if task.node == master:
            return task.offset_ns, task.offset_ns + jitter
        after = start_delay(m, task) + task.offset_ns  # after the SYNC's reception
        return s_best + after, s_worst + after

    def on_sync(due: int, window: tuple[int, int], r: int, worst_path: bool) -> tuple[int, int]:
        """First SYNC instant (plus offset) that can take data ready at r: (cycle, its time on this path)."""
        k = max(0, r // period - 1)
        while True:
            if k % due == 0:
                earliest, latest = k * period + window[0], k * period + window[1]
                # the worst path counts data as taken only if ready before the earliest possible instant
                if (earliest if worst_path else latest) >= r:
                    return k, (latest if worst_path else max(r, earliest))
            k += 1

    # the flow's own TPDOs fix its pattern of cycles, and the bus's completions repeat every len(completion) SYNCs;
    # a pattern too long to walk takes every cycle at the worst completion (only latest ends grow: still a bound)
    own = [st.every[ref] for step in flow.steps if step.kind == "message" for ref in step.refs if ref in st.every]
    hyper = lcm(*own) if own else 1
    if hyper > MAX_FLOW_CYCLES:
        return None  # not walked: the flow keeps its unsynchronised bound
    completion = list(st.completion_ns)
    whole = len(completion) == (lcm(*st.every.values()) if st.every else 1)  # not cut short by the SYNC analysis
    if whole and lcm(hyper, len(completion)) <= MAX_FLOW_CYCLES:
        hyper = lcm(hyper, len(completion))
    else:
        completion = [None if None in completion else max(c for c in completion if c is not None)]

    def cycle_end(k: int) -> int:
        """The latest end of cycle k's synchronous TPDOs: the analysis counts from the SYNC's queueing, which is up
        to the master's jitter late."""
        done = completion[k % len(completion)]
        return k * period + jitter + (done if done is not None else period)

    def tpdo_end(name: str, r: int, worst_path: bool) -> int:
        """The end of the first TPDO that carries data ready at r. Its drive samples at the SYNC's reception or
        as it queues the TPDO, its tx_delay later (either may be the device's): the best path takes data ready up to
        the latest of those instants, and no TPDO goes out before the earliest queueing."""
        delay = st.release_delay_ns.get(name, 0)
        k, t = on_sync(st.every[name], (s_best, s_worst + delay), r, worst_path)
        if not worst_path:
            return max(t, k * period + s_best + delay) + st.frame_ns[name]
        return cycle_end(k)

    for step in flow.steps:
        for ref in step.refs:
            if step.kind == "task":
                task = m.task(ref)
                if (task.sync_bus != bus and task.on_message is None) or task_response(task, task_ns) is None:
                    return None
            elif ref in st.every_nth_write or (  # written every n-th cycle only: the free-running bound covers it
                ref not in st.every and (chained.get(ref) is None or chained[ref].worst_ns is None)
            ):
                return None
    first = flow.steps[0]
    head = first.refs[0]
    starts = []
    # a start instant may come this much later than the one taken (the data's age is measured from it in a run)
    spread = 0
    def before_next_sync(ref: str, r: int) -> int | None:
        """The cycle whose SYNC is certain to follow a message queued at r through the SYNC producer's FIFO."""
        return r // period + 1 if ref in st.ahead_of_sync else None

    sampled: list[int] = []  # a flow that starts at a synchronous TPDO: the cycle whose sample each start takes
    for k in range(2 * hyper):
        if first.kind == "task" and m.task(head).sync_bus == bus:
            early, late = activation(m.task(head))
            starts.append(k * period + early)
            spread = late - early
        elif first.kind == "message" and head in st.every and k % st.every[head] == 0:
            # sampled at the SYNC's reception, or as the TPDO is queued its tx_delay later (tpdo_end)
            starts.append(k * period + s_best)
            sampled.append(k)
            spread = s_worst - s_best + st.release_delay_ns.get(head, 0)
    if not starts:
        return None
    runs: list[Run] = []
    for n, start in enumerate(starts):
        # the worst case from the earliest start, the best case from the latest
        lo, hi = start + spread, start
        got: tuple[int, int] | None = None
        by_sync: int | None = None  # the previous step's data is at its consumers by this cycle's SYNC
        for i, step in enumerate(flow.steps):
            last = i == len(flow.steps) - 1
            outs = []
            ahead = [before_next_sync(ref, hi) for ref in step.refs] if step.kind == "message" else []
            for ref, k_sync in zip(step.refs, ahead):
                # the start's sample goes out in its own cycle's TPDO, queued at or after the start
                if i == 0 and sampled and ref in st.every and sampled[n] % st.every[ref] == 0:
                    outs.append((lo + st.frame_ns[ref], cycle_end(sampled[n])))
                    continue
                if ref in st.every:
                    outs.append((tpdo_end(ref, lo, False), tpdo_end(ref, hi, True)))
                    continue
                d = chained[ref]
                end = hi + (d.worst_ns or 0)
                if k_sync is not None:  # sent before SYNC k, which ends by k * period + s_worst
                    end = min(end, k_sync * period + s_worst)
                outs.append((lo + d.best_ns, end))
            if step.kind == "task":
                for ref in step.refs:
                    task = m.task(ref)
                    if task.sync_bus == bus:
                        a_lo = on_sync(1, activation(task), lo, False)[1]
                        a_hi = on_sync(1, activation(task), hi, True)[1]
                        if by_sync is not None:
                            a_hi = min(a_hi, by_sync * period + activation(task)[1])
                    else:  # started by a message
                        a_lo, a_hi = lo + start_delay(m, task), hi + start_delay(m, task)
                    busy = task_response(task, task_ns) or 0  # bounded: checked above
                    outs.append((a_lo, a_hi) if last else (a_lo + task.bcet_ns, a_hi + busy))
            lo, hi = max(o[0] for o in outs), max(o[1] for o in outs)
            by_sync = None
            if step.kind == "message":
                got = (lo, hi)
                if ahead and all(k is not None for k in ahead):
                    by_sync = max(k for k in ahead if k is not None)
        # runs hold ends relative to the start taken: the best case's, which began `spread` later, is moved back
        runs.append((start, lo - spread, hi, None if got is None else (got[0] - spread, got[1]), None))
    return _freshest(runs, hyper * period)
