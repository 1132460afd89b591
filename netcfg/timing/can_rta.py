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

When the utilisation of hp(m) + m reaches 1 the busy period never ends and R_m is unbounded (None).
Priorities follow the arbitration field: a lower base identifier wins; at an equal 11-bit base, a standard
frame beats an extended one (its RTR/IDE bits are dominant where the extended frame sends SRR/IDE recessive).

Speed: in a fixed-point step, ceil(x / T_k) is 1 for every k with T_k - J_k >= x (x = w + tau or t), so
those terms are a prefix sum of C; only the few messages with a shorter period need the ceiling. Keeping
the messages sorted by T_k - J_k makes that set a prefix found by binary search, vectorised with numpy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from netcfg.timing.frames import arbitration_key

ONE_SHOT = 1 << 60  # "period" of an on-demand message: it interferes at most once per busy period
MAX_INSTANCES = 1_000_000


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

    def schedulable(self, deadline_ns: int | None) -> bool | None:
        if deadline_ns is None:
            return None
        return self.wcrt_ns is not None and self.wcrt_ns <= deadline_ns


def analyse(frames: Sequence[CanFrame], tau_ns: int) -> dict[str, Response]:
    """Response time of every frame on one bus (all frames compete in arbitration)."""
    order = sorted(range(len(frames)), key=lambda i: frames[i].priority_key)
    fs = [frames[i] for i in order]
    n = len(fs)
    if n == 0:
        return {}
    c = np.array([f.c_ns for f in fs], dtype=np.int64)
    t = np.array([f.t_ns or ONE_SHOT for f in fs], dtype=np.int64)
    j = np.array([f.j_ns for f in fs], dtype=np.int64)
    prefix_c = np.concatenate(([0], np.cumsum(c)))  # prefix_c[i] = sum of C over hp(i)
    utilisation = np.cumsum(np.where(t < ONE_SHOT, c / t, 0.0))  # utilisation of hp(i) + i
    blocking = np.concatenate((np.maximum.accumulate(c[::-1])[::-1][1:], [0]))  # max C over lp(i)
    slack_order = np.argsort(t - j, kind="stable")  # "short" messages first
    slack_sorted = (t - j)[slack_order]

    def extra(x: int, upto: int) -> int:
        """sum over k < upto of (ceil((x + J_k) / T_k) - 1) * C_k: the interference beyond one instance each."""
        cut = int(np.searchsorted(slack_sorted, x, side="left"))
        if cut == 0:
            return 0
        ks = slack_order[:cut]
        ks = ks[ks < upto]
        if ks.size == 0:
            return 0
        return int(((-(-(x + j[ks]) // t[ks])) - 1) @ c[ks])

    out: dict[str, Response] = {}
    for i, f in enumerate(fs):
        b = int(blocking[i])
        if utilisation[i] >= 1.0:
            out[f.name] = Response(f.name, None, b, None, 0, 0)
            continue
        # level-i busy period (eq. 10), starting from a lower bound of its least fixed point
        busy = b + int(prefix_c[i + 1])
        while True:
            nxt = b + int(prefix_c[i + 1]) + extra(busy, i + 1)
            if nxt == busy:
                break
            busy = nxt
        q_count = max(1, -(-(busy + int(j[i])) // int(t[i])))
        if q_count > MAX_INSTANCES:
            out[f.name] = Response(f.name, None, b, busy, q_count, 0)
            continue
        worst, worst_q, w = -1, 0, 0
        for q in range(q_count):
            w = max(w, b + q * int(c[i]) + int(prefix_c[i]))
            while True:  # eq. 12
                nxt = b + q * int(c[i]) + int(prefix_c[i]) + extra(w + tau_ns, i)
                if nxt == w:
                    break
                w = nxt
            r = int(j[i]) + w - q * int(t[i]) + int(c[i])
            if r > worst:
                worst, worst_q = r, q
        out[f.name] = Response(f.name, worst, b, busy, q_count, worst_q)
    return out


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
