"""Switched full-duplex Ethernet/UDP (seed 001, section 6.2.2.7).

Every cable is two independent links, one per direction. A message crosses the links on the tree path from
its producer to each consumer (a switch forwards a multicast once per egress port). Per link: frames per
second, utilisation, and the paper's rule f_transm < f_max / n, generalised to frames of any size as
sum(f_i * Tframe_i) < 1 (with n equal minimum-size frames it is exactly n * f_transm < f_max).

Delay budget, eq. 6.3:  Tdelay = Tpre + Twait + Tframe + Tprop + Tswitch + Tpost. With store-and-forward
switches the frame is serialised again on every hop, so Tframe counts once per link; Tswitch = Tmux + Tqueue,
and Tqueue on a FIFO egress port is bounded by the port's level busy period: the frames of every flow on that
port that can arrive together, w = sum_i ceil(w / T_i) * C_i, minus the frame's own transmission.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import pairwise
from typing import TYPE_CHECKING

from netcfg import model
from netcfg.timing import load
from netcfg.timing.frames import udp_frame_bytes, udp_frame_ns

if TYPE_CHECKING:
    import networkx as nx

PROPAGATION_M_PER_S = 0.7 * 299_792_458  # velocity factor 0.7 (seed 001: 0.4-0.7, 2.1e8 m/s)
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


def analyse(bus: model.Bus, nodes: dict[str, model.Node]) -> tuple[list[LinkLoad], list[PathDelay]]:
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
    for ll in links.values():
        ll.busy_period_ns = fifo_busy_period([(frame_ns[n], by_name[n].interval_ns) for n in ll.messages])
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


def fifo_busy_period(flows: list[tuple[int, int | None]]) -> int | None:
    """Longest busy period of a FIFO port fed by flows (C, T); None when the port is overloaded."""
    periodic = [(c, t) for c, t in flows if t]
    if sum(c / t for c, t in periodic) >= 1:
        return None
    w = sum(c for c, _ in flows)
    while True:
        nxt = sum(c * -(-w // t) for c, t in periodic) + sum(c for c, t in flows if not t)
        if nxt == w:
            return w
        w = nxt
