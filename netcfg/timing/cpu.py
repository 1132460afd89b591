"""Processor load: the worst-case response time of every task on one node's processor.

Tasks run under fixed priorities (rate-monotonic unless the spec gives them priorities). A task's activations
are at least T apart (its period, its trigger's fastest period, or the minimum inter-arrival of the message that
starts it) and may come up to J late (an event-driven task inherits its message's arrival jitter).

* preemptive (the default): the level-i busy period of Lehoczky (1990) with release jitter (Tindell 1994),
  every instance q in it:
      L = sum over hp(i) + i of ceil((L + J_k) / T_k) C_k,   Q = ceil((L + J_i) / T_i)
      w(q) = (q + 1) C_i + sum over hp(i) of ceil((w(q) + J_k) / T_k) C_k,   R(q) = J_i + w(q) - q T_i
* non-preemptive: the same equations as CAN arbitration (Davis et al. 2007; see can_rta), one nanosecond
  as the time quantum, the longest lower-priority task as blocking.

A task activated once (no period) interferes once. Times are integer nanoseconds; the utilisation test is exact.
A node above 100 % has no bounded response for the tasks that share the overload (None).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from netcfg.timing import can_rta
from netcfg.timing.load import compare_to_capacity

Scheduling = Literal["preemptive", "non-preemptive"]


@dataclass(frozen=True)
class CpuTask:
    name: str
    c_ns: int  # worst-case execution time
    t_ns: int | None  # shortest time between two activations; None: activated once
    j_ns: int = 0  # activation jitter
    priority: int | None = None  # 0 the highest; None: rate-monotonic after the given ones


def priority_order(tasks: Sequence[CpuTask]) -> list[CpuTask]:
    """Highest priority first: given priorities, then rate-monotonic (shortest interval first), list order on ties."""
    keyed = sorted(
        enumerate(tasks),
        key=lambda it: (
            it[1].priority is None,
            it[1].priority or 0,
            it[1].t_ns if it[1].t_ns is not None else can_rta.ONE_SHOT,
            it[0],
        ),
    )
    return [t for _, t in keyed]


def utilisation(tasks: Sequence[CpuTask]) -> float:
    return sum(t.c_ns / t.t_ns for t in tasks if t.t_ns)


def overloaded(tasks: Sequence[CpuTask]) -> bool:
    """True when the periodic demand is above 100 % of the processor, decided exactly."""
    return compare_to_capacity(utilisation(tasks), [(t.c_ns, t.t_ns) for t in tasks if t.t_ns]) > 0


def analyse(tasks: Sequence[CpuTask], scheduling: Scheduling = "preemptive") -> dict[str, int | None]:
    """Worst-case response time of every task, from its activation to its end; None when unbounded."""
    ordered = priority_order(tasks)
    if scheduling == "non-preemptive":
        # CAN arbitration is fixed-priority non-preemptive scheduling: rank as identifier, 1 ns as bit time
        frames = [can_rta.CanFrame(t.name, rank, True, t.c_ns, t.t_ns, t.j_ns) for rank, t in enumerate(ordered)]
        return {name: r.wcrt_ns for name, r in can_rta.analyse(frames, 1).items()}
    out: dict[str, int | None] = {}
    for i, task in enumerate(ordered):
        out[task.name] = _preemptive(ordered[:i], task)
    return out


def _preemptive(hp: list[CpuTask], task: CpuTask) -> int | None:
    level = [*hp, task]
    if compare_to_capacity(utilisation(level), [(t.c_ns, t.t_ns) for t in level if t.t_ns]) > 0:
        return None
    steps = 0

    def demand(x: int, of: list[CpuTask]) -> int:
        return sum(t.c_ns * (-(-(x + t.j_ns) // t.t_ns) if t.t_ns else 1) for t in of)

    busy = sum(t.c_ns for t in level)
    while True:
        nxt = demand(busy, level)
        steps += 1
        if nxt == busy:
            break
        if steps > can_rta.MAX_ITERATIONS:  # exactly 100 % with jitter: no end
            return None
        busy = nxt
    instances = max(1, -(-(busy + task.j_ns) // task.t_ns)) if task.t_ns else 1
    worst, w = 0, 0
    for q in range(instances):
        w = max(w, (q + 1) * task.c_ns + sum(t.c_ns for t in hp))
        while True:
            nxt = (q + 1) * task.c_ns + demand(w, hp)
            steps += 1
            if nxt == w:
                break
            if steps > can_rta.MAX_ITERATIONS:
                return None
            w = nxt
        worst = max(worst, task.j_ns + w - q * (task.t_ns or 0))
    return worst
