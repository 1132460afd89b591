"""An FTT-CAN bus's whole run at once (netcfg.sim.whole_run does the same for switched Ethernet).

Event by event, every elementary cycle costs a dozen Python events: the EC start, the trigger message (TM), the
tasks it triggers, the synchronous window and each of its frames. On a bus whose windows keep their traffic
apart, none of that depends on the run, so it is a handful of array computations per slot of the macro-cycle:

* the TM goes at each EC start (the bus is idle then: the last EC's synchronous window is over, and the TM's
  identifier beats every asynchronous one) and is received a TM frame time later;
* the triggered tasks start at that reception plus their node's rx_delay, for an execution time drawn from their
  own generator (the same numbers the event path draws);
* the EC's synchronous frames are queued at max(window start, TM reception) and go back to back in identifier
  order; a message-activated task starts at its frame's reception plus rx_delay;
* the asynchronous frames still run through the bus's arbitration loop (netcfg.sim.can_bus), alone: the gate
  keeps each inside its window, and here also out of the TM's time, which is what the TM did to them;
* each flow's samples follow from those streams (netcfg.sim.flows.measure_streams).

What this covers (plan()): one FTT-CAN bus run as FTT-CAN, no faults, no trace, no exact stuffing (its payloads
are random draws shared with the asynchronous frames), no FIFO transmit queues, no task that sends, nobody
listening to asynchronous frames, a TM that outranks every asynchronous frame, and a schedule whose windows
hold what they carry (each EC's TM before its synchronous window, that window over by the next EC, and with the
synchronous window first, over before the asynchronous one opens). Everything else runs event by event, and so
does a covered run that meets a tie only the order of two events at one instant decides (flows.Undecided). For
the same seed both paths give identical results (tests/test_sim_whole_run.py).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from netcfg.sim.engine import NEVER
from netcfg.sim.flows import Stream, measure_streams
from netcfg.sim.whole_run import _EMPTY, _activations, _exec_times, flows_covered

if TYPE_CHECKING:
    from netcfg.runtime import Task
    from netcfg.sim.can_bus import CanBus, Gate
    from netcfg.sim.ftt import FttMaster
    from netcfg.sim.scenario import Scenario


@dataclass(frozen=True)
class _Slot:
    """One EC of the macro-cycle: its synchronous frames, (source, start, end) counted from the EC start."""

    frames: tuple[tuple[int, int, int], ...]
    release: int  # when they are queued, from the EC start


@dataclass(frozen=True)
class Plan:
    master: FttMaster
    can: CanBus
    tm_ns: int  # the TM's frame time on this bus
    slots: tuple[_Slot, ...]
    triggered: dict[str, tuple[Task, tuple[int, ...], int]]  # task -> (task, slots that start it, rx_delay)
    on_message: dict[str, tuple[Task, str, int]]  # task -> (task, its message, rx_delay)


def plan(sc: Scenario) -> Plan | None:
    """What the whole run needs, worked out once; None if the run is not covered."""
    from netcfg.sim.ftt import FttMaster

    opts, cfg = sc.opts, sc.cfg
    if opts.faults or opts.trace or opts.stuffing == "exact" or not sc.synchronised or sc.sends:
        return None
    if len(cfg.buses) != 1 or not flows_covered(sc):
        return None
    bus = cfg.buses[0]
    master = sc.protocols.get(bus.name)
    if not isinstance(master, FttMaster) or bus.ftt is None:
        return None
    ftt, can = bus.ftt, sc.can[bus.name]
    tm = can.sources[master.tm]
    if can.fifos:
        return None
    asynchronous = [s for s in can.sources if s.index != tm.index and s.name not in master.owned]
    if any(not s.gated or s.key < tm.key or s.index in can.listeners for s in asynchronous):
        return None
    slots = []
    for slot in ftt.schedule:
        window = ftt.window_start(slot.ec)
        release = max(window, tm.dur_ns)
        frames, t = [], release
        for src in sorted((can.by_name[m] for m in slot.messages), key=lambda s: s.key):
            frames.append((src.index, t, t + src.dur_ns))
            t += src.dur_ns
        opens, _ = ftt.async_window(slot.ec)
        if tm.dur_ns > window or t > ftt.ec_ns or (ftt.sync_first and frames and t > opens):
            return None
        slots.append(_Slot(tuple(frames), release))
    triggered: dict[str, tuple[Task, tuple[int, ...], int]] = {}
    for i, slot in enumerate(ftt.schedule):
        for trigger in slot.triggers:
            for task in sc.tasks_on_trigger(trigger):
                if task.ref in triggered and i in triggered[task.ref][1]:
                    return None  # started twice by one TM
                known = triggered.get(task.ref, (task, (), cfg.node(task.node).rx_delay_ns))
                triggered[task.ref] = (task, (*known[1], i), known[2])
    on_message: dict[str, tuple[Task, str, int]] = {}
    for name, tasks in sc._message_tasks.items():
        if name not in master.owned or name not in can.by_name:
            return None
        for task in tasks:
            on_message[task.ref] = (task, name, cfg.node(task.node).rx_delay_ns)
    return Plan(master, can, tm.dur_ns, tuple(slots), triggered, on_message)


def run(sc: Scenario, p: Plan) -> None:
    """Compute the whole run into the scenario's records, as Scenario.run() would leave them."""
    d = sc.opts.duration_ns
    master, can = p.master, p.can
    ftt = master.ftt
    # the asynchronous frames: the bus's own loop, with nothing else on the bus
    sc.sim.skip_to(0)  # the periodic tasks' first activations, queued as the scenario was built: computed below
    can.gate = _async_gate(master, p.tm_ns)
    can.start()
    sc.sim.run_until(d)
    starts = _activations(master.clock.phase_ns, master.clock.drift_ppb, 0, ftt.ec_ns, d)  # the EC grid
    master.ecs = len(starts)
    tm_end = starts + p.tm_ns
    slot_of = np.arange(len(starts)) % ftt.macro_cycle_ec
    heard = tm_end < d  # the TM's reception happens within the run: its EC's triggers and window follow
    can.record.msg.extend([master.tm] * len(starts))
    can.record.response.extend([p.tm_ns] * len(starts))
    sent: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}  # source -> (release, end) per slot
    for i, slot in enumerate(p.slots):
        if not slot.frames:
            continue
        ec_start = starts[heard & (slot_of == i)]
        queued = ec_start + slot.release
        ec_start = ec_start[queued < d]  # the window's event happens within the run
        for src, begin, finish in slot.frames:
            started = ec_start[ec_start + begin < d]
            sent.setdefault(src, []).append((started + slot.release, started + finish))
            for at in (ec_start[ec_start + begin >= d] + slot.release).tolist():  # queued, never sent
                can._seq += 1
                heapq.heappush(can._pending, (can.sources[src].key, at, can._seq, src, None))
    deliveries: dict[str, Stream] = {}
    for src, parts in sorted(sent.items()):
        release = np.concatenate([r for r, _ in parts])
        order = np.argsort(release, kind="stable")  # slot by slot: into time order
        release, end = release[order], np.concatenate([e for _, e in parts])[order]
        can.record.msg.extend([src] * len(release))
        can.record.response.extend((end - release).tolist())
        delivered = end < d
        deliveries[can.sources[src].name] = Stream(False, release[delivered], end[delivered])
    # the tasks
    activations: dict[str, tuple[Task, np.ndarray]] = {}
    for t, clock, period in sc.free_running_tasks():
        activations[t.ref] = (t, _activations(clock.phase_ns, clock.drift_ppb, t.offset_ns, period, d))
    for ref, (task, slots, rx_delay) in p.triggered.items():
        at = tm_end[heard & np.isin(slot_of, slots)] + rx_delay
        activations[ref] = (task, at[at < d])
    for ref, (task, name, rx_delay) in p.on_message.items():
        heard_at = deliveries.get(name, Stream(False, _EMPTY, _EMPTY)).end + rx_delay
        activations[ref] = (task, heard_at[heard_at < d])
    activity: dict[str, Stream] = {}
    for ref, (task, start) in activations.items():
        end = start + _exec_times(sc, task, len(start))
        if len(start):
            sc.task_arrays[ref] = (start, end)
        activity[ref] = Stream(True, start, end, task.on_message)
    for tr in sc.flows:
        streams = {}
        for step in tr.steps:
            for ref in step.refs:
                if step.kind == "task":
                    streams[ref] = activity.get(ref) or Stream(True, _EMPTY, _EMPTY)
                else:
                    streams[ref] = deliveries.get(ref) or Stream(False, _EMPTY, _EMPTY)
        measure_streams(tr, streams)
    sc.sim.skip_to(d)


def _async_gate(master: FttMaster, tm_ns: int) -> Gate:
    """FttMaster's gate, with each asynchronous window opening no earlier than the TM's end: the TM, which wins
    the arbitration at the EC start, kept asynchronous frames off the bus until then."""
    ftt = master.ftt

    def gate(t: int, dur: int) -> int:
        k = master.ec_of(t)
        for _ in range(2 * ftt.macro_cycle_ec + 2):
            opens, closes = ftt.async_window(k)
            start = master.ec_start(k)
            s = max(t, start + max(opens, tm_ns))
            if s + dur <= start + closes:
                return s
            k += 1
        return NEVER

    return gate
