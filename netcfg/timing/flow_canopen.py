"""The synchronised flow model on SYNC-driven CANopen (seed 000): SYNC tasks run a fixed offset after each SYNC,
synchronous TPDOs sample at SYNC and are done by the cycle's completion, other messages go out when their producer
has the data (synchronised_canopen, over the SYNC cycles of the flow's pattern).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import lcm
from typing import TYPE_CHECKING

from netcfg import model
from netcfg.timing.flow_steps import Delivery, Run, TaskTimes, freshest, start_delay, task_response

if TYPE_CHECKING:  # only in annotations: a spec without CANopen loads no SYNC-cycle analysis
    from netcfg.timing.canopen_sync import MasterLoop

MAX_FLOW_CYCLES = 2_000  # SYNC cycles of a CANopen flow's pattern walked one by one (twice: runs wrap around)


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
    return freshest(runs, hyper * period)
