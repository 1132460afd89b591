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
those terms are a prefix sum of C; only the few messages with a shorter period need the ceiling. Keeping
the messages sorted by T_k - J_k makes that set a prefix found by binary search, vectorised with numpy.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from itertools import chain
from math import lcm
from typing import Literal

import numpy as np

from netcfg.timing.can_errors import ErrorModel, recovery_costs
from netcfg.timing.clocks import PPM, longest_local, shortest_real
from netcfg.timing.frames import arbitration_key
from netcfg.timing.load import compare_to_capacity

ONE_SHOT = 1 << 60  # "period" of an on-demand message: it interferes at most once per busy period
MAX_ITERATIONS = 20_000  # fixed-point steps per message (busy period and every instance together)

# why a response time is None: the load reaches the capacity, or the bound needs more than MAX_ITERATIONS, or a
# FIFO transmit queue can hold two instances of one message (can_fifo)
Limit = Literal["load", "iterations", "fifo"]


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
    c = np.array([f.c_ns for f in fs], dtype=np.int64)
    t = np.array([f.t_ns or ONE_SHOT for f in fs], dtype=np.int64)
    j = np.array([f.j_ns for f in fs], dtype=np.int64)
    prefix_c = np.concatenate(([0], np.cumsum(c)))  # prefix_c[i] = sum of C over hp(i)
    periodic = t < ONE_SHOT
    # utilisation of hp(i) + i at the fastest clocks, approximately
    utilisation = np.cumsum(np.where(periodic, c / t, 0.0)) * (PPM / (PPM - tolerance_ppm))
    blocking = np.concatenate((np.maximum.accumulate(c[::-1])[::-1][1:], [0]))  # max C over lp(i)
    # ceil(longest_local(x + J_k) / T_k) > 1 needs x > shortest_real(T_k) - J_k: "short" messages first
    slack = np.where(periodic, shortest_real(np.where(periodic, t, 0), tolerance_ppm), t) - j
    slack_order = np.argsort(slack, kind="stable")
    slack_sorted = slack[slack_order]
    recovery = recovery_costs(c.tolist(), errors) if errors else [0] * n

    def lost(x: int, i: int) -> int:
        """E_i(x): the time bit errors may take in a window of length x (real time, as the error model is)."""
        return errors.overhead(x, recovery[i] - errors.error_frame_ns) if errors else 0

    def extra(x: int, upto: int) -> int:
        """sum over k < upto of (ceil((x + J_k) / T_k) - 1) * C_k, x + J_k on k's clock: the interference
        beyond one instance each."""
        cut = int(np.searchsorted(slack_sorted, x, side="left"))
        if cut == 0:
            return 0
        ks = slack_order[:cut]
        ks = ks[ks < upto]
        if ks.size == 0:
            return 0
        return int(((-(-longest_local(x + j[ks], tolerance_ppm) // t[ks])) - 1) @ c[ks])

    def demand(x: int, upto: int) -> int:
        """Eq. 10's right-hand side without blocking: sum over k < upto of ceil((x + J_k) / T_k) * C_k."""
        return int(prefix_c[upto]) + extra(x, upto)

    out: dict[str, Response] = {}
    for i, f in enumerate(fs):
        b = int(blocking[i])
        # lazy: the exact sum is formed only when the float one lies too close to 1 (building the pairs for every
        # message made the analysis quadratic in Python objects: 0.11 s instead of 0.02 s for 1,000 messages)
        hp_loads: Iterable[tuple[int, int]] = (
            (int(ck) * PPM, int(tk) * (PPM - tolerance_ppm))
            for ck, tk, p in zip(c[: i + 1], t[: i + 1], periodic[: i + 1])
            if p
        )
        approx = float(utilisation[i])
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
        busy = b + int(prefix_c[i + 1])
        while steps < MAX_ITERATIONS:
            nxt = b + demand(busy, i + 1) + lost(busy, i)
            steps += 1
            if nxt == busy:
                break
            busy = nxt
        else:
            out[f.name] = Response(f.name, None, b, None, 0, 0, "iterations")
            continue
        q_count = max(1, -(-longest_local(busy + int(j[i]), tolerance_ppm) // int(t[i])))
        worst, worst_q, worst_e, w = -1, 0, 0, 0
        for q in range(q_count):
            w = max(w, b + q * int(c[i]) + int(prefix_c[i]))
            while steps < MAX_ITERATIONS:  # eq. 12
                nxt = b + q * int(c[i]) + demand(w + tau_ns, i) + lost(w + int(c[i]), i)
                steps += 1
                if nxt == w:
                    break
                w = nxt
            else:
                break
            r = int(j[i]) + w - shortest_real(q * int(t[i]), tolerance_ppm) + int(c[i])
            if r > worst:
                worst, worst_q, worst_e = r, q, lost(w + int(c[i]), i)
        if steps >= MAX_ITERATIONS:
            out[f.name] = Response(f.name, None, b, busy, q_count, 0, "iterations")
            continue
        out[f.name] = Response(f.name, worst, b, busy, q_count, worst_q, error_ns=worst_e)
    return out


def _ends_at_full_load(b: int, c: np.ndarray, t: np.ndarray, j: np.ndarray, periodic: np.ndarray) -> bool:
    """At a utilisation of exactly 1, eq. 10 has a fixed point iff it has one at or below the hyperperiod L:
    its right-hand side is at least t + B + (jitter and one-shot terms) everywhere, and equals L at L when those
    are 0; the iteration from below then reaches it. Python integers: L may not fit in 64 bits."""
    hyper = lcm(*(int(tk) for tk, p in zip(t, periodic) if p))
    need = b + sum(-(-(hyper + int(jk)) // int(tk)) * int(ck) for ck, tk, jk in zip(c, t, j))
    return need <= hyper


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
