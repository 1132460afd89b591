"""Switched full-duplex Ethernet/UDP (seed 001, section 6.2.2.7).

Every cable is two independent links, one per direction. A message crosses the links on the tree path from
its producer to each consumer (a switch forwards a multicast once per egress port). Per link: frames per
second, utilisation, and the paper's rule f_transm < f_max / n, generalised to frames of any size as
sum(f_i * Tframe_i) < 1 (with n equal minimum-size frames it is exactly n * f_transm < f_max).

Delay budget, eq. 6.3:  Tdelay = Tpre + Twait + Tframe + Tprop + Tswitch + Tpost. With store-and-forward
switches the frame is serialised again on every hop, so Tframe counts once per link; Tswitch = Tmux + Tqueue,
and Tqueue on a FIFO egress port is bounded by the port's level busy period: the frames of every flow on that
port that can arrive together, w = sum_i ceil((w + J_i) / T_i) * C_i, minus the frame's own transmission.
J_i is flow i's arrival jitter at that port: its release jitter plus the queueing it may meet on the hops
before (0 at best, the wait bound at worst), so frames bunched by an upstream switch count as they arrive
(holistic analysis, Tindell and Clark 1994). Waits and jitters depend on each other; they are iterated from
zero jitter until nothing changes (they only grow), at most MAX_ROUNDS times.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import pairwise
from typing import TYPE_CHECKING

from netcfg.timing import load
from netcfg.timing.frames import udp_frame_bytes, udp_frame_ns

if TYPE_CHECKING:
    import networkx as nx

    from netcfg import model

PROPAGATION_M_PER_S = 0.7 * 299_792_458  # velocity factor 0.7 (seed 001: 0.4-0.7, 2.1e8 m/s)
# Frames a NIC's or switch port's transmit queue holds, counting the one being sent, when the spec does not say
# (nodes' nic_queue, switches' and ports' queue); the simulator drops a frame that finds its queue full. An
# assumption, not a datasheet figure: small unmanaged switches share a packet memory of a few tens of kilobytes
# among their ports, and 64 frames per port is of that order for minimum-size frames.
QUEUE_FRAMES = 64
Link = tuple[str, str]


@dataclass
class LinkLoad:
    src: str
    dst: str
    messages: list[str] = field(default_factory=list)
    frames_per_s: float = 0.0
    utilization: float = 0.0
    busy_period_ns: int | None = 0
    senders: set[str] = field(default_factory=set)


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
    for msg in bus.messages:
        used = {hop for hops in msg_routes[msg.name].values() for hop in hops}
        for hop in sorted(used):
            ll = links.setdefault(hop, LinkLoad(*hop))
            ll.messages.append(msg.name)
            ll.senders.add(msg.producer)
            rate = load.rate_hz(msg)
            ll.frames_per_s += rate
            ll.utilization += rate * frame_ns[msg.name] / 1e9
    by_name = {m.name: m for m in bus.messages}
    # arrival jitter of each message at each link of its route, grown with the upstream waits until stable
    jitter = {
        (m.name, hop): m.jitter_ns + extra.get(m.name, 0) for m in bus.messages for hop in _hops(msg_routes[m.name])
    }
    for _ in range(MAX_ROUNDS):
        for hop, ll in links.items():
            ll.busy_period_ns = fifo_busy_period(
                [(frame_ns[n], by_name[n].interval_ns, jitter[(n, hop)]) for n in ll.messages]
            )
        grown = _jitters(bus.messages, msg_routes, links, frame_ns, extra)
        if grown is None or grown == jitter:
            break
        jitter = grown
    else:
        for ll in links.values():  # still growing: no bound
            ll.busy_period_ns = None
    delays = []
    for msg in bus.messages:
        own = frame_ns[msg.name]
        for consumer, hops in msg_routes[msg.name].items():
            queues = [links[hop].busy_period_ns for hop in hops]
            waits = [None if q is None else q - own for q in queues]
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
                busy = links[hop].busy_period_ns
                if busy is None:
                    return None
                late += busy - frame_ns[m.name]
    return out


def fifo_busy_period(flows: list[tuple[int, int | None, int]]) -> int | None:
    """Longest busy period of a FIFO port fed by flows (C, T, J); None when the port is overloaded (exactly: at
    100 % a busy period can only end without jitter, which the step limit then finds too)."""
    periodic = [(c, t, j) for c, t, j in flows if t]
    if load.compare_to_capacity(sum(c / t for c, t, _ in periodic), [(c, t) for c, t, _ in periodic]) > 0:
        return None
    w = sum(c for c, _, _ in flows)
    for _ in range(MAX_STEPS):
        nxt = sum(c * -(-(w + j) // t) for c, t, j in periodic) + sum(c for c, t, _ in flows if not t)
        if nxt == w:
            return w
        w = nxt
    return None
