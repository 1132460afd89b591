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

Offsets (this module's extension, for a node whose FIFO members are released at fixed offsets of its own clock,
as can_offsets takes them for priority queues): the members' releases repeat over the hyperperiod L of their
periods, and a frame can only be ahead of m's frame if it is in the queue when m's is queued: queued no later and
not yet sent. A release k at d ns of the node's clock before one of m's (d over the repetitions of L) is queued
within J_k of it and sent within R_k after that; m's is queued within J_m. On the node's one clock a distance of d
ns lasts between shortest_real(d) and longest_real(d), so k's frame can be in the queue then only if
shortest_real(d) < J_k + R_k (k released first) or shortest_real(L - d) <= J_m (m's release, late by its jitter,
after k's): the release windows widened by the jitter and by the queue bound overlap. Each release of m is bounded
as above with M(x) narrowed to those members (its own set's L, B, C_MIN), and m takes the largest over its
releases. The R_k the test uses are the bounds themselves: starting from R = C, sets and bounds are raised until
they agree; any such R is sound, since the first frame (in queue order) to wait longer than its R would find only
frames of its set ahead. Members without a usable offset (none, sent by a task, sporadic, or an unrolling past
can_offsets.MAX_JOBS jobs) can be queued at any time, so they are with every frame and every frame with them; a
node with fewer than two offset members gets Davis's bound unchanged. The backlog counts the frames waiting for
the bus: one leaves its slot when its transmission starts (as the simulator's queue counts it), at most R_k - C_k
after it was queued, so the same test with R_k - C_k in place of R_k gives the frames a release can find queued;
the backlog is one more than the most of them. In a queue that drops when full (`drop_depth`), a member that can
find depth frames queued can be dropped: it has no response time (`limit == "dropped"`).

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
from dataclasses import dataclass, field, replace
from math import lcm

from netcfg.timing.can_errors import ErrorModel
from netcfg.timing.can_offsets import MAX_JOBS, unrolled_jobs
from netcfg.timing.can_rta import MAX_ITERATIONS, ONE_SHOT, CanFrame, Limit, Response
from netcfg.timing.clocks import PPM, longest_local, shortest_real
from netcfg.timing.load import compare_to_capacity

MAX_ROUNDS = 100  # rounds of the jitter iteration between FIFO queues, and of a queue's own offset iteration


@dataclass(frozen=True)
class FifoBound:
    """Davis's bound for one set of frames that can be queued together; the terms --explain shows."""

    together: tuple[str, ...]  # the frames that can be in the queue at once, in priority order
    lowest: str  # L: its interference comes from every other node's frame above this one
    blocking_ns: int  # B
    queued_ns: int  # sum of C over `together`: every frame that can be ahead, and the frame itself
    c_min_ns: int
    interference_ns: int | None  # the other nodes' frames that win arbitration meanwhile
    queue_ns: int | None  # R: queued to sent
    limit: Limit | None = None
    error_ns: int = 0  # E(w + C_MIN): the bus's bit-error term in w (0 without an error model)


@dataclass(frozen=True)
class FifoQueue:
    """One node's FIFO as the analysis bounds it: the figures of its largest bound (all members' under Davis),
    and each member's own bound when offsets keep members apart."""

    node: str
    members: tuple[str, ...]  # in priority order
    lowest: str
    blocking_ns: int
    queued_ns: int
    c_min_ns: int
    interference_ns: int | None
    queue_ns: int | None  # the largest R of a member: queued to sent
    limit: Limit | None = None
    error_ns: int = 0
    together: tuple[str, ...] = ()  # the frames the largest bound counts (every member without offsets)
    bounds: Mapping[str, FifoBound] = field(default_factory=dict)  # each member's bound
    ahead: Mapping[str, int] = field(default_factory=dict)  # the most frames a member's frame can find queued
    backlog: int | None = None  # the most frames in the queue at once
    narrowed: bool = False  # the members' offsets on the node's clock keep some of them apart


@dataclass(frozen=True)
class FifoAnalysis:
    responses: dict[str, Response]  # every frame on the bus
    queues: dict[str, FifoQueue]  # by node
    effective_jitter_ns: dict[str, int]  # J'_k of every FIFO frame: how other frames see it
    dropped: dict[str, str] = field(default_factory=dict)  # message -> node: can find its dropping queue full


def analyse(
    frames: Sequence[CanFrame],
    tau_ns: int,
    fifo_of: Mapping[str, str],
    priority: Callable[[Sequence[CanFrame]], dict[str, Response]],
    tolerance_ppm: int = 0,
    errors: ErrorModel | None = None,
    offsets: Mapping[str, int] | None = None,
    drop_depth: Mapping[str, int] | None = None,
) -> FifoAnalysis:
    """Response time of every frame on one bus. `fifo_of` maps each message sent through a FIFO queue to its node;
    `priority` analyses priority-queued frames (can_rta.analyse or can_offsets.analyse with the bus's offsets);
    senders' clocks are within +-tolerance_ppm of nominal. `offsets`: the FIFO members released at a fixed offset
    of their node's clock; `drop_depth`: node -> depth of each FIFO that drops a frame queued into it when full."""
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
            node: _queue(node, members, frames, jitter, tau_ns, tolerance_ppm, errors, offsets or {})
            for node, members in sorted(groups.items())
        }
        grown = dict(jitter)
        for q in queues.values():
            if q.queue_ns is None:
                continue
            for f in groups[q.node]:
                r = q.bounds[f.name].queue_ns
                assert r is not None
                grown[f.name] = max(f.j_ns, f.j_ns + r - f.c_ns)
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
    # a frame that can find its queue full is lost then: the message has no response time (its frames that get
    # through are still sent within the queue's bound, so other frames see them as before)
    dropped = {
        name: node
        for node, q in sorted(queues.items())
        if q.queue_ns is not None and node in (drop_depth or {})
        for name in q.members
        if q.ahead[name] >= (drop_depth or {})[node]
    }
    for f in frames:
        q_node = fifo_of.get(f.name)
        if q_node is not None:
            q = queues[q_node]
            b = q.bounds.get(f.name)
            if q.queue_ns is None or b is None or b.queue_ns is None:
                out[f.name] = Response(f.name, None, q.blocking_ns, None, 1, 0, q.limit, error_ns=q.error_ns)
            elif f.name in dropped:
                out[f.name] = Response(f.name, None, b.blocking_ns, None, 1, 0, "dropped", error_ns=b.error_ns)
            else:
                out[f.name] = Response(f.name, f.j_ns + b.queue_ns, b.blocking_ns, None, 1, 0, error_ns=b.error_ns)
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
    return FifoAnalysis(out, queues, {name: jitter[name] for name in fifo_of if name in jitter}, dropped)


def _jobs(members: list[CanFrame], offsets: Mapping[str, int]) -> tuple[int, list[tuple[CanFrame, int]]] | None:
    """The releases of the members with an offset over one hyperperiod of the node's clock (member, offset in
    it); None when fewer than two members keep an offset or the unrolling is too long (Davis's bound then)."""
    kept = [(f, f.t_ns) for f in members if f.name in offsets and f.t_ns]
    if len(kept) < 2:
        return None
    if unrolled_jobs([t for _, t in kept]) > MAX_JOBS:  # the priority-queue analysis' limit, one rule
        return None
    period = lcm(*(t for _, t in kept))
    return period, [(f, (offsets[f.name] + k * t) % period) for f, t in kept for k in range(period // t)]


def _queue(
    node: str,
    members: list[CanFrame],
    frames: Sequence[CanFrame],
    jitter: Mapping[str, int],
    tau_ns: int,
    ppm: int,
    errors: ErrorModel | None,
    offsets: Mapping[str, int],
) -> FifoQueue:
    ordered = sorted(members, key=lambda f: f.priority_key)
    names = tuple(f.name for f in ordered)
    rank = {n: i for i, n in enumerate(names)}
    pattern = _jobs(ordered, offsets)
    fixed = {f.name for f, _ in pattern[1]} if pattern else set()
    free = frozenset(n for n in names if n not in fixed)  # queued at any time: with any frame, any frame with them
    known: dict[frozenset[str], FifoBound] = {}  # a set's bound depends only on the set (this round's jitters)

    def bound(together: frozenset[str]) -> FifoBound:
        if (b := known.get(together)) is None:
            b = known[together] = _bound(
                [f for f in ordered if f.name in together], names, frames, jitter, tau_ns, ppm, errors
            )
        return b

    # R of each member, from below: a member's frame is ahead of a job's in the queue only if it was queued no
    # later and not yet sent, i.e. queued less than its own R before; sets and bounds grow until they agree
    r = {f.name: f.c_ns for f in ordered}
    sets: list[tuple[str, frozenset[str]]] = []
    for _ in range(MAX_ROUNDS):
        sets = [(n, frozenset(names)) for n in sorted(free)]
        if pattern:
            sets += _together(pattern, free, r, ppm)
        worst: dict[str, FifoBound] = {}
        for n, s in sets:
            b = bound(s)
            if b.queue_ns is None:
                return _summary(node, names, b, {}, {}, None, False)
            if n not in worst or b.queue_ns > (worst[n].queue_ns or 0):
                worst[n] = b
        grown = {n: max(r[n], worst[n].queue_ns or 0) for n in names}
        # the paper's premise: one instance of each member at most in the queue, each sent within its period
        late = [f for f in ordered if f.t_ns is not None and f.j_ns + grown[f.name] > shortest_real(f.t_ns, ppm)]
        if late:
            b = max(worst.values(), key=lambda b: b.queue_ns or 0)
            return _summary(node, names, replace(b, queue_ns=None, limit="fifo"), {}, {}, None, False)
        if grown == r:
            break
        r = grown
    else:
        b = max(known.values(), key=lambda b: b.queue_ns or 0)
        return _summary(node, names, replace(b, queue_ns=None, limit="iterations"), {}, {}, None, False)
    # the backlog: a frame leaves the queue when its transmission starts, at most R - C after it was queued (the
    # frame on the bus no longer takes a slot, as the simulator's queue counts it)
    waiting = [(n, frozenset(names)) for n in sorted(free)]
    if pattern:
        waiting += _together(pattern, free, {f.name: r[f.name] - f.c_ns for f in ordered}, ppm)
    ahead = {n: max(len(s) - 1 for m, s in waiting if m == n) for n in names}
    top = max((worst[n] for n in names), key=lambda b: (b.queue_ns or 0, -rank[b.lowest]))
    narrowed = any(len(s) < len(names) for _, s in sets)
    return _summary(node, names, top, worst, ahead, 1 + max(ahead.values()), narrowed)


def _together(
    pattern: tuple[int, list[tuple[CanFrame, int]]], free: frozenset[str], stay: Mapping[str, int], ppm: int
) -> list[tuple[str, frozenset[str]]]:
    """For each release j of a member with an offset, the members whose frame can be in the queue when j's is
    queued: a release k at d ns of the node's clock before j (d ranging over the hyperperiod's repetitions) is
    queued J_k after it at most, and stays at most `stay` (R_k until sent, R_k - C_k until it starts); j is queued
    within J_j of its release. So k's frame can be there if the real distance D satisfies -J_j <= D < J_k + stay_k,
    the clock making D anything between shortest_real(d) and longest_real(d). Only the nearest repetition on each
    side matters."""
    period, jobs = pattern
    out = []
    for fj, oj in jobs:
        s = set(free) | {fj.name}
        for fk, ok in jobs:
            if fk.name in s:
                continue
            d = (oj - ok) % period  # k released d before j, or period - d after it
            if shortest_real(d, ppm) < fk.j_ns + stay[fk.name] or shortest_real(period - d, ppm) <= fj.j_ns:
                s.add(fk.name)
        out.append((fj.name, frozenset(s)))
    return out


def _summary(
    node: str,
    names: tuple[str, ...],
    top: FifoBound,
    bounds: Mapping[str, FifoBound],
    ahead: Mapping[str, int],
    backlog: int | None,
    narrowed: bool,
) -> FifoQueue:
    return FifoQueue(
        node,
        names,
        top.lowest,
        top.blocking_ns,
        top.queued_ns,
        top.c_min_ns,
        top.interference_ns,
        top.queue_ns,
        top.limit,
        top.error_ns,
        top.together,
        bounds,
        ahead,
        backlog,
        narrowed,
    )


def _bound(
    together: list[CanFrame],
    names: tuple[str, ...],
    frames: Sequence[CanFrame],
    jitter: Mapping[str, int],
    tau_ns: int,
    ppm: int,
    errors: ErrorModel | None = None,
) -> FifoBound:
    """Davis's bound of a FIFO holding `together` (in priority order); `names`: all of the node's FIFO members,
    whose frames are never another node's."""
    lowest = together[-1]
    others = [f for f in frames if f.name not in names]
    hp = [f for f in others if f.priority_key < lowest.priority_key]
    blocking = max((f.c_ns for f in others if f.priority_key > lowest.priority_key), default=0)
    queued = sum(f.c_ns for f in together)
    c_min = min(f.c_ns for f in together)
    base = blocking + queued - c_min
    q = FifoBound(tuple(f.name for f in together), lowest.name, blocking, queued, c_min, None, None)
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
    return replace(q, interference_ns=w - base - lost, queue_ns=r, error_ns=lost)
