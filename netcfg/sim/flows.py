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
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from netcfg.runtime import Flow, RuntimeConfig

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
                if flow.steps[i].kind == "task":
                    node = ref.split(".", 1)[0]
                    mine = tuple(
                        r for r in prev.refs
                        if (prev.kind == "message" and node in cfg.message(r).consumers)
                        or (prev.kind == "task" and r.split(".", 1)[0] == node)
                    )
                else:
                    producer = cfg.message(ref).producer
                    mine = tuple(r for r in prev.refs if prev.kind == "task" and r.split(".", 1)[0] == producer)
                self.local[(i, ref)] = mine or prev.refs
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


@dataclass
class Stream:
    """One flow item's activity over a whole run, in the order the event path sees it: a task's activations
    (start, end) or a message's listened deliveries (release, end, in delivery order). `on_delivery_of`: the
    message whose delivery starts the task (it reads that delivery at once), None for a periodic task."""

    task: bool
    first: np.ndarray  # start or release
    end: np.ndarray
    on_delivery_of: str | None = None


def measure_streams(tracker: FlowTracker, streams: Mapping[str, Stream]) -> None:
    """The tracker's samples from whole streams: what task_started() and message_delivered(), called event by
    event, would record, for flows whose every step has one item that appears once (whole_run.covers checks).

    Data age as in the event path: a step's item holds (available at, stamp) records in the order they are added;
    a reader takes the last record available by its instant (a task at its start, a message at its release).
    Where that depends on which of two events at one instant comes first, or on records the event path has
    already forgotten (HISTORY), this raises Undecided."""
    steps = tracker.steps
    last = len(steps) - 1
    times = stamps = added = np.empty(0, dtype=np.int64)  # the previous step's item: records in add order
    prev_ref = ""
    for i, step in enumerate(steps):
        ref = step.refs[0]
        s = streams[ref]
        when = s.first  # the instant each call reads at
        at_event = s.first if s.task else s.end  # the instant each call happens
        if i == 0:
            stamp = s.first
        else:
            j = np.searchsorted(times, when, side="right") - 1
            every = not len(j) or int(j.min()) >= 0  # every call found a record (most runs, after the first)
            ok = j >= 0
            found = j if every else np.where(ok, j, 0)
            if s.task and len(times):  # a record available at the very instant the task starts
                tie = ok & (times[found] == when) & (added[found] == at_event)
                own = steps[i - 1].kind == "message" and (s.on_delivery_of in (None, prev_ref))
                if tie.any() and not own:
                    raise Undecided(f"flow '{tracker.name}': {ref} starts as {prev_ref} is added")
            seen = np.searchsorted(added, at_event, side="right")  # records added by then, at most
            # further back than the fewest records the event path keeps; cautious: it may start the event path
            # again where that path had in fact kept the record, never the other way round
            back = found < seen - HISTORY - 1
            if back.any() and (back & ok & (seen > 2 * HISTORY)).any():
                raise Undecided(f"flow '{tracker.name}': {ref} reads further back than the event path keeps")
            if every:
                stamp = stamps[j]
            else:  # only the calls that found a stamp go on
                stamp = stamps[j[ok]]
                s = Stream(s.task, s.first[ok], s.end[ok], s.on_delivery_of)
        if s.task:
            if i == last:
                tracker.latency.samples = _reached(tracker.latency.done, stamp, s.first)
                return
            times, stamps, added = s.end, stamp, s.first
            if len(times) > 1 and (times[1:] < times[:-1]).any():
                raise Undecided(f"flow '{tracker.name}': {ref} ends out of order")
        else:
            times, stamps, added = s.end, stamp, s.end
            if i == last:
                tracker.latency.samples = _reached(tracker.latency.done, stamp, s.end)
                return
            if i == tracker.delivery_step and tracker.delivery is not None:
                tracker.delivery.samples = _reached(tracker.delivery.done, stamp, s.end)
        prev_ref = ref


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
