"""The synchronised flow model on FTT-CAN: the master's schedule fixes when every synchronous message is sent and
every triggered task starts, so each step takes the first instance at or after the moment its data is ready, and
the latency range comes out of the schedule itself, over every instance of the macro-cycle (synchronised).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from netcfg import model
from netcfg.timing.flow_rates import Rates
from netcfg.timing.flow_steps import (
    Delivery,
    TaskTimes,
    Uses,
    clock_tolerance,
    freshest,
    message_period,
    queue_delay,
    sampling,
    sending_tasks,
    sent_by_producer,
    start_delay,
    task_response,
)

if TYPE_CHECKING:  # only in annotations: a spec without FTT-CAN loads no schedule
    from netcfg.timing.ftt import Schedule


@dataclass(frozen=True)
class FttTimes:
    schedule: Schedule
    frame_ns: dict[str, tuple[int, int]]  # message -> (nominal, worst) frame time
    entries: dict[str, tuple[int, int]]  # synchronous message or trigger -> (period, init) in ECs



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
        return 0 if not i or sent_by_producer(m, msg, flow.steps[i - 1]) else sampling(message_period(msg), None, ppm)

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
                            # its TM may end up to tm_early_ns before its worst-case end, so the data ready at hi
                            # may miss a TM that ended early, unless it came in a frame, which cannot end within a
                            # frame's time of the TM's end (the bus carried the TM); an early start of the flow's
                            # last task is taken at the end
                            a_lo = next_activation(task, lo)
                            a_hi = next_activation(task, hi + miss_margin(i))
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
        return freshest(runs, s.macro_cycle * ec, hold)  # None if no start's data is ever used

    def miss_margin(i: int) -> int:
        """How much sooner than at its worst a TM may end with the data of step i - 1 not yet in: its whole
        earliness after a task, which ends whenever; after frames, only what the shortest of them leaves of it;
        none for the first step, whose start is the activation itself."""
        if not i:
            return 0
        before = flow.steps[i - 1]
        if before.kind != "message":
            return s.tm_early_ns
        shortest = min(ftt.frame_ns.get(ref, (0, 0))[0] for ref in before.refs)
        return max(0, s.tm_early_ns - shortest)

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
    # ... and a triggered task's start may come early, with a TM shorter than its worst case: the first step's,
    # which makes the flow longer, and the last step's, which makes it shorter
    early = s.tm_early_ns if first.kind == "task" else 0
    if flow.steps[-1].kind == "task" and any(m.task(r).trigger is not None for r in flow.steps[-1].refs):
        lat_lo = max(0, lat_lo - s.tm_early_ns)
    if not late and not early:
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
        lat_hi += early  # nor shorter, however early
    if got_range is not None:
        delivered = max(i for i, step in enumerate(flow.steps) if step.kind == "message")
        if anchored(delivered):
            got_range = (max(0, got_range[0] - late), got_range[1] + early)
    return (lat_lo, lat_hi), got_range
