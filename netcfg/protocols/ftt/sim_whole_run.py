"""An FTT-CAN bus's whole run at once (netcfg.sim.whole_run does the same for switched Ethernet); the scenario runs
it through Ftt.sim_whole_run.

Event by event, every elementary cycle costs a dozen Python events: the EC start, the trigger message (TM), the
tasks it triggers, the synchronous window and each of its frames. On a bus whose windows keep their traffic
apart, none of that depends on the run, so it is a handful of array computations per slot of the macro-cycle:

* the TM goes at each EC start (the bus is idle then: the last EC's synchronous window is over, and the TM's
  identifier beats every asynchronous one) and is received a TM frame time later;
* the triggered tasks start at that reception plus their node's rx_delay, for an execution time drawn from their
  own generator (the same numbers the event path draws);
* the EC's synchronous frames are queued at the window's start (the TM being over by then) and go back to back
  in identifier order; a message-activated task starts at its frame's reception plus rx_delay;
* what tasks send (asynchronous messages: the master sends the synchronous ones) is known from their ends
  (+ tx_delay; a sporadic message's minimum gap skips sends as the event path does), and joins the
  asynchronous frames, which still run through the bus's arbitration loop (netcfg.sim.can_bus), alone: the gate
  keeps each inside its window, and here also out of the TM's time, which is what the TM did to them;
* the tasks those frames start follow from their deliveries, and each flow's samples from all those streams
  (netcfg.sim.flows.measure_flows).

What this covers (plan()): one FTT-CAN bus run as FTT-CAN, no faults, no exact stuffing (its payloads are random
draws shared with the asynchronous frames), no FIFO transmit queues, a TM that outranks every asynchronous frame,
messages sent by one task each, no task started by an asynchronous frame that sends
(the frames would then depend on each other), and a schedule whose windows hold what they carry (each EC's TM
before its synchronous window, that window over by the next EC, and with the synchronous window first, over
before the asynchronous one opens). Everything else runs event by event, and so does a covered run that meets a
tie only the order of two events at one instant decides (flows.Undecided). For the same seed both paths give
identical results (tests/test_sim_whole_run.py).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from netcfg.sim.flows import AFTER, AFTER_OWN, BEFORE, BEFORE_OWN, EMPTY, Stream, measure_flows, streams_measure
from netcfg.sim.whole_run import WholeRunScenario, clock_activations, exec_times

if TYPE_CHECKING:
    from netcfg.protocols.ftt.sim import FttMaster
    from netcfg.runtime import Task
    from netcfg.sim.can_bus import CanBus, Listener


@dataclass(frozen=True)
class _Frames:
    """One synchronous message's frames over the macro-cycle, one entry per slot that carries it, counted from
    that EC's start: when the window queues it, when it starts and when it ends."""

    slots: np.ndarray
    queued: np.ndarray
    begin: np.ndarray
    end: np.ndarray


@dataclass(frozen=True)
class Plan:
    master: FttMaster
    can: CanBus
    tm_ns: int  # the TM's frame time on this bus
    sync: dict[int, _Frames]  # source -> its frames
    triggered: dict[str, tuple[Task, np.ndarray, int]]  # task -> (task, the slots whose TM starts it, rx_delay)
    on_message: dict[str, tuple[Task, str, int]]  # task -> (task, its message, rx_delay)
    sends: dict[str, list[tuple[int, int]]]  # task -> (asynchronous source, its minimum gap if sporadic, else 0)
    listened: frozenset[int]  # asynchronous sources someone listens to (a flow, a task)


def plan(sc: WholeRunScenario) -> Plan | None:
    """What the whole run needs, worked out once; None if the run is not covered."""
    from netcfg.protocols.ftt.sim import FttMaster

    opts, cfg = sc.opts, sc.cfg
    if opts.faults or opts.stuffing == "exact" or not sc.synchronised:
        return None
    if len(cfg.buses) != 1 or not streams_measure(sc.flows):
        return None
    bus = cfg.buses[0]
    master = sc.protocols.get(bus.name)
    if not isinstance(master, FttMaster) or bus.ftt is None:
        return None
    ftt, can = bus.ftt, sc.can[bus.name]
    tm = can.sources[master.tm]
    if can.fifos:
        return None
    asynchronous = {s.name: s for s in can.sources if s.index != tm.index and s.name not in master.owned}
    if any(not s.gated or s.key <= tm.key for s in asynchronous.values()):
        return None
    entries: dict[int, list[tuple[int, int, int, int]]] = {}  # source -> (slot, queued, begin, end)
    triggered: dict[str, tuple[Task, list[int], int]] = {}
    for i, slot in enumerate(ftt.schedule):
        window = ftt.window_start(i)
        queued = t = window  # the TM ends before the window opens (below): its frames are queued at its start
        for src in sorted((can.by_name[m] for m in slot.messages), key=lambda s: s.key):
            entries.setdefault(src.index, []).append((i, queued, t, t + src.dur_ns))
            t += src.dur_ns
        opens, _ = ftt.async_window(i)
        if tm.dur_ns > window or t > ftt.ec_ns or (ftt.sync_first and slot.messages and t > opens):
            return None
        for trigger in slot.triggers:
            for task in sc.tasks_on_trigger(trigger):
                known = triggered.setdefault(task.ref, (task, [], cfg.node(task.node).rx_delay_ns))
                if known[1] and known[1][-1] == i:
                    return None  # started twice by one TM
                known[1].append(i)
    # what tasks send goes into the asynchronous window, one sending task per message; a task started by an
    # asynchronous frame must send nothing (the frames it started from would then depend on what it sends)
    sends: dict[str, list[tuple[int, int]]] = {}
    senders: set[str] = set()
    for ref, names in sc.sends.items():
        for name in names:
            if name in senders:  # (what tasks send is asynchronous: the master owns the synchronous messages)
                return None
            senders.add(name)
            sends.setdefault(ref, []).append((asynchronous[name].index, cfg.message(name).min_gap_ns))
    on_message: dict[str, tuple[Task, str, int]] = {}
    for name in can.by_name:
        for task in sc.tasks_on_message(name):
            if name in asynchronous and task.ref in sends:
                return None
            on_message[task.ref] = (task, name, cfg.node(task.node).rx_delay_ns)
    listened = frozenset(s.index for s in asynchronous.values() if s.index in can.listeners)
    sync = {src: _Frames(*np.array(rows, dtype=np.int64).T) for src, rows in sorted(entries.items())}
    return Plan(
        master, can, tm.dur_ns, sync, {ref: (t, np.array(at), rx) for ref, (t, at, rx) in triggered.items()},
        on_message, sends, listened,
    )


def run(sc: WholeRunScenario, p: Plan) -> None:
    """Compute the whole run into the scenario's records, as Scenario.run() would leave them: the TM and
    synchronous frames, then the tasks that do not wait for an asynchronous frame, then the asynchronous frames
    (what those tasks send among them), then the tasks those frames start, then the flows."""
    d = sc.opts.duration_ns
    master, can = p.master, p.can
    ftt = master.ftt
    sc.sim.skip_to(0)  # the periodic tasks' first activations, queued as the scenario was built: computed below
    starts = clock_activations(master.clock.phase_ns, master.clock.drift_ppb, 0, ftt.ec_ns, d)  # the EC grid
    master.ecs = len(starts)
    tm_end = starts + p.tm_ns
    received = int(np.searchsorted(tm_end, d))  # the ECs whose TM is received in the run: their triggers and window
    cycles = -(-received // ftt.macro_cycle_ec)

    def ecs(slots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The received ECs whose slot is one of these (in order), and for each, which of them."""
        k = (np.arange(cycles, dtype=np.int64)[:, None] * ftt.macro_cycle_ec + slots).ravel()
        which = np.tile(np.arange(len(slots)), cycles)
        keep = k < received
        return k[keep], which[keep]

    # the TM and the synchronous frames, in the records after the asynchronous ones (each message's in order)
    frames: list[tuple[int, np.ndarray, np.ndarray, list[bytes | None] | None]] = []  # source, release, end, data
    tm_data: list[bytes | None] | None = None
    if can.trace:  # each TM carries its slot's schedule
        payloads = [master.tm_payload(i) for i in range(ftt.macro_cycle_ec)]
        tm_data = [payloads[i % ftt.macro_cycle_ec] for i in range(len(starts))]
    frames.append((master.tm, starts, tm_end, tm_data))
    deliveries: dict[str, Stream] = {}
    unsent: list[tuple[int, int]] = []  # (source, queued at): queued in the run, not sent in it
    for src, f in p.sync.items():
        k, which = ecs(f.slots)
        ec = starts[k]
        queued = ec + f.queued[which]
        begin = ec + f.begin[which]
        end = ec + f.end[which]
        sent = begin < d  # queued within the run (the window's event happens), and started in it
        unsent += [(src, at) for at in queued[(queued < d) & ~sent].tolist()]
        release, end = queued[sent], end[sent]
        frames.append((src, release, end, None))  # no payload outside exact stuffing, as the master submits them
        delivered = end < d
        deliveries[can.sources[src].name] = Stream(False, release[delivered], end[delivered])
    # the tasks that no asynchronous frame starts, and what they send
    activations: dict[str, tuple[Task, np.ndarray, str]] = {}  # task -> (task, its starts, its order at ties)
    for t, clock, period in sc.free_running_tasks():
        activations[t.ref] = (t, clock_activations(clock.phase_ns, clock.drift_ppb, t.offset_ns, period, d), AFTER)
    for ref, (task, slots, rx_delay) in p.triggered.items():
        at = tm_end[ecs(slots)[0]] + rx_delay
        activations[ref] = (task, at[at < d], BEFORE)  # its event was queued as the TM was received
    listened = {can.sources[src].name for src in p.listened}
    late = {ref: v for ref, v in p.on_message.items() if v[1] in listened}  # started by asynchronous frames
    activity: dict[str, Stream] = {}

    def run_tasks(which: dict[str, tuple[Task, np.ndarray, str]]) -> None:
        for ref, (task, start, ties) in which.items():
            end = start + exec_times(sc, task, len(start))
            if len(start):
                sc.task_arrays[ref] = (start, end)
            activity[ref] = Stream(True, start, end, task.on_message, ties)

    for ref, (task, name, rx_delay) in p.on_message.items():
        if ref not in late:
            activations[ref] = _started_by(task, deliveries.get(name) or Stream(False, EMPTY, EMPTY), rx_delay, d)
    run_tasks(activations)
    sent_t, sent_src = [EMPTY], [EMPTY]
    for ref, sends in p.sends.items():
        if ref in activity:
            stream = activity[ref]
            at = stream.end + sc.cfg.node(activations[ref][0].node).tx_delay_ns
            for src, gap in sends:
                mine = _spaced(at, gap) if gap else at
                sent_t.append(mine)
                sent_src.append(np.full(len(mine), src, dtype=np.int64))
    # the asynchronous frames: the bus's own loop, alone on the bus, with what the tasks send as released frames
    recorded: dict[int, tuple[list[int], list[int]]] = {src: ([], []) for src in p.listened}
    for src, (rel, ends) in recorded.items():
        can.listen_only(src, _recorder(rel, ends))
    release_t = np.concatenate(sent_t)
    if len(release_t):
        order = np.argsort(release_t, kind="stable")
        can.add_stream(_Released(release_t[order], np.concatenate(sent_src)[order]))
    # the gate, with each asynchronous window opening no earlier than the TM's end: the TM, which wins the
    # arbitration at the EC start, kept asynchronous frames off the bus until then
    can.gate = partial(master.gate, opens_after=p.tm_ns)
    can.start()
    sc.sim.run_until(d)
    for src, (rel, ends) in recorded.items():
        deliveries[can.sources[src].name] = Stream(False, np.array(rel, dtype=np.int64), np.array(ends, dtype=np.int64))
    run_tasks({ref: _started_by(task, deliveries[name], rx_delay, d) for ref, (task, name, rx_delay) in late.items()})
    # the records the event path leaves
    rec = can.record
    for src, release, end, data in frames:
        rec.msg.extend([src] * len(release))
        rec.response.extend((end - release).tolist())
        if can.trace:  # a trace's frames in any order (netcfg.sim.cli.trace_frames sorts them)
            rec.end.extend(end.tolist())
            rec.data.extend(data if data is not None else [None] * len(end))
    for src, at in unsent:
        can.queued_unsent(src, at)
    def taken(name: str) -> Stream:  # as the event path hands deliveries to flows: from when the data was taken
        got = deliveries.get(name) or Stream(False, EMPTY, EMPTY)
        lag = sc.capture_lag(sc.cfg.message(name))
        return replace(got, first=got.first - lag) if lag else got

    measure_flows(sc.flows, activity, taken)
    sc.sim.skip_to(d)


def _started_by(task: Task, delivered: Stream, rx_delay: int, d: int) -> tuple[Task, np.ndarray, str]:
    """A message-activated task's activations: each delivery of its message plus its node's rx_delay; with
    rx_delay, its start was queued at the delivery before (so it comes before one at the same instant)."""
    at = delivered.end + rx_delay
    return task, at[at < d], BEFORE_OWN if rx_delay else AFTER_OWN


def _spaced(at: np.ndarray, gap: int) -> np.ndarray:
    """The sends a sporadic message's minimum gap lets through, as Scenario.run_task decides them activation by
    activation: each at least `gap` after the last one let through."""
    kept, last = [], None
    for t in at.tolist():
        if last is None or t >= last + gap:
            kept.append(t)
            last = t
    return np.array(kept, dtype=np.int64)


class _Released:
    """Frames released at known instants, as a bus's release stream (CanBus.add_stream)."""

    chunk_free = True  # no random draws: chunking them any way gives the same releases

    def __init__(self, times: np.ndarray, sources: np.ndarray) -> None:
        self.times, self.sources = times, sources

    def __call__(self, t0: int, t1: int) -> tuple[np.ndarray, np.ndarray]:
        i, j = np.searchsorted(self.times, [t0, t1])
        return self.times[i:j], self.sources[i:j]


def _recorder(release: list[int], end: list[int]) -> Listener:
    def heard(e: int, _src: int, r: int, _data: bytes | None) -> None:
        release.append(r)
        end.append(e)

    return heard
