"""Switched full-duplex Ethernet/UDP (seed 001, section 6.2.2.7).

Every cable is two independent links, one per direction. A message crosses the links on the tree path from
its producer to each consumer (a switch forwards a multicast once per egress port). Per link: frames per
second, utilisation, and the paper's rule f_transm < f_max / n, generalised to frames of any size as
sum(f_i * Tframe_i) < 1 (with n equal minimum-size frames it is exactly n * f_transm < f_max).

Delay budget, eq. 6.3:  Tdelay = Tpre + Twait + Tframe + Tprop + Tswitch + Tpost. With store-and-forward
switches the frame is serialised again on every hop, so Tframe counts once per link; Tswitch = Tmux + Tqueue.

Each link's transmitter is a FIFO queue served at the link rate (the sender's NIC, a switch's egress port). A
frame arriving at time a of a busy period that began at 0 has finished once everything that arrived in [0, a]
has been sent, so its delay is at most sup_a (W(a) - a), W(a) the most work that can arrive in a window of
length a (the horizontal deviation of network calculus, Le Boudec and Thiran 2001), and its wait that minus its
own frame. Flow i (frame C_i, period T_i, arrival jitter J_i) brings at most floor((a + J_i) / T_i) + 1
frames into such a window. Frames that reach a switch's port over one input link were serialised by that link:
they end their reception one after another, so together they bring at most a + the longest of their frames
(the "grouping" of the trajectory approach, Martin and Minet 2006; Bauer, Scharbarg and Fraboul 2010), however
bunched their jitter lets them be. The sender's NIC has no such input: its messages may all be released at once.
J_i at a link is flow i's release jitter plus the waits it may meet on the links before (0 at best); waits and
jitters depend on each other, so they are iterated from zero jitter until nothing changes (they only grow), at
most MAX_ROUNDS times (holistic analysis, Tindell and Clark 1994).

The same windows bound the backlog, in frames, that the queue must hold (the simulator drops a frame that finds
its queue full): at time a at most N(a) - floor(a / C_max) frames are there, N(a) the frames that can arrive in
[0, a] (over one input link at most floor(a / C_min) + 1 of them) and floor(a / C_max) those sent by then, and at
most the one being sent plus floor((W(a) - a) / C_min), as many as the work still queued can hold.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from itertools import pairwise
from typing import TYPE_CHECKING

from netcfg.timing import load
from netcfg.timing.frames import QUEUE_FRAMES, udp_frame_bytes, udp_frame_ns

if TYPE_CHECKING:
    import networkx as nx

    from netcfg import model

PROPAGATION_M_PER_S = 0.7 * 299_792_458  # velocity factor 0.7 (seed 001: 0.4-0.7, 2.1e8 m/s)
Link = tuple[str, str]
Flow = tuple[int, int | None, int]  # (frame time C, period T or None for at most one frame, arrival jitter J)


@dataclass(frozen=True)
class Input:
    """Frames reaching a queue one way: over one input link (serialised: at most one of its frame times per frame
    time) or, at the sender's NIC, released by the node itself (any number at once)."""

    serialised: bool
    flows: tuple[Flow, ...]


@dataclass(frozen=True)
class Queue:
    """Bounds of one FIFO transmit queue."""

    busy_period_ns: int
    delay_ns: int  # from a frame's arrival to the end of its transmission, at most
    backlog: int  # frames at the queue at once, counting the one being sent, at most


@dataclass
class LinkLoad:
    src: str
    dst: str
    messages: list[str] = field(default_factory=list)
    frames_per_s: float = 0.0
    utilization: float = 0.0
    queue: Queue | None = None  # None when the link is overloaded or its bound does not converge
    senders: set[str] = field(default_factory=set)

    @property
    def busy_period_ns(self) -> int | None:
        return None if self.queue is None else self.queue.busy_period_ns


@dataclass(frozen=True)
class PathDelay:
    message: str
    consumer: str
    hops: tuple[Link, ...]
    tpre_ns: int
    twait_ns: int | None  # FIFO wait on the sender's own link; None when that link is overloaded
    tframe_ns: int  # summed over the hops (store and forward)
    tprop_ns: int
    tswitch_ns: int | None  # Tmux + Tqueue over the switches; None when an egress port is overloaded
    tpost_ns: int

    @property
    def total_ns(self) -> int | None:
        if self.twait_ns is None or self.tswitch_ns is None:
            return None
        return self.tpre_ns + self.twait_ns + self.tframe_ns + self.tprop_ns + self.tswitch_ns + self.tpost_ns


def topology(bus: model.Bus) -> tuple[nx.Graph, dict[Link, float]]:
    import networkx as nx

    graph: nx.Graph = nx.Graph()
    cables: dict[Link, float] = {}
    for sw in bus.switches:
        for port, to in sw.ports.items():
            graph.add_edge(sw.name, to)
            cables[(sw.name, to)] = cables[(to, sw.name)] = sw.cables_m.get(port, 0.0)
    if not bus.switches and len(bus.nodes) == 2:
        graph.add_edge(*bus.nodes)
    return graph, cables


def routes(graph: nx.Graph, msg: model.Message) -> dict[str, tuple[Link, ...]]:
    import networkx as nx

    out = {}
    for consumer in msg.consumers:
        path = nx.shortest_path(graph, msg.producer, consumer)
        out[consumer] = tuple(pairwise(path))
    return out


@dataclass(frozen=True)
class QueueAt:
    """Whose transmit queue sends on a link, and how many frames it holds."""

    depth: int
    switch: model.Switch | None  # None: the sending node's NIC
    port: int | None = None  # None at a switch: a port the spec does not list


def queue_depths(bus: model.Bus, nodes: dict[str, model.Node]) -> dict[Link, QueueAt]:
    """Each link's transmit queue: a switch port's for the link it sends on, else the sending node's NIC."""
    out: dict[Link, QueueAt] = {}
    switches = {sw.name: sw for sw in bus.switches}
    for sw in bus.switches:
        for port, to in sw.ports.items():
            out[(sw.name, to)] = QueueAt(sw.queues.get(port, QUEUE_FRAMES), sw, port)
    for sw in bus.switches:
        for to in sw.ports.values():
            if to in switches:  # a cable between switches listed at this end only: the other's unlisted port
                out.setdefault((to, sw.name), QueueAt(switches[to].queue, switches[to]))
            else:
                out[(to, sw.name)] = QueueAt(nodes[to].nic_queue, None)
    if not bus.switches and len(bus.nodes) == 2:
        a, b = bus.nodes
        out[(a, b)], out[(b, a)] = QueueAt(nodes[a].nic_queue, None), QueueAt(nodes[b].nic_queue, None)
    return out


def propagation_ns(cable_m: float) -> int:
    """Tprop of one cable, rounded to the nanosecond (per hop, as the simulator does too)."""
    return round(cable_m / PROPAGATION_M_PER_S * 1e9)


def min_frame_ns(bitrate: int) -> int:
    """The shortest frame on the wire (84 bytes): an empty datagram."""
    return udp_frame_ns(0, bitrate)


def max_min_frame_rate(bitrate: int) -> float:
    """f_max: frames per second of minimum size (84 bytes) one link can carry; 148.81 kHz at 100 Mbit/s."""
    return bitrate / (8 * udp_frame_bytes(0))


def analyse(
    bus: model.Bus, nodes: dict[str, model.Node], extra_jitter: dict[str, int] | None = None
) -> tuple[list[LinkLoad], list[PathDelay]]:
    """Links and path delays; `extra_jitter` adds release jitter to messages (a sending task's variation)."""
    extra = extra_jitter or {}
    graph, cables = topology(bus)
    switches = {s.name: s for s in bus.switches}
    frame_ns = {m.name: load.udp_timing(m, bus.bitrate).tx_ns for m in bus.messages}
    links: dict[Link, LinkLoad] = {}
    msg_routes = {m.name: routes(graph, m) for m in bus.messages}
    before: dict[tuple[str, Link], Link | None] = {}  # (message, link) -> the link it arrives over (None: its NIC)
    for msg in bus.messages:
        for hops in msg_routes[msg.name].values():
            for k, hop in enumerate(hops):
                before[(msg.name, hop)] = hops[k - 1] if k else None
        for hop in sorted(_hops(msg_routes[msg.name])):
            ll = links.setdefault(hop, LinkLoad(*hop))
            ll.messages.append(msg.name)
            ll.senders.add(msg.producer)
            rate = load.rate_hz(msg)
            ll.frames_per_s += rate
            ll.utilization += rate * frame_ns[msg.name] / 1e9
    period = {m.name: _shortest_period(m) for m in bus.messages}
    # arrival jitter of each message at each link of its route, grown with the upstream waits until stable
    jitter = {
        (m.name, hop): m.jitter_ns + extra.get(m.name, 0) for m in bus.messages for hop in _hops(msg_routes[m.name])
    }
    for _ in range(MAX_ROUNDS):
        for hop, ll in links.items():
            by_input: dict[Link | None, list[Flow]] = {}
            for n in ll.messages:
                by_input.setdefault(before[(n, hop)], []).append((frame_ns[n], period[n], jitter[(n, hop)]))
            ll.queue = fifo_queue([Input(k is not None, tuple(fs)) for k, fs in by_input.items()])
        grown = _jitters(bus.messages, msg_routes, links, frame_ns, extra)
        if grown is None or grown == jitter:
            break
        jitter = grown
    else:
        for ll in links.values():  # still growing: no bound
            ll.queue = None
    delays = []
    for msg in bus.messages:
        own = frame_ns[msg.name]
        for consumer, hops in msg_routes[msg.name].items():
            waits = [_wait(links[hop], own) for hop in hops]
            tswitch: int | None = None
            if all(w is not None for w in waits[1:]):  # every hop after the first leaves a switch's egress port
                tswitch = sum(switches[hop[0]].latency_ns + (w or 0) for hop, w in zip(hops[1:], waits[1:]))
            tprop = sum(propagation_ns(cables.get(h, 0.0)) for h in hops)
            delays.append(
                PathDelay(
                    message=msg.name,
                    consumer=consumer,
                    hops=hops,
                    tpre_ns=nodes[msg.producer].tx_delay_ns,
                    twait_ns=waits[0],
                    tframe_ns=own * len(hops),
                    tprop_ns=tprop,
                    tswitch_ns=tswitch,
                    tpost_ns=nodes[consumer].rx_delay_ns,
                )
            )
    return [links[k] for k in sorted(links)], delays


MAX_ROUNDS = 1_000  # rounds of the jitter propagation
MAX_STEPS = 20_000  # fixed-point steps of one busy period


def _hops(route: dict[str, tuple[Link, ...]]) -> set[Link]:
    return {hop for hops in route.values() for hop in hops}


def _shortest_period(m: model.Message) -> int | None:
    """The shortest time between two releases, in whole nanoseconds rounded down (a rate's exact period need not
    be whole), so that counting releases by it never counts too few."""
    if m.kind == "on-demand" or not m.interval_ns:
        return None
    exact = load.exact_rate(m)
    return min(m.interval_ns, int(Fraction(10**9) / exact)) if exact else m.interval_ns


def _wait(ll: LinkLoad, own_ns: int) -> int | None:
    return None if ll.queue is None else ll.queue.delay_ns - own_ns


def _jitters(
    messages: list[model.Message],
    msg_routes: dict[str, dict[str, tuple[Link, ...]]],
    links: dict[Link, LinkLoad],
    frame_ns: dict[str, int],
    extra: dict[str, int],
) -> dict[tuple[str, Link], int] | None:
    """Each message's jitter at each hop: its release jitter plus the worst waits on the hops before (None when
    some wait is unbounded)."""
    out: dict[tuple[str, Link], int] = {}
    for m in messages:
        for hops in msg_routes[m.name].values():
            late = m.jitter_ns + extra.get(m.name, 0)
            for hop in hops:
                out[(m.name, hop)] = max(out.get((m.name, hop), 0), late)
                wait = _wait(links[hop], frame_ns[m.name])
                if wait is None:
                    return None
                late += wait
    return out


def _count(a: int, t: int | None, j: int, closed: bool) -> int:
    """Frames of a flow (period t, jitter j) that can arrive in a window of length a: [0, a] or [0, a)."""
    if not t:
        return 1
    return (a + j) // t + 1 if closed else -(-(a + j) // t)


def _work(inputs: list[Input], a: int, closed: bool) -> int:
    """The most transmission time that can arrive in a window of length a."""
    total = 0
    for inp in inputs:
        w = sum(c * _count(a, t, j, closed) for c, t, j in inp.flows)
        total += min(w, a + max(c for c, _, _ in inp.flows)) if inp.serialised else w
    return total


def fifo_queue(inputs: list[Input]) -> Queue | None:
    """Busy period, delay and backlog bounds of a FIFO queue served at the link rate (times are frame times at
    that rate); None when the queue is overloaded (exactly: at 100 % a busy period can only end without jitter,
    which the step limit then finds too)."""
    flows = [f for inp in inputs for f in inp.flows]
    periodic = [(c, t) for c, t, _ in flows if t]
    if load.compare_to_capacity(sum(c / t for c, t in periodic), periodic) > 0:
        return None
    # the busy period: the first instant by which everything that arrived before it has been sent
    w = _work(inputs, 0, True)
    for _ in range(MAX_STEPS):
        nxt = _work(inputs, w, False)
        if nxt == w:
            break
        w = nxt
    else:
        return None
    busy = w
    # arrivals step up at the instants a = m T - J inside the busy period; between two of them the bounds are
    # piecewise linear, so their suprema lie at those instants, where a serialised input's linear limit meets its
    # flows' work (a = work - C_max), or where its frame-count limit steps (a = k C_min)
    steps = {0, busy}
    for _, t, j in flows:
        if t:
            steps.update(range(t - j % t if j % t else t, busy, t))
    at = sorted(steps)
    points = set(at)
    c_max = max(c for c, _, _ in flows)
    for inp in (i for i in inputs if i.serialised):
        longest = max(c for c, _, _ in inp.flows)
        shortest = min(c for c, _, _ in inp.flows)
        frames = sum(_count(busy, t, j, True) for _, t, j in inp.flows)
        points.update(k * shortest for k in range(1, min(frames, -(-busy // shortest))))
        for a in at:
            cross = sum(c * _count(a, t, j, True) for c, t, j in inp.flows) - longest
            if a < cross < busy:
                points.add(cross)
    c_min = min(c for c, _, _ in flows)
    delay = backlog = 0
    # frames there at a: at most the arrivals minus those sent (non-increasing between two points), and at most
    # the one being sent plus the frames the work still queued can hold (largest at one end of the interval)
    order = sorted(points)
    counts = []
    for a in order:
        queued = _work(inputs, a, True) - a
        delay = max(delay, queued)
        counts.append((_frames(inputs, a) - a // c_max, 1 + max(queued, 0) // c_min))
    for (by_frames, by_work), after in zip(counts, [*counts[1:], counts[-1]]):
        backlog = max(backlog, min(by_frames, max(by_work, after[1])))
    return Queue(busy, delay, backlog)


def _frames(inputs: list[Input], a: int) -> int:
    """The most frames that can arrive in [0, a]."""
    total = 0
    for inp in inputs:
        n = sum(_count(a, t, j, True) for _, t, j in inp.flows)
        total += min(n, a // min(c for c, _, _ in inp.flows) + 1) if inp.serialised else n
    return total
