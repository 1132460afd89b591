"""Worst-case response times of classical CAN messages.

The analysis is the revised one of Davis, Burns, Bril and Lukkien (2007), "Controller Area Network (CAN)
schedulability analysis: refuted, revisited and revised", Real-Time Systems 35(3), section 5, implemented
from its equations. For a message m with transmission time C_m, period (or minimum inter-arrival) T_m,
queuing jitter J_m, and bit time tau:

  blocking         B_m = max over lower-priority k of C_k                                         (eq. 5)
  busy period      t_m = B_m + sum over k in hp(m) + m of ceil((t_m + J_k) / T_k) * C_k             (eq. 10)
  instances        Q_m = ceil((t_m + J_m) / T_m)                                                    (eq. 11)
  queuing delay    w_m(q) = B_m + q*C_m + sum over k in hp(m) of ceil((w_m(q) + J_k + tau) / T_k) * C_k (eq. 12)
  response time    R_m(q) = J_m + w_m(q) - q*T_m + C_m,   R_m = max over q in 0..Q_m-1           (eq. 13, 14)

The arithmetic is exact: times are integer nanoseconds and the utilisation test is decided with fractions
(a float sum of ten loads of 0.1 is 0.9999999999999999). When the utilisation of hp(m) + m exceeds 1 the busy
period never ends and R_m is unbounded (None). At exactly 1 it ends only if the traffic repeats without
blocking or jitter: then the busy period is at most the hyperperiod L, which one evaluation of eq. 10 at L
decides. A busy period that needs more than MAX_ITERATIONS fixed-point steps (utilisation a hair under 1)
is reported as such (`limit == "iterations"`) rather than computed for minutes.
Priorities follow the arbitration field: a lower base identifier wins; at an equal 11-bit base, a standard
frame beats an extended one (its RTR/IDE bits are dominant where the extended frame sends SRR/IDE recessive).

Bit errors (`errors`, netcfg.timing.can_errors): an additive term E_m(t) = (n + ceil(t / T_err)) * (error frame +
max over hep(m) of C) joins eq. 10 as E_m(t_m) and eq. 12 as E_m(w_m(q) + C_m) (an error may hit m itself), and the
errors' long-run rate, one recovery per T_err, joins the utilisation test.

Speed: in a fixed-point step, ceil(x / T_k) is 1 for every k with T_k - J_k >= x (x = w + tau or t), so
those terms are a prefix sum of C; only the messages with a shorter period need the ceiling. Messages of one
period and jitter share that ceiling, so they are kept as one class (sorted by T_k - J_k, with a prefix sum of
C over its members in priority order): a step costs one term per class of shorter period, and a bus has a
handful of periods. Plain Python integers: exact at any size, and `check` loads no numpy; only a bus of more than
MANY_CLASSES classes sums per message with numpy, which is faster there.
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from itertools import accumulate, chain
from math import lcm
from typing import Literal

from netcfg.timing.can_errors import ErrorModel, recovery_costs
from netcfg.timing.clocks import PPM, longest_local, shortest_real
from netcfg.timing.frames import arbitration_key
from netcfg.timing.load import compare_to_capacity

ONE_SHOT = 1 << 60  # "period" of an on-demand message: it interferes at most once per busy period
MAX_ITERATIONS = 20_000  # fixed-point steps per message (busy period and every instance together)
# a bus with more classes of (period, jitter) than this sums its interference with numpy, per message: Python's
# loop costs about 0.3 us a class and step, numpy's about 0.06 us a message and step plus 0.05 s to import it
MANY_CLASSES = 512

# why a response time is None: the load reaches the capacity, or the bound needs more than MAX_ITERATIONS, or a
# FIFO transmit queue can hold two instances of one message, or can be full when a frame that it drops is queued
# (can_fifo)
Limit = Literal["load", "iterations", "fifo", "dropped"]


@dataclass(frozen=True)
class CanFrame:
    name: str
    id: int
    extended: bool
    c_ns: int  # worst-case transmission time, inter-frame space included
    t_ns: int | None  # period or minimum inter-arrival time; None: on-demand, sent at most once
    j_ns: int = 0  # queuing jitter
    d_ns: int | None = None  # deadline

    @property
    def priority_key(self) -> int:
        return arbitration_key(self.id, self.extended)


@dataclass(frozen=True)
class Response:
    name: str
    wcrt_ns: int | None  # None: unbounded
    blocking_ns: int
    busy_period_ns: int | None
    instances: int  # Q_m
    worst_instance: int  # the q that gave R_m
    limit: Limit | None = None  # set when wcrt_ns is None
    error_ns: int = 0  # E_m in the worst instance's queuing delay (0 without an error model)

    def schedulable(self, deadline_ns: int | None) -> bool | None:
        if deadline_ns is None:
            return None
        return self.wcrt_ns is not None and self.wcrt_ns <= deadline_ns


def analyse(
    frames: Sequence[CanFrame], tau_ns: int, tolerance_ppm: int = 0, errors: ErrorModel | None = None
) -> dict[str, Response]:
    """Response time of every frame on one bus (all frames compete in arbitration). Periods are counted on their
    senders' clocks, each within +-tolerance_ppm of nominal (see clocks): a window of x real ns holds the releases
    of longest_local(x) ns of a sender's time, and q periods of m last at least shortest_real(q T_m). `errors`: the
    bit errors allowed for (None: an error-free bus)."""
    order = sorted(range(len(frames)), key=lambda i: frames[i].priority_key)
    fs = [frames[i] for i in order]
    n = len(fs)
    if n == 0:
        return {}
    c = [f.c_ns for f in fs]
    t = [f.t_ns or ONE_SHOT for f in fs]
    j = [f.j_ns for f in fs]
    prefix_c = list(accumulate(c, initial=0))  # prefix_c[i] = sum of C over hp(i)
    periodic = [tk < ONE_SHOT for tk in t]
    # utilisation of hp(i) + i at the fastest clocks, approximately
    fast = PPM / (PPM - tolerance_ppm)
    utilisation = [u * fast for u in accumulate(ck / tk if p else 0.0 for ck, tk, p in zip(c, t, periodic))]
    blocking = [*reversed(list(accumulate(reversed(c[1:]), max))), 0]  # max C over lp(i)
    classes = _interference_classes(c, t, j, periodic, tolerance_ppm)
    recovery = recovery_costs(c, errors) if errors else [0] * n

    def lost(x: int, i: int) -> int:
        """E_i(x): the time bit errors may take in a window of length x (real time, as the error model is)."""
        return errors.overhead(x, recovery[i] - errors.error_frame_ns) if errors else 0

    extra = (
        _extra_by_class(classes, tolerance_ppm)
        if len(classes) <= MANY_CLASSES
        else _extra_vectorised(c, t, j, periodic, tolerance_ppm)
    )

    def demand(x: int, upto: int) -> int:
        """Eq. 10's right-hand side without blocking: sum over k < upto of ceil((x + J_k) / T_k) * C_k."""
        return prefix_c[upto] + extra(x, upto)

    out: dict[str, Response] = {}
    for i, f in enumerate(fs):
        b = blocking[i]
        # lazy: the exact sum is formed only when the float one lies too close to 1 (building the pairs for every
        # message made the analysis quadratic in Python objects: 0.11 s instead of 0.02 s for 1,000 messages)
        hp_loads: Iterable[tuple[int, int]] = (
            (c[k] * PPM, t[k] * (PPM - tolerance_ppm)) for k in range(i + 1) if periodic[k]
        )
        approx = utilisation[i]
        if errors:  # one recovery per T_err in the long run
            hp_loads = chain(hp_loads, [(recovery[i], errors.interval_ns)])
            approx += recovery[i] / errors.interval_ns
        full = compare_to_capacity(approx, hp_loads)
        # exactly full with drifting clocks: the fastest clocks overload it, so no end is assumed; with errors a
        # burst on a full bus is never caught up
        if full > 0 or (
            full == 0
            and (
                tolerance_ppm
                or errors is not None
                or not _ends_at_full_load(b, c[: i + 1], t[: i + 1], j[: i + 1], periodic[: i + 1])
            )
        ):
            out[f.name] = Response(f.name, None, b, None, 0, 0, "load")
            continue
        # level-i busy period (eq. 10), starting from a lower bound of its least fixed point
        steps = 0
        busy = b + prefix_c[i + 1]
        while steps < MAX_ITERATIONS:
            nxt = b + demand(busy, i + 1) + lost(busy, i)
            steps += 1
            if nxt == busy:
                break
            busy = nxt
        else:
            out[f.name] = Response(f.name, None, b, None, 0, 0, "iterations")
            continue
        q_count = max(1, -(-longest_local(busy + j[i], tolerance_ppm) // t[i]))
        worst, worst_q, worst_e, w = -1, 0, 0, 0
        for q in range(q_count):
            w = max(w, b + q * c[i] + prefix_c[i])
            while steps < MAX_ITERATIONS:  # eq. 12
                nxt = b + q * c[i] + demand(w + tau_ns, i) + lost(w + c[i], i)
                steps += 1
                if nxt == w:
                    break
                w = nxt
            else:
                break
            r = j[i] + w - shortest_real(q * t[i], tolerance_ppm) + c[i]
            if r > worst:
                worst, worst_q, worst_e = r, q, lost(w + c[i], i)
        if steps >= MAX_ITERATIONS:
            out[f.name] = Response(f.name, None, b, busy, q_count, 0, "iterations")
            continue
        out[f.name] = Response(f.name, worst, b, busy, q_count, worst_q, error_ns=worst_e)
    return out


def _ends_at_full_load(b: int, c: list[int], t: list[int], j: list[int], periodic: list[bool]) -> bool:
    """At a utilisation of exactly 1, eq. 10 has a fixed point iff it has one at or below the hyperperiod L:
    its right-hand side is at least t + B + (jitter and one-shot terms) everywhere, and equals L at L when those
    are 0; the iteration from below then reaches it."""
    hyper = lcm(*(tk for tk, p in zip(t, periodic) if p))
    need = b + sum(-(-(hyper + jk) // tk) * ck for ck, tk, jk in zip(c, t, j))
    return need <= hyper


@dataclass(frozen=True)
class _Class:
    """Messages of one period and jitter: in a window of x they are all released ceil((x + J) / T) times."""

    slack: int  # a window longer than this holds a second release of each (see `analyse`)
    t: int
    j: int
    members: list[int]  # their priority ranks, ascending
    prefix_c: list[int]  # prefix_c[r] = sum of C over the first r members


def _extra_by_class(classes: list[_Class], tolerance_ppm: int) -> Callable[[int, int], int]:
    def extra(x: int, upto: int) -> int:
        """sum over k < upto of (ceil((x + J_k) / T_k) - 1) * C_k, x + J_k on k's clock: the interference
        beyond one instance each."""
        total = 0
        for cls in classes:
            if cls.slack >= x:
                break
            members = bisect_left(cls.members, upto)
            if members:
                total += (-(-longest_local(x + cls.j, tolerance_ppm) // cls.t) - 1) * cls.prefix_c[members]
        return total

    return extra


def _extra_vectorised(
    c: list[int], t: list[int], j: list[int], periodic: list[bool], tolerance_ppm: int
) -> Callable[[int, int], int]:
    """The same sum over messages sorted by slack, with numpy: for buses of many distinct periods (5,000 distinct
    periods: 0.8 s against 3.9 s by class)."""
    import numpy as np

    c_arr, t_arr, j_arr = (np.array(v, dtype=np.int64) for v in (c, t, j))
    slack = np.array([shortest_real(tk, tolerance_ppm) if p else tk for tk, p in zip(t, periodic)], dtype=np.int64)
    slack -= j_arr
    slack_order = np.argsort(slack, kind="stable")
    slack_sorted = slack[slack_order]

    def extra(x: int, upto: int) -> int:
        cut = int(np.searchsorted(slack_sorted, x, side="left"))
        ks = slack_order[:cut]
        ks = ks[ks < upto]
        if ks.size == 0:
            return 0
        return int(((-(-longest_local(x + j_arr[ks], tolerance_ppm) // t_arr[ks])) - 1) @ c_arr[ks])

    return extra


def _interference_classes(
    c: list[int], t: list[int], j: list[int], periodic: list[bool], tolerance_ppm: int
) -> list[_Class]:
    """The messages grouped by (T, J), ordered by slack: a fixed-point step pays per class, not per message
    (a bus has a handful of periods)."""
    ranks: dict[tuple[int, int], list[int]] = {}
    for k, key in enumerate(zip(t, j)):
        ranks.setdefault(key, []).append(k)
    classes = [
        _Class(
            (shortest_real(tk, tolerance_ppm) if periodic[ks[0]] else tk) - jk,
            tk,
            jk,
            ks,
            list(accumulate((c[k] for k in ks), initial=0)),
        )
        for (tk, jk), ks in ranks.items()
    ]
    return sorted(classes, key=lambda cls: cls.slack)


def tindell_1994(frames: Sequence[CanFrame], tau_ns: int) -> dict[str, int | None]:
    """The original, optimistic analysis (Tindell, Burns, Wellings 1994): only the first instance in the
    busy period, R = J + w + C with w = B + sum over hp of ceil((w + J_k + tau) / T_k) * C_k. Kept only to
    show, in the tests, the cases where it is wrong (Davis et al. 2007, section 3)."""
    fs = sorted(frames, key=lambda f: f.priority_key)
    out: dict[str, int | None] = {}
    for i, f in enumerate(fs):
        b = max((g.c_ns for g in fs[i + 1 :]), default=0)
        hp = fs[:i]
        if sum(g.c_ns / (g.t_ns or ONE_SHOT) for g in hp) >= 1:
            out[f.name] = None
            continue
        w = b
        while True:
            nxt = b + sum(-(-(w + g.j_ns + tau_ns) // (g.t_ns or ONE_SHOT)) * g.c_ns for g in hp)
            if nxt == w:
                break
            w = nxt
        out[f.name] = f.j_ns + w + f.c_ns
    return out
