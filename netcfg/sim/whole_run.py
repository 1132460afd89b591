"""The whole run at once: a system of periodic tasks, switched Ethernet and flows, computed stream by stream.

The event path (Scenario.run) takes one Python event per task activation and per frame someone listens to; a
15 kHz control loop costs tens of thousands of them per simulated second. Where nothing feeds back, the same run
is a handful of array computations, taken in dependency order:

* a periodic task's activations are its node's clock at offset + k * period, its execution times one array
  of its own generator's draws (Simulator.random: the same numbers the event path draws one at a time);
* a message-activated task's activations are the listened deliveries of its message at its node;
* the frames a task sends go to its NIC as it ends (+ tx_delay); each link serves, once everything that feeds
  it is known, the frames of one window of the run (WINDOW_NS) by Lindley's recursion (netcfg.sim.ethernet's
  free-running links), window after window, so a long run's arrays stay small;
* each flow's samples follow from those streams (netcfg.sim.flows.measure_flows).

What this covers (covers()): Ethernet buses only, no faults, flows whose every item appears in one step, tasks that
send no sporadic message, and an order among tasks and links in which each comes after all that feeds it (no
feedback, such as a link carrying a frame sent because of an earlier frame on that link). Everything else runs
event by event; so does a covered run that meets a tie only the order of two events at one instant decides
(flows.Undecided), from the start. For the same seed both paths give identical results
(tests/test_sim_whole_run.py).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from netcfg.runtime import Message, Task
from netcfg.sim.engine import PPB, NodeClock, drift_ns
from netcfg.sim.flows import AFTER, AFTER_OWN, EMPTY, FlowTracker, Stream, Undecided, measure_flows, streams_measure
from netcfg.sim.run import SimRun

if TYPE_CHECKING:
    from netcfg.sim.ethernet import EthernetNetwork

__all__ = ["Undecided", "WholeRunScenario", "covers", "plan", "run"]


class WholeRunScenario(SimRun, Protocol):
    """What a whole run (here, and netcfg.sim.ftt_whole_run) reads of its scenario besides a driver's view, and the
    records it fills in (netcfg.sim.scenario.Scenario): the scenario calls it, so it does not import the scenario."""

    flows: list[FlowTracker]
    task_arrays: dict[str, tuple[np.ndarray, np.ndarray]]  # task -> (starts, ends) of its runs, computed whole
    eth_owner: dict[str, EthernetNetwork]  # the networks themselves: whole_run reads their links

    @property
    def synchronised(self) -> bool: ...

    def exec_draws(self, ref: str) -> np.random.Generator: ...

    def free_running_tasks(self) -> list[tuple[Task, NodeClock, int]]: ...

    def capture_lag(self, m: Message) -> int: ...

Job = tuple[str, Any]  # ("task", Task) or ("link", (its network, Link))


def covers(sc: WholeRunScenario) -> bool:
    return plan(sc) is not None


def _networks(sc: WholeRunScenario) -> list[EthernetNetwork] | None:
    from netcfg.sim.ethernet import EthernetNetwork

    nets = [d for d in sc.protocols.values() if isinstance(d, EthernetNetwork)]
    if sc.can or len(nets) != len(sc.protocols):
        return None
    return nets


def plan(sc: WholeRunScenario) -> list[Job] | None:
    """The tasks and links in an order where each comes after everything that feeds it; None if the run is not
    covered."""
    if sc.opts.faults:
        return None
    nets = _networks(sc)
    if nets is None:
        return None
    if not streams_measure(sc.flows):
        return None
    tasks: dict[str, Task] = {task.ref: task for task, _, _ in sc.free_running_tasks()}
    feeds: dict[int, list[int]] = {}  # job -> the jobs that need it first
    jobs: list[Job] = []
    ids: dict[object, int] = {}

    def job(kind: str, what: object, key: object) -> int:
        if key not in ids:
            ids[key] = len(jobs)
            jobs.append((kind, what))
        return ids[key]

    for net in nets:
        for link in net.order:
            job("link", (net, link), (id(net), link.index))
        for (_, a), kids in net.children.items():
            for kid in kids:
                feeds.setdefault(ids[(id(net), a)], []).append(ids[(id(net), kid.index)])
        for (i, consumer), (_, listening) in net.listeners.items():
            for task in listening:
                tasks[task.ref] = task
                last = next(li for (mi, li), c in net.deliver_to.items() if mi == i and c == consumer)
                feeds.setdefault(ids[(id(net), last)], []).append(job("task", task, task.ref))
    for ref, task in tasks.items():
        me = job("task", task, ref)
        for name in sc.sends.get(ref, ()):
            if sc.cfg.message(name).min_gap_ns:
                return None  # its minimum inter-arrival time skips sends one by one
            owner = sc.eth_owner.get(name)
            if owner is None:
                return None
            first = owner.first.get(owner.index[name])
            if first is not None:
                feeds.setdefault(me, []).append(ids[(id(owner), first.index)])
    # Kahn's algorithm, in the order the jobs were found (deterministic)
    needs = [0] * len(jobs)
    for fed in feeds.values():
        for k in fed:
            needs[k] += 1
    ready = [k for k in range(len(jobs)) if not needs[k]]
    order: list[Job] = []
    while ready:
        k = ready.pop(0)
        order.append(jobs[k])
        for after in feeds.get(k, ()):
            needs[after] -= 1
            if not needs[after]:
                ready.append(after)
    return order if len(order) == len(jobs) else None  # a cycle: feedback


def run(sc: WholeRunScenario, order: list[Job]) -> None:
    """Compute the whole run into the scenario's records, as Scenario.run() would leave them: a window of
    simulated time at a time (WINDOW_NS), every task and link in dependency order within it (`order`: plan(sc))."""
    nets = _networks(sc)
    assert nets is not None
    d = sc.opts.duration_ns
    periodic = {  # task -> every activation of the run
        t.ref: clock_activations(clock.phase_ns, clock.drift_ppb, t.offset_ns, period, d)
        for t, clock, period in sc.free_running_tasks()
    }
    tasks: list[Task] = [what for kind, what in order if kind == "task"]
    starts: dict[str, list[np.ndarray]] = {t.ref: [] for t in tasks}
    ends: dict[str, list[np.ndarray]] = {t.ref: [] for t in tasks}
    heard = {t.ref: _Heard() for t in tasks if t.ref not in periodic}
    for net in nets:
        net.whole_run_begin()
    for w0 in range(0, d, WINDOW_NS):
        w1 = min(w0 + WINDOW_NS, d)
        for net in nets:
            net.whole_run_release(w0, w1)
        for kind, what in order:
            if kind == "link":
                net, link = what
                net.whole_run_link(link, w1)
                continue
            task: Task = what
            if task.ref in periodic:
                every = periodic[task.ref]
                start = every[np.searchsorted(every, w0) : np.searchsorted(every, w1)]
            else:
                start = heard[task.ref].before(w1, _heard_by(nets, task))
            end = start + exec_times(sc, task, len(start))
            starts[task.ref].append(start)
            ends[task.ref].append(end)
            send = end + sc.cfg.node(task.node).tx_delay_ns
            send = send[send < d]
            for name in sc.sends.get(task.ref, ()):
                net = sc.eth_owner[name]
                net.whole_run_send(net.index[name], send)
    activity: dict[str, Stream] = {}
    for t in tasks:
        start, end = np.concatenate(starts[t.ref]), np.concatenate(ends[t.ref])
        if len(start):
            sc.task_arrays[t.ref] = (start, end)
        activity[t.ref] = Stream(True, start, end, t.on_message, AFTER if t.on_message is None else AFTER_OWN)
    measure_flows(sc.flows, activity, lambda name: _deliveries(nets, name))
    sc.sim.skip_to(d)


WINDOW_NS = 1_000_000_000  # simulated time computed at once, so a long run's arrays stay small: computed whole,
# 60 s of NTUA SAHR spent nearly as long in the kernel's page faults as computing. Any multiple of the Ethernet
# chunk (ethernet.CHUNK_NS) gives the same results (jitter is drawn a chunk at a time)


class _Heard:
    """A message-activated task's activations, window by window: the deliveries heard so far not yet used."""

    def __init__(self) -> None:
        self.used = 0  # deliveries already taken (parts of the network's list, then elements of `left`)
        self.left = EMPTY

    def before(self, t: int, parts: list[np.ndarray]) -> np.ndarray:
        """The deliveries before t not taken yet, in order (each part of the list is in order, and so is the list)."""
        new = parts[self.used :]
        self.used = len(parts)
        pool = np.concatenate([self.left, *new]) if new else self.left
        k = int(np.searchsorted(pool, t))
        self.left = pool[k:]
        return pool[:k]


def clock_activations(phase: int, drift_ppb: int, offset: int, period: int, until: int) -> np.ndarray:
    """NodeClock.to_global(offset + k * period) for k = 0, 1, ... while before `until` (Scenario._periodic_task)."""
    n = int((until - phase) / (period * (1 + drift_ppb / PPB))) + 2 if until > phase else 1
    local = offset + np.arange(n, dtype=np.int64) * period
    t = phase + local + drift_ns(local, drift_ppb)
    while len(t) and t[-1] < until:  # the estimate fell short (it never should by more than a step)
        local = offset + np.arange(len(t), 2 * len(t) + 1, dtype=np.int64) * period
        t = np.concatenate([t, phase + local + drift_ns(local, drift_ppb)])
    return t[t < until]


def exec_times(sc: WholeRunScenario, task: Task, n: int) -> np.ndarray:
    """n execution times, as Scenario.run_task draws them one activation at a time."""
    lo, hi = task.bcet_ns, task.wcet_ns
    if hi <= lo:
        return np.full(n, hi, dtype=np.int64)
    return lo + (sc.exec_draws(task.ref).random(n) * (hi - lo + 1)).astype(np.int64)


def _heard_by(nets: list[EthernetNetwork], task: Task) -> list[np.ndarray]:
    """The delivery instants, part by part, of a message-activated task's message at its node."""
    name = task.on_message
    for net in nets:
        if name in net.index and net.heard is not None:
            return [e for _, e in net.heard.get((net.index[name], task.node), [])]
    return []


def _deliveries(nets: list[EthernetNetwork], name: str) -> Stream:
    """A message's listened deliveries at every consumer, in the order they happen."""
    for net in nets:
        if name in net.index and net.heard is not None:
            i = net.index[name]
            parts = [p for (mi, _), ps in net.heard.items() if mi == i for p in ps]
            if not parts:
                break
            rel = np.concatenate([r for r, _ in parts])
            end = np.concatenate([e for _, e in parts])
            if (end[1:] < end[:-1]).any():  # several consumers' deliveries, one consumer's after another
                order = np.argsort(end, kind="stable")
                rel, end = rel[order], end[order]
            same = np.flatnonzero(end[1:] == end[:-1])
            if len(same) and (rel[same] != rel[same + 1]).any():
                raise Undecided(f"message '{name}': two consumers receive different frames at one instant")
            return Stream(False, rel, end)
    return Stream(False, EMPTY, EMPTY)
