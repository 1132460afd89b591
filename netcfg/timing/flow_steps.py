"""One step of a flow as every flow model bounds it, and data age over a schedule's runs.

Owns what the free-running and the synchronised models (netcfg.timing.flows, flow_ftt, flow_canopen) share: a
message's delivery (Delivery), a task's response, activation period and start delay, a message's period and its
queueing after the task that sends it, which tasks send a message, the clock tolerance a flow's waits count, the
sampling delay of a free-running reader, and freshest: the age of the data a schedule's uses take.
"""

from __future__ import annotations

from bisect import bisect_left
from dataclasses import dataclass

from netcfg import model
from netcfg.timing import clocks


@dataclass(frozen=True)
class Delivery:
    """From the moment a message is queued to its reception: (best, worst); worst None when unbounded."""

    best_ns: int
    worst_ns: int | None



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
    message, a SYNC, its message), as netcfg.sim starts it; an Ethernet delivery already includes it (Tpost), and an
    EtherCAT cycle task starts on its node's own cycle or SYNC0."""
    if task.on_message is not None:
        return m.nodes[task.node].rx_delay_ns if m.buses[m.messages[task.on_message].bus].is_can else 0
    on_can = task.trigger is not None or (task.sync_bus is not None and m.buses[task.sync_bus].is_can)
    return m.nodes[task.node].rx_delay_ns if on_can else 0


def message_period(msg: model.Message) -> int | None:
    """How long a periodic message may take to be sent again: the slowest period of a period_range, else its period
    (a sporadic message: its minimum inter-arrival time, all that is known)."""
    return msg.slowest_ns or msg.period_ns or msg.interval_ns


def clock_tolerance(m: model.Model) -> int:
    """The clock tolerance a flow's waits count: flows cross nodes and buses, so the largest any CAN bus states
    (the default where there is none)."""
    return max((b.clock_tolerance_ppm for b in m.buses.values() if b.is_can), default=clocks.DEFAULT_TOLERANCE_PPM)


def sampling(consumer_period: int | None, refresh: int | None, ppm: int, spread: int = 0) -> int:
    """Worst sampling delay of a free-running consumer: up to one of its periods (and the `spread` of its starts
    about their instants: two starts may be a period and that spread apart), and never more than the input's
    renewal period (a slower consumer always reads data renewed within that period: its age counts). Both
    periods run on a node's own clock, so in real time they may be `ppm` longer."""
    waits = [clocks.longest_real(p, ppm) + extra for p, extra in ((consumer_period, spread), (refresh, 0)) if p]
    return min(waits, default=0)


def start_spread(m: model.Model, task: model.Task, chained: dict[str, Delivery]) -> int | None:
    """How late after its nominal instant a task that runs at its period may start: a CANopen SYNC task of the
    SYNC producer within the master's jitter (its wake-up latency), one of a drive at the SYNC frame's reception,
    which that jitter and the frame's queueing move; one on an EtherCAT cycle within its cycle's jitter (the
    master's send jitter, a DC slave's SYNC0 precision); 0 for a task on its own clock; None when SYNC's delivery
    is unbounded."""
    bus = m.buses[task.sync_bus] if task.sync_bus is not None else None
    if bus is None:
        return 0
    co = bus.canopen
    if co is None:
        return task.cycle_jitter_ns
    if task.node == co.sync_producer:
        return co.master_jitter_ns
    sync = next((x.name for x in bus.messages if x.implicit == "SYNC"), None)
    delivery = chained.get(sync) if sync is not None else None
    if delivery is None or delivery.worst_ns is None:
        return None
    return co.master_jitter_ns + delivery.worst_ns - delivery.best_ns


def sent_by_producer(m: model.Model, msg: model.Message, prev: model.FlowStep | None) -> bool:
    """True when the task before the message in the flow sends it as it finishes (same rate; and its bus lets a
    task send it: netcfg.resolve.flows put the task in its sent_by)."""
    if prev is None or prev.kind != "task":
        return False
    senders = sending_tasks(m, msg)
    return any(
        m.task(ref).node == msg.producer and same_rate(m, m.task(ref), msg) and ref in senders for ref in prev.refs
    )


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


Uses = tuple[tuple[int, int], ...]  # activations of a flow's triggered last task: (earliest start, latest start)
# start, end (best), end (worst), last message's delivery, the last task's activations it may reach (None: the task
# follows its input, each activation its own)
Run = tuple[int, int, int, tuple[int, int] | None, Uses | None]


def freshest(
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
