"""Worst-case response times of classical CAN messages when the messages of one sender keep offsets.

Model: Tindell's transaction model (Tindell 1994, "Adding time-offsets to schedulability analysis", University of
York YCS-221; Palencia and Gonzalez Harbour 1998, "Schedulability analysis for tasks with static and dynamic
offsets", RTSS), applied to CAN as Yomsi, Bertrand, Navet and Davis (2012, "Controller Area Network (CAN): response
time analysis with offsets", WFCS) do: the periodic messages a node sends from one clock with fixed offsets form a
transaction; transactions (nodes) have no common clock, so their phases are arbitrary. Each transaction is unrolled
over its hyperperiod L (the lcm of its periods): a message of period T becomes L / T jobs of period L.

We use the sufficient (upper-bound) test, not the exact one: the exact analysis tries every combination of one
candidate job per transaction at the critical instant, exponential in the number of nodes; the upper bound takes,
for every other transaction independently, the most work it can release in any window of length x,

    I_G(x) = max over candidate jobs c of G of sum over jobs j of G in hp(m) of n_jc(x) * C_j,

which is what Yomsi et al. call the sufficient test, chosen here because it is polynomial and needs no search
over node phases (which are unknown on a real bus). Only the analysed message's own node is anchored: its busy
period starts at one of its jobs at or above m's priority (the candidate c), and m's instances sit at their offsets
from it. The response time of every instance of m in the level-m busy period is taken as in Davis, Burns, Bril and
Lukkien (2007, section 5, eqs. 10-14), with the interference of the other transactions given by I_G:

    busy period  t = B + sum_G I_G(t) + (own jobs at or above m's priority queued in [0, t))
    instance p   w_p = B + (earlier instances of m) * C_m + sum_G I_G(w_p + tau) + (own hp jobs in [0, w_p + tau))
                 R_p = w_p + C_m - (earliest possible release of p relative to the busy period's start)

Jitter: a job j is counted in a window [0, x) anchored on c's queuing if some release of c within its jitter
allows it: its distance d from c's nominal release satisfies -J_j <= d < x + J_c (a union over c's jitter, sound;
with J_c = 0 it is Palencia's count floor((J_j + phi)/T) + ceil((x - phi)/T)). Clocks: a transaction runs on its
sender's clock, within +-tolerance of nominal, so a window of x real ns is counted as longest_local(x) ns of it
and a distance d between two of its releases as at least shortest_real(d) real ns. Every bound here is also taken no
larger than the offset-free one (both are sound), so without offsets the result is exactly can_rta.analyse's.
Bit errors (can_rta's `errors`) add the same term E_m here: E_m(t) to the busy period, E_m(w_p + C_m) to w_p.
A transaction whose unrolling passes MAX_JOBS jobs is analysed without offsets (its messages stay independent).

With `latest` the candidate c is taken at its latest release, as Palencia and Gonzalez Harbour (1998, section 3) place
the critical instant: the busy period starts as c is queued after its whole jitter, and the jobs counted are those
whose latest release is not before it, -J_j + J_c <= d < x + J_c (their phase phi_ijk = T - (Phi_k + J_k - Phi_j)
mod T); the union over c's jitter is not needed because every candidate is tried. With clocks, J_c is taken as
shortest_real(J_c) there. can_transactions, whose replies carry a jitter of up to their commands' whole response,
uses it; the static offsets of one sender keep the union (their bounds stay as they were).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from math import lcm
from typing import TYPE_CHECKING

from netcfg.timing import can_rta
from netcfg.timing.can_errors import ErrorModel
from netcfg.timing.can_rta import CanFrame, Response
from netcfg.timing.clocks import longest_local, longest_real, shortest_real

if TYPE_CHECKING:  # numpy is imported where a bus has transactions: a bus without offsets is analysed without it
    import numpy as np

MAX_JOBS = 512  # jobs of one unrolled transaction
MAX_STEPS = 20_000  # fixed-point steps per message before the offset-free bound is kept


@dataclass(frozen=True)
class Transaction:
    """The jobs of one sender's offset messages over one hyperperiod, ordered by priority then offset."""

    node: str
    hyperperiod_ns: int
    names: tuple[str, ...]  # message of each job
    offset_ns: np.ndarray  # offset of each job inside the hyperperiod
    c_ns: np.ndarray
    j_ns: np.ndarray
    key: np.ndarray  # arbitration key of each job's message


def unrolled_jobs(periods: Sequence[int]) -> int:
    """Jobs of one sender's offset messages with these periods over their hyperperiod."""
    hyper = lcm(*periods)
    return sum(hyper // t for t in periods)


def too_long(members: Mapping[str, tuple[str, int]]) -> dict[str, list[str]]:
    """Message -> (sender, period) of the messages with an offset: the senders whose unrolling passes MAX_JOBS
    (transactions leaves them out, so their offsets are not used), each with its messages in name order."""
    by_node: dict[str, list[tuple[str, int]]] = {}
    for name, (node, period) in members.items():
        by_node.setdefault(node, []).append((name, period))
    return {
        node: sorted(n for n, _ in group)
        for node, group in sorted(by_node.items())
        if len(group) > 1 and unrolled_jobs([t for _, t in group]) > MAX_JOBS
    }


def transactions(frames: Sequence[CanFrame], offsets: Mapping[str, tuple[str, int]]) -> list[Transaction]:
    """Group the frames with a known offset by sender and unroll each group; a group of one message gains
    nothing from offsets and is left out, as is one whose unrolling is too long."""
    by_node: dict[str, list[tuple[CanFrame, int]]] = {}
    for f in frames:
        if f.name in offsets and f.t_ns:
            node, offset = offsets[f.name]
            by_node.setdefault(node, []).append((f, offset))
    out: list[Transaction] = []
    if not any(len(members) > 1 for members in by_node.values()):
        return out
    import numpy as np

    for node in sorted(by_node):
        members = by_node[node]
        if len(members) < 2:
            continue
        if unrolled_jobs([f.t_ns for f, _ in members if f.t_ns]) > MAX_JOBS:
            continue
        period = lcm(*(f.t_ns for f, _ in members if f.t_ns))
        jobs = sorted(
            (
                (f.priority_key, (o + k * f.t_ns) % period, f)
                for f, o in members
                if f.t_ns
                for k in range(period // f.t_ns)
            ),
            key=lambda x: (x[0], x[1]),
        )
        out.append(
            Transaction(
                node,
                period,
                tuple(f.name for _, _, f in jobs),
                np.array([o for _, o, _ in jobs], dtype=np.int64),
                np.array([f.c_ns for _, _, f in jobs], dtype=np.int64),
                np.array([f.j_ns for _, _, f in jobs], dtype=np.int64),
                np.array([k for k, _, _ in jobs], dtype=np.int64),
            )
        )
    return out


def _counts(distance: np.ndarray, jitter: np.ndarray, period: int, window: np.ndarray) -> np.ndarray:
    """Releases at distance + n*period (any integer n) with -jitter <= d < window: how many, elementwise."""
    import numpy as np  # loaded already (the caller's arrays); a bound name of the module would be imported eagerly

    first = -((jitter + distance) // period)  # ceil((-jitter - distance) / period)
    last = -(-(window - distance) // period) - 1  # ceil((window - distance) / period) - 1
    return np.maximum(last - first + 1, 0)  # not ndarray.clip: ten times the overhead on these small arrays


class _Interference:
    """I_G(x) of one other transaction for the messages below its first `count` jobs (jobs are in priority order,
    so those are the jobs above such a message). Messages between the same two jobs of G share one, and the values
    it computed: the fixed points of neighbouring messages revisit the same windows."""

    def __init__(self, tr: Transaction, count: int, ppm: int, latest: bool = False) -> None:
        self.period = tr.hyperperiod_ns
        self.ppm = ppm
        self.c = tr.c_ns[:count]
        self.j = longest_local(tr.j_ns[:count], ppm)
        o = tr.offset_ns[:count]
        self.distance = (o[None, :] - o[:, None]) % self.period  # [candidate, job]
        self.jc = self.j[:, None]
        # the jobs' jitter less the candidate's (its latest release: `latest`), [candidate, job]
        self.lead = self.j[None, :] - (shortest_real(tr.j_ns[:count], ppm)[:, None] if latest else 0)
        self.at: dict[int, int] = {}

    def __call__(self, x: int) -> int:
        if self.c.size == 0:
            return 0
        if (known := self.at.get(x)) is not None:
            return known
        n = _counts(self.distance, self.lead, self.period, longest_local(x + self.jc, self.ppm))
        self.at[x] = value = int((n @ self.c).max())
        return value


def analyse(
    frames: Sequence[CanFrame],
    tau_ns: int,
    offsets: Mapping[str, tuple[str, int]],
    tolerance_ppm: int = 0,
    errors: ErrorModel | None = None,
    latest: bool = False,
) -> dict[str, Response]:
    """Response time of every frame on one bus; `offsets` maps a message to (its sender, its offset) when it is
    released at that offset of its sender's clock (periodic, not sent by a task); `errors` the bit errors allowed
    for. Never above can_rta.analyse. Senders' clocks are within +-tolerance_ppm of nominal. `latest`: each
    candidate of a busy period's start at its latest release (Palencia and Gonzalez Harbour), else any."""
    plain = can_rta.analyse(frames, tau_ns, tolerance_ppm, errors)
    groups = transactions(frames, offsets)
    if not groups:
        return plain
    grouped = {name for tr in groups for name in tr.names}
    interference: dict[tuple[int, int], _Interference] = {}  # by (transaction, jobs above the message)
    out = dict(plain)
    for f in frames:
        r = plain[f.name]
        if r.wcrt_ns is None:
            continue
        bound = _with_offsets(
            f, frames, groups, grouped, r.blocking_ns, tau_ns, tolerance_ppm, errors, interference, latest
        )
        if bound is not None and bound < r.wcrt_ns:
            out[f.name] = replace(r, wcrt_ns=bound)
    return out


def _with_offsets(
    m: CanFrame,
    frames: Sequence[CanFrame],
    groups: list[Transaction],
    grouped: set[str],
    blocking: int,
    tau: int,
    ppm: int,
    errors: ErrorModel | None = None,
    interference: dict[tuple[int, int], _Interference] | None = None,
    latest: bool = False,
) -> int | None:
    import numpy as np

    key = m.priority_key
    largest = max(g.c_ns for g in frames if g.priority_key <= key)  # the frames an error can make m wait for

    def lost(x: int) -> int:
        return errors.overhead(x, largest) if errors else 0

    free = [g for g in frames if g.name not in grouped and g.priority_key < key]  # independent hp messages
    fc = np.array([g.c_ns for g in free], dtype=np.int64)
    ft = np.array([g.t_ns or can_rta.ONE_SHOT for g in free], dtype=np.int64)
    fj = np.array([g.j_ns for g in free], dtype=np.int64)
    own = next((tr for tr in groups if m.name in tr.names), None)
    shared = {} if interference is None else interference
    others = []
    for g, tr in enumerate(groups):
        if tr is not own:
            count = int(np.searchsorted(tr.key, key, side="left"))  # its jobs above m
            if (known := shared.get((g, count))) is None:
                known = shared[g, count] = _Interference(tr, count, ppm, latest)
            others.append(known)

    def local(x: int) -> int:
        return longest_local(x, ppm)

    def earliest(d: int) -> int:
        """The least real distance of a release d ns (of its sender's clock) after another one."""
        return shortest_real(d, ppm) if d >= 0 else -longest_real(-d, ppm)

    foreign_at: dict[int, int] = {}  # the fixed points below revisit the same windows; numpy per call is slow

    def foreign(x: int) -> int:
        """Work of everything but m's own transaction in a window of length x."""
        if (known := foreign_at.get(x)) is not None:
            return known
        total = int((-(-longest_local(x + fj, ppm) // ft)) @ fc) if fc.size else 0
        foreign_at[x] = total = total + sum(i(x) for i in others)
        return total

    steps = 0

    def least_fixed_point(start: int, rhs: object) -> int | None:
        nonlocal steps
        x = start
        while steps < MAX_STEPS:
            steps += 1
            nxt = rhs(x)  # type: ignore[operator]
            if nxt <= x:
                return x
            x = nxt
        return None

    if own is None:
        # m's instances: independent, as in Davis et al. 2007 with I_G in place of the offset-free terms
        t_m = m.t_ns or can_rta.ONE_SHOT
        busy = least_fixed_point(
            blocking + m.c_ns, lambda t: blocking + foreign(t) + -(-local(t + m.j_ns) // t_m) * m.c_ns + lost(t)
        )
        if busy is None:
            return None
        worst = 0
        for q in range(max(1, -(-local(busy + m.j_ns) // t_m))):
            w = least_fixed_point(
                blocking + q * m.c_ns, lambda x, q=q: blocking + q * m.c_ns + foreign(x + tau) + lost(x + m.c_ns)
            )
            if w is None:
                return None
            worst = max(worst, m.j_ns + w - shortest_real(q * t_m, ppm) + m.c_ns)
        return worst

    period = own.hyperperiod_ns
    level = own.key <= key  # m's own jobs and those above it
    hp = own.key < key
    mine = own.key == key
    worst = 0
    for c in np.flatnonzero(level):
        jc = int(own.j_ns[c])
        shift = shortest_real(jc, ppm) if latest else 0  # the jobs counted are those not released before c
        dist = (own.offset_ns - own.offset_ns[c]) % period  # every own job's distance from c's nominal release
        dist_hp, j_hp, c_hp = dist[hp], longest_local(own.j_ns[hp], ppm) - shift, own.c_ns[hp]

        def own_hp(
            x: int, dist_hp: np.ndarray = dist_hp, j_hp: np.ndarray = j_hp, c_hp: np.ndarray = c_hp, jc: int = jc
        ) -> int:
            return int(_counts(dist_hp, j_hp, period, np.int64(local(x + jc))) @ c_hp)

        # m's instances around c: distances d + n*L, present in the busy period when d >= -J_m
        d_m = dist[mine]

        def m_count(x: int, d_m: np.ndarray = d_m, jc: int = jc, shift: int = shift) -> int:
            return int(_counts(d_m, np.full_like(d_m, local(m.j_ns) - shift), period, np.int64(local(x + jc))).sum())

        busy = least_fixed_point(
            blocking + m.c_ns,
            lambda t, own_hp=own_hp, m_count=m_count: blocking + foreign(t) + own_hp(t) + m_count(t) * m.c_ns + lost(t),
        )
        if busy is None:
            return None
        # the instances of m in the busy period, in release order
        first = -((local(m.j_ns) - shift + d_m) // period)
        last = -(-(local(busy + jc) - d_m) // period) - 1
        instances = sorted(int(d + n * period) for d, a, b in zip(d_m, first, last) for n in range(int(a), int(b) + 1))
        for earlier, d in enumerate(instances):
            w = least_fixed_point(
                blocking + earlier * m.c_ns,
                lambda x, e=earlier, own_hp=own_hp: (
                    blocking + e * m.c_ns + foreign(x + tau) + own_hp(x + tau) + lost(x + m.c_ns)
                ),
            )
            if w is None:
                return None
            worst = max(worst, w + m.c_ns - max(earliest(d) - jc, -m.j_ns))
    return worst
