"""Worst-case response times on a CAN bus where some nodes queue their frames in FIFO order.

The analysis is Davis, Kollmann, Pollex and Slomka (2011), "Controller Area Network (CAN) schedulability analysis
with FIFO queues", ECRTS, section 4 (University of York report YCS-2011-462), implemented from its equations. A node
x with a FIFO transmit queue offers the bus only the frame at the head of its queue, so a high-priority frame waits
behind every lower-priority frame queued before it (priority inversion). With M(x) the messages of x's FIFO, L(x)
the lowest-priority of them, C_MIN(x) the shortest transmission time among them, and every other node's frames k
(priority-queued or in another FIFO):

  blocking         B_x = max over k not in M(x) with lower priority than L(x) of C_k
  queuing delay    w_x = B_x + sum over k in M(x) of C_k - C_MIN(x)
                         + sum over k not in M(x) in hp(L(x)) of ceil((w_x + J_k + tau) / T_k) * C_k
  response time    R_x = w_x + C_MIN(x),   R_m = J_m + R_x for every m in M(x)

Every frame of the FIFO can be ahead of m (one instance each), and while any of them heads the queue it loses
arbitration only to frames above L(x); m, the last, starts within w and cannot be interrupted once it does. The
bound of m is B + sum C + interference(w_m + tau) with w_m largest for the smallest C_m, so C_MIN bounds every
member: the whole FIFO shares one queuing bound R_x (each member adds its own queuing jitter J_m).
The paper's assumption, checked here: at most one instance of each FIFO message is queued at a time, i.e.
R_m <= T_m for every member; a FIFO that breaks it has no bound here (`limit == "fifo"`; Davis and Navet 2012 treat
that case, which is left out).

Interference from a FIFO frame on other frames: it reaches arbitration (the head of its queue) anywhere between
its release and R_k - C_k after it, so other frames see it with the queuing jitter J'_k = R_k - C_k (the paper's
treatment of FIFO messages as priority-queued ones with increased jitter). FIFO bounds depend on one another
through these jitters: they are iterated from J' = J until nothing grows (each round can only raise them).
Priority-queued frames are then analysed as before (Davis et al. 2007; can_rta, or can_offsets with release
offsets) with the FIFO frames' J'. Integer nanoseconds throughout; the same MAX_ITERATIONS per fixed point and the
same conventions for unbounded results as can_rta. Clocks as can_rta counts them (netcfg.timing.clocks): another
node's releases in a window of x real ns are those of longest_local(x) ns of its clock, and a member's next
instance may come shortest_real(T) after the last. Bit errors (netcfg.timing.can_errors), when the bus allows for
them, add E(t) over the window up to the end of the frame, each costing an error frame and the resending of the
longest frame on the bus (any frame may be the one hit): R = B + sum of C + interference + E(R), iterated as
w = R - C_MIN; their long-run rate joins the load test.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

from netcfg.timing.can_errors import ErrorModel
from netcfg.timing.can_rta import MAX_ITERATIONS, ONE_SHOT, CanFrame, Limit, Response
from netcfg.timing.clocks import PPM, longest_local, shortest_real
from netcfg.timing.load import compare_to_capacity

MAX_ROUNDS = 100  # rounds of the jitter iteration between FIFO queues


@dataclass(frozen=True)
class FifoQueue:
    """One node's FIFO as the analysis bounds it; the terms --explain shows."""

    node: str
    members: tuple[str, ...]  # in priority order
    lowest: str  # L(x): its interference comes from every other frame above this one
    blocking_ns: int  # B_x
    queued_ns: int  # sum of C over the FIFO: every frame that can be ahead, and the frame itself
    c_min_ns: int
    interference_ns: int | None  # the other nodes' frames that win arbitration meanwhile
    queue_ns: int | None  # R_x: queued to sent, for every member
    limit: Limit | None = None
    error_ns: int = 0  # E(w + C_MIN): the bus's bit-error term in w (0 without an error model)


@dataclass(frozen=True)
class FifoAnalysis:
    responses: dict[str, Response]  # every frame on the bus
    queues: dict[str, FifoQueue]  # by node
    effective_jitter_ns: dict[str, int]  # J'_k of every FIFO frame: how other frames see it


def analyse(
    frames: Sequence[CanFrame],
    tau_ns: int,
    fifo_of: Mapping[str, str],
    priority: Callable[[Sequence[CanFrame]], dict[str, Response]],
    tolerance_ppm: int = 0,
    errors: ErrorModel | None = None,
) -> FifoAnalysis:
    """Response time of every frame on one bus. `fifo_of` maps each message sent through a FIFO queue to its node;
    `priority` analyses priority-queued frames (can_rta.analyse or can_offsets.analyse with the bus's offsets);
    senders' clocks are within +-tolerance_ppm of nominal."""
    groups: dict[str, list[CanFrame]] = {}
    for f in frames:
        if f.name in fifo_of:
            groups.setdefault(fifo_of[f.name], []).append(f)
    if not groups:
        return FifoAnalysis(priority(frames), {}, {})
    jitter = {f.name: f.j_ns for f in frames}
    queues: dict[str, FifoQueue] = {}
    for _ in range(MAX_ROUNDS):
        queues = {
            node: _queue(node, members, frames, jitter, tau_ns, tolerance_ppm, errors)
            for node, members in sorted(groups.items())
        }
        grown = dict(jitter)
        for q in queues.values():
            for f in groups[q.node]:
                if q.queue_ns is not None:
                    grown[f.name] = max(f.j_ns, f.j_ns + q.queue_ns - f.c_ns)
        if grown == jitter:
            break
        jitter = grown
    else:
        queues = {node: replace(q, queue_ns=None, limit="iterations") for node, q in queues.items()}
    effective = [replace(f, j_ns=jitter[f.name]) for f in frames]
    out = priority(effective)
    # a FIFO without a bound reaches arbitration at no bounded time: every frame below its highest-priority member
    # can meet it any number of times
    top = {node: min(f.priority_key for f in members) for node, members in groups.items()}
    bottom = {node: max(f.priority_key for f in members) for node, members in groups.items()}
    # ... and so is another FIFO whose lowest-priority message is below that member, and so on
    spreading = True
    while spreading:
        spreading = False
        for node, q in sorted(queues.items()):
            hit = [
                u.limit
                for other, u in sorted(queues.items())
                if other != node and u.queue_ns is None and top[other] < bottom[node]
            ]
            if q.queue_ns is not None and hit:
                queues[node] = replace(q, queue_ns=None, limit=hit[0])
                spreading = True
    unbounded = [(top[node], q.limit) for node, q in sorted(queues.items()) if q.queue_ns is None]
    for f in frames:
        q_node = fifo_of.get(f.name)
        if q_node is not None:
            q = queues[q_node]
            r = None if q.queue_ns is None else f.j_ns + q.queue_ns
            out[f.name] = Response(f.name, r, q.blocking_ns, None, 1, 0, q.limit, error_ns=q.error_ns)
            continue
        for highest, limit in unbounded:
            if f.priority_key > highest and out[f.name].wcrt_ns is not None:
                # the figures of the discarded bound go with it
                out[f.name] = replace(
                    out[f.name],
                    wcrt_ns=None,
                    limit=limit,
                    busy_period_ns=None,
                    instances=0,
                    worst_instance=0,
                    error_ns=0,
                )
    return FifoAnalysis(out, queues, {name: jitter[name] for name in fifo_of if name in jitter})


def _queue(
    node: str,
    members: list[CanFrame],
    frames: Sequence[CanFrame],
    jitter: Mapping[str, int],
    tau_ns: int,
    ppm: int,
    errors: ErrorModel | None = None,
) -> FifoQueue:
    names = {f.name for f in members}
    ordered = sorted(members, key=lambda f: f.priority_key)
    lowest = ordered[-1]
    others = [f for f in frames if f.name not in names]
    hp = [f for f in others if f.priority_key < lowest.priority_key]
    blocking = max((f.c_ns for f in others if f.priority_key > lowest.priority_key), default=0)
    queued = sum(f.c_ns for f in members)
    c_min = min(f.c_ns for f in members)
    base = blocking + queued - c_min
    q = FifoQueue(node, tuple(f.name for f in ordered), lowest.name, blocking, queued, c_min, None, None)
    periodic = [(f.c_ns * PPM, f.t_ns * (PPM - ppm)) for f in hp if f.t_ns]  # at the fastest clocks
    longest = max(f.c_ns for f in frames)
    if errors is not None:  # one error frame and one resent frame per T_err in the long run
        periodic.append(((errors.error_frame_ns + longest) * PPM, errors.interval_ns * PPM))
    if compare_to_capacity(sum(c / t for c, t in periodic), iter(periodic)) >= 0:
        return replace(q, limit="load")
    w = base + sum(f.c_ns for f in hp)
    for _ in range(MAX_ITERATIONS):
        nxt = base + sum(
            -(-longest_local(w + jitter[f.name] + tau_ns, ppm) // (f.t_ns or ONE_SHOT)) * f.c_ns for f in hp
        )
        if errors is not None:
            nxt += errors.overhead(w + c_min, longest)
        if nxt == w:
            break
        w = nxt
    else:
        return replace(q, limit="iterations")
    r = w + c_min
    lost = errors.overhead(w + c_min, longest) if errors is not None else 0
    q = replace(q, interference_ns=w - base - lost, queue_ns=r, error_ns=lost)
    # the paper's premise: one instance of each member at most in the queue, each sent within its period
    if any(f.t_ns is not None and f.j_ns + r > shortest_real(f.t_ns, ppm) for f in members):
        return replace(q, queue_ns=None, limit="fifo")
    return q
