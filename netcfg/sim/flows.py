"""End-to-end flows measured as data age, the way the analysis defines them (netcfg.timing.flows).

Every piece of data carries a stamp: the instant its flow began (the first task's activation, or the first
message's release). A task reads, at its start, the freshest data its node has for the previous step; a message
carries, at its release, the freshest output of the previous step on its producer. A step with several items in
parallel needs all of them, so it takes the oldest of their stamps. The flow's latency is measured once per
stamp, when every item of the last step has used it (a task at its activation, a message at its reception); a
stamp overwritten before it is used is not a sample, as in the analysis.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from netcfg.runtime import Flow, RuntimeConfig
from netcfg.timing.flow_inputs import step_inputs

EMPTY = np.empty(0, dtype=np.int64)  # a stream with nothing in it
HISTORY = 64  # availability records kept per item: enough to look back one message's worth of releases


@dataclass
class _Item:
    times: list[int] = field(default_factory=list)  # when each stamp became available
    stamps: list[int] = field(default_factory=list)

    def add(self, t: int, stamp: int) -> None:
        self.times.append(t)
        self.stamps.append(stamp)
        if len(self.times) > 2 * HISTORY:
            del self.times[:HISTORY], self.stamps[:HISTORY]

    def at(self, t: int) -> int | None:
        i = bisect_right(self.times, t)
        return self.stamps[i - 1] if i else None


@dataclass
class _End:
    """Stamps waiting for every item of a final step."""

    refs: frozenset[str]
    waiting: dict[int, dict[str, int]] = field(default_factory=dict)
    done: int = -1  # stamps at or below this are finished (stamps of one item only grow)
    samples: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.single = len(self.refs) == 1

    def reach(self, ref: str, stamp: int, t: int) -> None:
        if stamp <= self.done:
            return
        if self.single:  # one item (most flows): it finishes the stamp at once, nothing waits
            self.samples.append(t - stamp)
            self.done = stamp
            return
        seen = self.waiting.setdefault(stamp, {})
        seen.setdefault(ref, t)
        if len(seen) == len(self.refs):
            self.samples.append(max(seen.values()) - stamp)
            self.done = stamp
            for s in [s for s in self.waiting if s <= stamp]:
                del self.waiting[s]


class FlowTracker:
    def __init__(self, cfg: RuntimeConfig, flow: Flow, warm_up_ns: int = 0) -> None:
        self.flow = flow
        self.name = flow.name
        self.steps = flow.steps
        self.items: dict[tuple[int, str], _Item] = {}
        self.where: dict[str, list[int]] = {}  # ref -> steps it appears in
        for i, step in enumerate(flow.steps):
            for ref in step.refs:
                self.where.setdefault(ref, []).append(i)
                self.items[(i, ref)] = _Item()
        self.local: dict[tuple[int, str], tuple[str, ...]] = {}  # (step, reader) -> refs of step-1 it reads
        for i in range(1, len(flow.steps)):
            prev = flow.steps[i - 1]
            for ref in flow.steps[i].refs:
                self.local[(i, ref)] = step_inputs(
                    prev, flow.steps[i].kind, ref, lambda r: cfg.message(r).consumers, lambda r: cfg.message(r).producer
                )
        last = len(flow.steps) - 1
        self.latency = _End(frozenset(flow.steps[last].refs), done=warm_up_ns - 1)
        msg_steps = [i for i, s in enumerate(flow.steps) if s.kind == "message"]
        self.delivery_step = msg_steps[-1] if msg_steps and msg_steps[-1] != last else None
        self.delivery = (
            _End(frozenset(flow.steps[self.delivery_step].refs), done=warm_up_ns - 1)
            if self.delivery_step is not None
            else None
        )

        # per ref, each step it appears in: (step, the items of the step before it reads or None at the first step,
        # its own item, whether the step is the last, whether it is the delivery step), looked up once
        self._steps_of: dict[str, tuple[tuple[int, tuple[_Item, ...] | None, _Item, bool, bool], ...]] = {
            ref: tuple(
                (
                    i,
                    None if i == 0 else tuple(self.items[(i - 1, r)] for r in self.local[(i, ref)]),
                    self.items[(i, ref)],
                    i == last,
                    i == self.delivery_step,
                )
                for i in steps
            )
            for ref, steps in self.where.items()
        }

    def refs(self) -> Iterable[str]:
        return self.where.keys()

    def task_started(self, ref: str, start: int, end: int) -> None:
        for _, reads, item, last, _ in self._steps_of.get(ref, ()):
            stamp = start if reads is None else _oldest(reads, start)
            if stamp is None:
                continue
            if last:
                self.latency.reach(ref, stamp, start)
            else:
                item.add(end, stamp)

    def message_delivered(self, name: str, release: int, end: int) -> None:
        for _, reads, item, last, delivery in self._steps_of.get(name, ()):
            stamp = release if reads is None else _oldest(reads, release)
            if stamp is None:
                continue
            item.add(end, stamp)
            if last:
                self.latency.reach(name, stamp, end)
            if delivery and self.delivery is not None:
                self.delivery.reach(name, stamp, end)


class Undecided(Exception):
    """Computing whole streams at once (netcfg.sim.whole_run) met a case whose result the order of two events at
    one instant decides, or the event path's bounded history: the run goes event by event instead."""


# How a task's start is ordered, in the event path, against a message delivery at the very same instant:
AFTER = "after"  # after every one: a periodic task (its events come after deliveries, netcfg.sim.engine.TASKS)
AFTER_OWN = "after-own"  # after its own message's: started from inside that delivery (no rx_delay)
BEFORE_OWN = "before-own"  # before its own message's: started by an event queued at an earlier one (rx_delay)
BEFORE = "before"  # before every one: started by an event queued before any such delivery (an FTT-CAN trigger's,
# queued at the trigger message's reception)


@dataclass
class Stream:
    """One flow item's activity over a whole run, in the order the event path sees it: a task's activations
    (start, end) or a message's listened deliveries (release, end, in delivery order). `on_delivery_of`: the
    message whose delivery starts the task, None for a periodic or triggered one; `ties`: how its start is ordered
    against a delivery at the same instant (AFTER ...); a tie no order covers is Undecided."""

    task: bool
    first: np.ndarray  # start or release
    end: np.ndarray
    on_delivery_of: str | None = None
    ties: str = AFTER


def measure_streams(tracker: FlowTracker, streams: Mapping[str, Stream]) -> None:
    """The tracker's samples from whole streams: what task_started() and message_delivered(), called event by
    event, would record, for flows whose every item appears in one step only (the whole runs check).

    Data age as in the event path: a step's item holds (available at, stamp) records in the order they are added;
    a reader takes the last record available by its instant (a task at its start, a message at its release) of
    each item it reads, and the oldest of their stamps. Where that depends on which of two events at one instant
    comes first, or on records the event path has already forgotten (HISTORY), this raises Undecided."""
    steps = tracker.steps
    last = len(steps) - 1
    records: dict[str, _Records] = {}  # the previous step's items
    for i, step in enumerate(steps):
        reached: list[tuple[str, np.ndarray, Stream]] = []  # per item: its stamps and the calls that had one
        for ref in step.refs:
            s = streams[ref]
            if i == 0:
                stamp = s.first
            else:
                reads = [records[r] for r in tracker.local[(i, ref)]]
                stamp, s = _read(tracker.name, ref, s, reads, steps[i - 1].kind == "message")
            reached.append((ref, stamp, s))
        if i == last:
            _finish(tracker.latency, reached)
            return
        if i == tracker.delivery_step and tracker.delivery is not None:
            _finish(tracker.delivery, reached)
        records = {}
        for ref, stamp, s in reached:
            if s.task:
                if len(s.end) > 1 and (s.end[1:] < s.end[:-1]).any():
                    raise Undecided(f"flow '{tracker.name}': {ref} ends out of order")
                records[ref] = _Records(ref, s.end, stamp, s.first)
            else:
                records[ref] = _Records(ref, s.end, stamp, s.end)


def streams_measure(trackers: Iterable[FlowTracker]) -> bool:
    """measure_streams computes these flows: each item of a flow appears in one of its steps only."""
    for tr in trackers:
        refs = [ref for step in tr.steps for ref in step.refs]
        if len(set(refs)) != len(refs):
            return False
    return True


def measure_flows(
    trackers: Iterable[FlowTracker], tasks: Mapping[str, Stream], messages: Callable[[str], Stream]
) -> None:
    """Every tracker's samples (measure_streams) from the tasks' streams (a task not there never ran) and each
    message's deliveries."""
    for tr in trackers:
        streams = {}
        for step in tr.steps:
            for ref in step.refs:
                if step.kind == "task":
                    streams[ref] = tasks.get(ref) or Stream(True, EMPTY, EMPTY)
                else:
                    streams[ref] = messages(ref)
        measure_streams(tr, streams)


@dataclass
class _Records:
    """One item's availability records over a whole run, in the order the event path adds them."""

    ref: str
    times: np.ndarray  # available from
    stamps: np.ndarray
    added: np.ndarray  # when the event path adds each


def _read(flow: str, ref: str, s: Stream, reads: list[_Records], after_message: bool) -> tuple[np.ndarray, Stream]:
    """The stamp each call of `s` takes from the items it reads (the oldest of their freshest), and the calls
    that found one in every item (the others add no record)."""
    when = s.first  # the instant each call reads at
    at_event = s.first if s.task else s.end  # the instant each call happens
    stamp: np.ndarray | None = None
    ok = np.ones(len(when), dtype=bool)
    for rec in reads:
        if not len(rec.times):
            return EMPTY, replace(s, first=EMPTY, end=EMPTY)
        j = np.searchsorted(rec.times, when, side="right") - 1
        found = j >= 0
        jj = np.where(found, j, 0)
        if s.task:  # a record available at the very instant the task starts
            tie = found & (rec.times[jj] == when) & (rec.added[jj] == at_event)
            if tie.any():
                sees = _sees_ties(s, rec.ref) if after_message else None
                if sees is None:
                    raise Undecided(f"flow '{flow}': {ref} starts as {rec.ref} is added")
                if not sees:  # the task came first: the records before that instant (a message's are added at once)
                    j = np.where(tie, np.searchsorted(rec.times, when, side="left") - 1, j)
                    found = j >= 0
                    jj = np.where(found, j, 0)
        seen = np.searchsorted(rec.added, at_event, side="right")  # records added by then, at most
        # further back than the fewest records the event path keeps; cautious: it may start the event path
        # again where that path had in fact kept the record, never the other way round
        back = found & (jj < seen - HISTORY - 1) & (seen > 2 * HISTORY)
        if back.any():
            raise Undecided(f"flow '{flow}': {ref} reads further back than the event path keeps")
        mine = rec.stamps[jj]
        stamp = mine if stamp is None else np.minimum(stamp, mine)
        ok &= found
    assert stamp is not None
    if ok.all():
        return stamp, s
    return stamp[ok], replace(s, first=s.first[ok], end=s.end[ok])


def _sees_ties(s: Stream, message: str) -> bool | None:
    """Whether a task reads a record of `message` delivered at the very instant it starts; None where the order of
    the two events is not known here."""
    if s.ties == AFTER or (s.ties == AFTER_OWN and message == s.on_delivery_of):
        return True
    if s.ties == BEFORE or (s.ties == BEFORE_OWN and message == s.on_delivery_of):
        return False
    return None


def _finish(end: _End, reached: list[tuple[str, np.ndarray, Stream]]) -> None:
    """_End.reach for every call of a final step's items, in the order the event path makes them: a task's at
    its start, a message's at its delivery."""
    if len(reached) == 1:
        _, stamp, s = reached[0]
        end.samples = _reached(end.done, stamp, s.first if s.task else s.end)
        return
    at = np.concatenate([s.first if s.task else s.end for _, _, s in reached])
    stamp = np.concatenate([st for _, st, _ in reached])
    which = np.concatenate([np.full(len(st), k) for k, (_, st, _) in enumerate(reached)])
    order = np.argsort(at, kind="stable")
    at, stamp, which = at[order], stamp[order], which[order]
    tie = (at[1:] == at[:-1]) & (which[1:] != which[:-1]) & (stamp[1:] != stamp[:-1])
    if tie.any():  # which item reaches first at that instant decides which stamp finishes
        raise Undecided(f"two items of one step reach different stamps at {int(at[1:][tie][0])} ns")
    refs = [ref for ref, _, _ in reached]
    for k, st, t in zip(which.tolist(), stamp.tolist(), at.tolist()):
        end.reach(refs[k], st, t)


def _reached(done: int, stamp: np.ndarray, t: np.ndarray) -> list[int]:
    """_End.reach for one item over a whole stream: a stamp counts when it is newer than every earlier one."""
    newest = np.maximum.accumulate(np.concatenate([[done], stamp]))[:-1]
    counts = stamp > newest
    return (t[counts] - stamp[counts]).tolist()


def _oldest(reads: tuple[_Item, ...], t: int) -> int | None:
    """The oldest of the freshest stamps these items had at t; None if one had none yet."""
    if len(reads) == 1:  # most steps read one item: no loop
        item = reads[0]
        i = bisect_right(item.times, t)
        return item.stamps[i - 1] if i else None
    oldest = None
    for item in reads:
        i = bisect_right(item.times, t)
        if not i:
            return None
        stamp = item.stamps[i - 1]
        if oldest is None or stamp < oldest:
            oldest = stamp
    return oldest
