"""Flows in step with an EtherCAT cycle. The master keeps the cycle on its own clock and distributed clocks fire a
DC slave's SYNC0 on it, so a task of either that runs on it (`sync: true`) starts a fixed offset after each cycle's
start, and the cycle's frame takes each PDO of the segment within a fixed window of that start. A flow made of
such tasks, the segment's PDOs, tasks their messages start and messages their tasks send as they end is walked
cycle by cycle: each step takes the first cycle that surely (at worst) or possibly (at best) finds its data in.
Both paths start at the flow's earliest start (a later one never ends earlier), and the windows of later steps do
not move with it (the master's wake-up and its frame's send are drawn apart): the worst case is the latest end from
the earliest start, the best case the earliest end less the latest start, and never less than the steps' own best
times.

Per cycle k, which starts at k * cycle (its frames sent up to the master's jitter J later):

- a task of the master's starts between k * cycle + offset and J later (its wake-up latency, as for the frame);
- a task of a DC slave's starts at k * cycle + its SYNC0 shift + offset, within distributed clocks' precision;
- a PDO is taken and delivered as netcfg.protocols.ethercat.messages.delivery says: an RxPDO at the master's send,
  a TxPDO as the datagram passes its slave.

A flow with a free-running task, a join, or a message with a rate of its own keeps the free-running bound
(netcfg.timing.flows.unsynchronised): its phase against the cycle is not known.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from netcfg import model
from netcfg.timing.flow_steps import (
    Delivery,
    Run,
    TaskTimes,
    freshest,
    queue_delay,
    sent_by_producer,
    start_delay,
    task_response,
)

if TYPE_CHECKING:
    from netcfg.bus_analysis import Analysis, FlowBounds
    from netcfg.protocols.ethercat.messages import PdoTiming


@dataclass(frozen=True)
class CycleFlows:
    """An EtherCAT segment's cycle as flows in step with it need it (netcfg.protocols.ethercat.analysis fills it)."""

    bus: str
    cycle_ns: int
    starts: dict[str, tuple[int, int]]  # node -> when its tasks' cycle starts, earliest and latest from k * cycle
    pdos: dict[str, PdoTiming]  # message -> when the frame takes and delivers its data

    def __call__(self, m: model.Model, flow: model.Flow, acc: Analysis) -> FlowBounds | None:
        return synchronised_ethercat(m, flow, self, acc.chained, acc.task_ns)


def synchronised_ethercat(
    m: model.Model, flow: model.Flow, cf: CycleFlows, chained: dict[str, Delivery], task_ns: TaskTimes | None
) -> FlowBounds | None:
    """(latency, last message's delivery) of a flow in step with the cycle over two cycles' starts (freshest), or
    None when some step is not in step with it."""
    cycle = cf.cycle_ns
    if not _in_step(m, flow, cf, chained, task_ns):
        return None

    def instants(task: model.Task) -> tuple[int, int]:
        """The earliest and latest start of a task on the cycle, from k * cycle: its node's cycle and its offset."""
        early, late = cf.starts[task.node]
        return early + task.offset_ns, late + task.offset_ns

    def first_cycle(r: int, at: int) -> int:
        """The first cycle k whose instant k * cycle + at is at or after r: an instant may lie a cycle or more after
        its cycle's start (an offset and the jitter, a SYNC0 shift and an offset), so the cycle before the start's
        (which runs in the steady state the walk stands for) may be the one."""
        return -(-(r - at) // cycle)

    head = flow.steps[0].refs[0]
    runs: list[Run] = []
    for k0 in range(2):
        if flow.steps[0].kind == "task":
            early, late = instants(m.task(head))
            # the start in [0, cycle): a SYNC0 shift and an offset may together reach past the cycle
            start, spread = k0 * cycle + early % cycle, late - early
        else:
            first = cf.pdos[head]
            start, spread = k0 * cycle + first.take_lo, first.take_hi - first.take_lo
        # Both paths from the earliest start: every step takes the first cycle whose window holds its data, so a
        # later start never ends earlier; the later steps' windows do not move with the start (the master's wake-up
        # and its frame's send are drawn apart), so the best case is the earliest end less the latest start, and the
        # worst the latest end from the earliest start. No start gets through faster than its steps' own best
        # times, without a wait (`floor`), which holds the best case where the spread would take it lower.
        lo = hi = start
        floor = 0
        got: tuple[int, int] | None = None
        prev: model.FlowStep | None = None
        for i, step in enumerate(flow.steps):
            ref = step.refs[0]
            if step.kind == "message":
                w: PdoTiming | None = cf.pdos.get(ref)
                if w is None:  # another bus's, sent as the task before it ends
                    d, tx = chained[ref], queue_delay(m, m.messages[ref], prev)
                    assert d.worst_ns is not None  # (_in_step)
                    lo, hi = lo + tx + d.best_ns, hi + tx + d.worst_ns
                    floor += tx + d.best_ns
                elif i == 0:  # the start's own cycle's frame
                    lo, hi = lo + w.best_ns, k0 * cycle + w.worst_ns
                    floor += w.best_ns
                else:
                    k_lo, k_hi = first_cycle(lo, w.take_hi), first_cycle(hi, w.take_lo)
                    lo, hi = max(lo, k_lo * cycle + w.take_lo) + w.best_ns, k_hi * cycle + w.worst_ns
                    floor += w.best_ns
                got = (max(lo - spread, start + floor), hi)
            else:
                task = m.task(ref)
                if i == 0:
                    a_lo, a_hi = lo, hi + spread  # the flow's start itself: it may start up to `spread` late
                elif task.sync_bus == cf.bus:
                    early, late = instants(task)
                    k_lo, k_hi = first_cycle(lo, late), first_cycle(hi, early)
                    a_lo, a_hi = max(lo, k_lo * cycle + early), k_hi * cycle + late
                else:  # started by the message before it
                    a_lo, a_hi = lo + start_delay(m, task), hi + start_delay(m, task)
                    floor += start_delay(m, task)
                busy = task_response(task, task_ns)
                assert busy is not None  # (_in_step)
                last = i == len(flow.steps) - 1
                lo, hi = (a_lo, a_hi) if last else (a_lo + task.bcet_ns, a_hi + busy)
                floor += 0 if last else task.bcet_ns
            prev = step
        # runs hold ends relative to the start taken: the best case's is measured from the latest start
        runs.append((start, max(lo - spread, start + floor), hi, got, None))
    return freshest(runs, cycle)


def _in_step(
    m: model.Model, flow: model.Flow, cf: CycleFlows, chained: dict[str, Delivery], task_ns: TaskTimes | None
) -> bool:
    """Every step one item in step with the cycle: a task on it or one the message before it starts, the
    segment's PDOs, another bus's messages sent as the task before them ends; the first a task on the cycle or a
    TxPDO (inputs, whose read starts the flow)."""
    first = flow.steps[0]
    if any(len(s.refs) != 1 for s in flow.steps):
        return False
    head = first.refs[0]
    if first.kind == "task" and m.task(head).sync_bus != cf.bus:
        return False  # (a task on the cycle is checked below)
    if first.kind == "message" and (head not in cf.pdos or m.messages[head].producer == _master(m, cf)):
        return False
    prev: model.FlowStep | None = None
    for i, step in enumerate(flow.steps):
        ref = step.refs[0]
        if step.kind == "task":
            task = m.task(ref)
            on_cycle = task.sync_bus == cf.bus and task.period_ns == cf.cycle_ns and task.node in cf.starts
            started = task.on_message is not None and prev is not None and task.on_message in prev.refs
            if not (on_cycle or started) or task_response(task, task_ns) is None:
                return False
        elif ref not in cf.pdos:
            d = chained.get(ref)
            if i == 0 or d is None or d.worst_ns is None or not sent_by_producer(m, m.messages[ref], prev):
                return False
        prev = step
    return True


def _master(m: model.Model, cf: CycleFlows) -> str | None:
    seg = m.buses[cf.bus].ethercat
    return None if seg is None else seg.master
