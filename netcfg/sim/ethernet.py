"""Switched full-duplex Ethernet/UDP, frame by frame, with the model netcfg.timing.ethernet analyses.

Every cable is two links, one per direction, each with its own FIFO transmitter at the bus bitrate. A frame of a
message with `size` data bytes carries the 1-byte application message id too (seed 001, Table 6.1), so it takes
udp_message_ns(size) on every link, padded to the 84-byte minimum (seed 001, eq. 6.4). Along its tree path the
frame is: released on its producer's drifting clock, handed to the NIC after the node's tx_delay (Tpre), queued
FIFO on the node's link, received completely by the switch (store and forward) after the cable's propagation time,
queued after the switch's latency (Tmux) on each egress port it leaves by (a multicast once per port), and
delivered to a consumer rx_delay (Tpost) after it has been received completely there. A receiving node may also
consume frames one after another (a FIFO server whose service time lies between a BCET and a WCET), which gives a
separate "processed" latency; flows and message-activated tasks see the delivery, as the analysis does.

Egress queues are finite (`queue_frames`, counting the frame being sent): a frame that finds its port full is
dropped (tail drop) and counted per port and per message. Seed 001 (section 6.2.2.5) warns of exactly this: "the
port's buffer may overflow and lead to unexpected delays or data loss".

Speed: free-running traffic does not depend on the rest of the simulation, so the links that carry only such
traffic (and are fed only by such links) are computed a chunk of simulated time at a time with numpy: releases are
generated per chunk, and each of these links, in path order, serves every frame that reaches it before the chunk's
end (Lindley's recursion, vectorised when nothing is dropped). A frame released later cannot reach any port earlier
than that, so those results are final. Only deliveries that someone listens to (a flow, a message-activated task)
become events. The cabling is taken to be a tree, as a switched Ethernet without spanning tree must be; paths are
its tree paths, as in the analysis.

Chained messages (sent by a flow task as it finishes, Scenario.sends) are not known ahead: submit() hands one to
the NIC at the current instant. A chunk computed ahead on a link such a frame crosses could be wrong (the frame
would have to be served before frames already served after it), so those links, and every link downstream of
them, run frame by frame in arrival order instead ("event links"). They are still served lazily: a link serves
its waiting frames up to a horizon before which every arrival is known, which is now for a NIC that takes chained
frames, the chunk's end for a free-running link, and for a switch port the least, over the links feeding it, of
their horizon plus the shortest frame time, cable and switch latency from them (a frame not yet known there
reaches the port no sooner). Serving happens on each submit (along the submitted frame's links) and at wake-ups
set just before the earliest instant a waiting frame could matter (a listened delivery), so nothing is served too
late and a link never serves a frame before one that arrives earlier.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from heapq import heappop, heappush
from itertools import pairwise
from typing import TYPE_CHECKING, Any

import numpy as np

from netcfg.runtime import Bus, Message
from netcfg.sim.engine import LATE, NEVER
from netcfg.sim.stats import stats_us
from netcfg.sim.streams import PeriodicStreams
from netcfg.timing import load
from netcfg.timing.ethernet import propagation_ns
from netcfg.timing.frames import udp_message_ns

if TYPE_CHECKING:
    from netcfg.runtime import Task
    from netcfg.sim.flows import FlowTracker
    from netcfg.sim.run import SimRun

# Egress buffer per port, in frames: an assumption, not a datasheet figure. Small unmanaged switches share a packet
# memory of a few tens of kilobytes among their ports; 64 frames per port is of that order for minimum-size frames.
# Override with queue_frames= (or SimOptions.eth_queue_frames).
QUEUE_FRAMES = 64
CHUNK_NS = 5_000_000  # simulated time computed at once; frames fare the same for any value (random draws for
# jitter may come in another order)

_I64 = np.int64
_EMPTY = np.empty(0, dtype=_I64)
Batch = tuple[np.ndarray, np.ndarray, np.ndarray]  # (arrival at the stage, message index, release), aligned
Waiting = tuple[int, int, int, int]  # a frame at an event link: (arrival, sequence number, message index, release)
Listen = tuple[list["FlowTracker"], list["Task"]]
Due = tuple[int, int, int]  # a waiting frame something observes: (latest instant to serve it by + 1, arrival, seq)


@dataclass
class _Link:
    """One direction of one cable with its transmitter and egress queue."""

    index: int
    src: str
    dst: str
    prop_ns: int
    latency_ns: int  # the switch at the far end (Tmux) before the next egress queue; 0 at a node
    crash_ns: int  # the sending node crashed: nothing starts from then on (NEVER for a switch)
    busy_until: int = 0
    frames: int = 0
    busy_ns: int = 0
    max_queue: int = 0
    lost: int = 0
    offered: float = 0.0  # sum of rate x frame time over the messages crossing it: the analysis' utilisation
    # free-running links (numpy, a chunk at a time)
    pending: list[Batch] = field(default_factory=list)
    tail: np.ndarray = field(default_factory=lambda: _EMPTY)  # ends of the frames that may still be at the port
    # event links (frame by frame, see the module's docstring)
    event: bool = False
    takes_chained: bool = False  # a NIC that chained frames enter at the current instant
    waiting: list[Waiting] = field(default_factory=list)  # a heap, in arrival order (then in order of arrival known)
    due: list[Due] = field(default_factory=list)  # a heap of the waiting frames that something observes
    fresh: list[Due] = field(default_factory=list)  # the same, arrived since the link was last served
    route: list[Any] = field(default_factory=list)  # per message: (next links, delivery here), see _build_event_links
    ends: deque[int] = field(default_factory=deque)  # ends of the frames that may still be at the port
    feeders: list[tuple[_Link, int]] = field(default_factory=list)  # (link, least delay from its end to here)
    served: int = -1  # every frame arriving here at or before this instant has been served


@dataclass
class _Server:
    """A receiving node consuming frames one after another (FIFO, service drawn between BCET and WCET)."""

    node: str
    bcet: np.ndarray  # per message index
    wcet: np.ndarray
    batches: list[Batch] = field(default_factory=list)  # deliveries (end, message, release), served after the run
    ends: list[int] = field(default_factory=list)  # the same, delivered one by one
    msgs: list[int] = field(default_factory=list)
    rels: list[int] = field(default_factory=list)
    busy_ns: int = 0


class EthernetNetwork:
    def __init__(
        self,
        sc: SimRun,
        bus: Bus,
        *,
        queue_frames: int | None = None,
        processing_ns: Mapping[str, tuple[int, int]] | None = None,
    ) -> None:
        """queue_frames, processing_ns: default to the options' eth_queue_frames and eth_processing_ns. processing:
        node -> (BCET, WCET) of consuming one frame; by default a node's on_message task for that message, else 0
        (no server)."""
        self.sc = sc
        self.bus = bus
        self.sim = sc.sim
        self.duration = sc.opts.duration_ns
        q = queue_frames if queue_frames is not None else sc.opts.eth_queue_frames
        self.queue_frames = QUEUE_FRAMES if q is None else int(q)
        if self.queue_frames < 1:
            raise ValueError(f"bus '{bus.name}': an egress queue must hold at least one frame")
        processing = processing_ns if processing_ns is not None else sc.opts.eth_processing_ns or {}
        self.messages: list[Message] = list(sc.cfg.messages_on(bus.name))
        self.index = {m.name: i for i, m in enumerate(self.messages)}
        self.owned = set(self.index)
        chained = {name for names in sc.sends.values() for name in names}
        self.chained = {i for i, m in enumerate(self.messages) if m.name in chained}
        self.frame_ns = np.array([udp_message_ns(m.size, bus.bitrate) for m in self.messages], dtype=_I64)
        self._frame = self.frame_ns.tolist()
        nodes = {n.name: n for n in sc.cfg.nodes}
        self.rx_delay = {n: nodes[n].rx_delay_ns for n in bus.nodes if n in nodes}
        self.tx_delay = {n: nodes[n].tx_delay_ns for n in bus.nodes if n in nodes}
        self._build_topology(bus)
        self._build_routes()
        self._build_sources()
        self._build_servers(nodes, processing)
        self._build_listeners()
        self._build_event_links()
        n = len(self.messages)
        self.sent = np.zeros(n, dtype=_I64)
        self.lost = np.zeros(n, dtype=_I64)  # deliveries that will never happen (a copy per consumer)
        self._lose: dict[int, list[int]] = {}  # message -> instants: the next frame queued at or after is lost
        self._rel: list[list[np.ndarray]] = [[] for _ in range(n)]  # deliveries, a batch at a time
        self._end: list[list[np.ndarray]] = [[] for _ in range(n)]
        self._rel1: list[list[int]] = [[] for _ in range(n)]  # deliveries, one at a time
        self._end1: list[list[int]] = [[] for _ in range(n)]
        self._proc_rel: list[list[np.ndarray]] = [[] for _ in range(n)]  # consumed by the receiving node
        self._proc_end: list[list[np.ndarray]] = [[] for _ in range(n)]
        self._proc_rel1: list[list[int]] = [[] for _ in range(n)]
        self._proc_end1: list[list[int]] = [[] for _ in range(n)]
        self._known = -1  # free-running releases are generated up to this instant
        self._seq = 0
        self._wakes: list[int] = []  # instants of the wake-ups set
        self._finished = False
        self._build_routes_by_link()
        # chained message -> (first link or None, producer's crash, tx_delay, need at the first link or -1, links)
        self._chained_how: dict[int, tuple[_Link | None, int, int, int, list[_Link]]] = {}
        for i in self.chained:
            m, link = self.messages[i], self.first.get(i)
            self._chained_how[i] = (
                link,
                self.sc.crash_at.get(m.producer, NEVER),
                self.tx_delay.get(m.producer, 0),
                -1 if link is None else self.need.get((i, link.index), -1),
                [] if link is None else self._below[link.index],
            )

    # -- set-up -----------------------------------------------------------------------------------------------
    def _build_topology(self, bus: Bus) -> None:
        self.switch_latency: dict[str, int] = {}
        cables: dict[tuple[str, str], float] = {}
        adj: dict[str, list[str]] = {}

        def edge(a: str, b: str, metres: float) -> None:
            for x, y in ((a, b), (b, a)):
                if y not in adj.setdefault(x, []):
                    adj[x].append(y)
                cables[(x, y)] = metres

        switches = bus.ethernet.switches if bus.ethernet else ()
        for sw in switches:
            self.switch_latency[sw.name] = sw.latency_ns
            for port in sw.ports:
                edge(sw.name, port.to, port.cable_m)
        if not switches and len(bus.nodes) == 2:
            edge(bus.nodes[0], bus.nodes[1], 0.0)
        self.adj = adj
        self.cables = cables
        self.links: dict[tuple[str, str], _Link] = {}

    def _link(self, a: str, b: str) -> _Link:
        link = self.links.get((a, b))
        if link is None:
            prop = propagation_ns(self.cables.get((a, b), 0.0))  # per hop, as the analysis' Tprop
            crash = NEVER if a in self.switch_latency else self.sc.crash_at.get(a, NEVER)
            latency = self.switch_latency.get(b, 0)
            link = self.links[(a, b)] = _Link(len(self.links), a, b, prop, latency, crash)
        return link

    def _path(self, src: str, dst: str) -> list[str]:
        prev: dict[str, str | None] = {src: None}
        todo = deque([src])
        while todo:
            x = todo.popleft()
            if x == dst:
                break
            for y in self.adj.get(x, ()):
                if y not in prev:
                    prev[y] = x
                    todo.append(y)
        if dst not in prev:
            raise ValueError(f"bus '{self.bus.name}': no cable path from '{src}' to '{dst}'")
        path = [dst]
        while (p := prev[path[-1]]) is not None:
            path.append(p)
        return path[::-1]

    def _build_routes(self) -> None:
        """Per message, the tree of links its frames cross: first link, children of each link, consumers reached."""
        self.first: dict[int, _Link] = {}
        self.children: dict[tuple[int, int], list[_Link]] = {}  # (message, link) -> next links
        self.deliver_to: dict[tuple[int, int], str] = {}  # (message, link) -> consumer at the link's end
        self.downstream: dict[tuple[int, int], int] = {}  # (message, link) -> consumers reached through it
        for i, m in enumerate(self.messages):
            for consumer in m.consumers:
                if consumer == m.producer:
                    continue
                hops = self._path(m.producer, consumer)
                links = [self._link(a, b) for a, b in pairwise(hops)]
                self.first[i] = links[0]
                for a, b in pairwise(links):
                    kids = self.children.setdefault((i, a.index), [])
                    if b not in kids:
                        kids.append(b)
                for lk in links:
                    self.downstream[(i, lk.index)] = self.downstream.get((i, lk.index), 0) + 1
                self.deliver_to[(i, links[-1].index)] = consumer
            rate = load.rate_hz(m)
            for lk in self.links.values():
                if (i, lk.index) in self.downstream:
                    lk.offered += rate * int(self.frame_ns[i]) / 1e9
        self.order = self._topological()

    def _topological(self) -> list[_Link]:
        """Links in an order where every link comes after those that feed it (a tree has no cycle of them)."""
        feeds: dict[int, set[int]] = {lk.index: set() for lk in self.links.values()}
        for (_, a), kids in self.children.items():
            for b in kids:
                feeds[b.index].add(a)
        by_index = {lk.index: lk for lk in self.links.values()}
        done: list[_Link] = []
        seen: set[int] = set()
        while len(done) < len(by_index):
            ready = [i for i in sorted(feeds) if i not in seen and feeds[i] <= seen]
            if not ready:
                raise ValueError(f"bus '{self.bus.name}': the cabling has a loop; switched Ethernet needs a tree")
            for i in ready:
                seen.add(i)
                done.append(by_index[i])
        return done

    def _build_sources(self) -> None:
        """The free-running senders' releases (netcfg.sim.streams), at the exact period of a rate the spec gave.
        Release jitter takes one random draw per release of a jittered message: those have a stream of their
        own (a stream draws for all its sources once one has jitter)."""
        free = []
        for i, m in enumerate(self.messages):
            if m.kind not in ("periodic", "sporadic") or not m.interval_ns or i not in self.first:
                continue  # on-demand traffic is not part of the steady state (as in the analysis)
            if i in self.chained:
                continue  # sent by its task as it finishes (submit)
            free.append(i)
        jittered = [i for i in free if self.messages[i].jitter_ns]
        steady = [i for i in free if not self.messages[i].jitter_ns]
        self.streams: list[PeriodicStreams] = []
        for group in (jittered, steady):
            if not group:
                continue
            msgs = [self.messages[i] for i in group]
            clocks = [self.sc.clock[m.producer] for m in msgs]
            rates = [load.exact_rate(m) for m in msgs]
            self.streams.append(
                PeriodicStreams(
                    sources=group,
                    periods=[Fraction(10**9) / r if r else m.interval_ns or 0 for m, r in zip(msgs, rates)],
                    offsets=[m.offset_ns or 0 for m in msgs],
                    phases=[c.phase_ns for c in clocks],
                    drifts_ppb=[c.drift_ppb for c in clocks],
                    jitters=[m.jitter_ns for m in msgs],
                    until=[self.sc.crash_at.get(m.producer, NEVER) for m in msgs],
                    rng=self.sc.rng,
                )
            )
        self._free = free  # message indices, ascending
        self._free_edges = np.array([*free, len(self.messages)], dtype=_I64)  # where each one's releases start
        self._tx_ns = [self.tx_delay.get(m.producer, 0) for m in self.messages]
        self._jitter_max = max((self.messages[i].jitter_ns for i in free), default=0)

    def _build_servers(self, nodes: Mapping[str, Any], processing: Mapping[str, tuple[int, int]]) -> None:
        n = len(self.messages)
        self.servers: dict[str, _Server] = {}
        for node in self.bus.nodes:
            if node not in nodes:
                continue
            bcet, wcet = np.zeros(n, dtype=_I64), np.zeros(n, dtype=_I64)
            for i, m in enumerate(self.messages):
                if node not in m.consumers:
                    continue
                if node in processing:
                    bcet[i], wcet[i] = processing[node]
                else:
                    tasks = [t for t in nodes[node].tasks if t.on_message == m.name]
                    if tasks:
                        bcet[i], wcet[i] = min(t.bcet_ns for t in tasks), max(t.wcet_ns for t in tasks)
            if (wcet < bcet).any() or (bcet < 0).any():
                raise ValueError(f"node '{node}': processing times must satisfy 0 <= BCET <= WCET")
            if wcet.any():
                self.servers[node] = _Server(node, bcet, wcet)

    def _build_listeners(self) -> None:
        sc = self.sc
        self.listeners: dict[tuple[int, str], Listen] = {}
        for i, m in enumerate(self.messages):
            trackers = sc.trackers_of(m.name)
            for consumer in m.consumers:
                tasks = [t for t in sc.tasks_on_message(m.name) if t.node == consumer]
                if trackers or tasks:
                    self.listeners[(i, consumer)] = (trackers, tasks)

    def _build_event_links(self) -> None:
        """Which links run frame by frame: those chained frames cross, and every link downstream of them."""
        kids: dict[int, set[int]] = {}
        for (_, a), bs in self.children.items():
            kids.setdefault(a, set()).update(b.index for b in bs)
        event = {a for (i, a) in self.downstream if i in self.chained}
        for link in self.order:  # feeders first, so one pass closes the set
            if link.index in event:
                event |= kids.get(link.index, set())
        for link in self.order:
            link.event = link.index in event
        for i in self.chained:
            if i in self.first:
                self.first[i].takes_chained = True
        self.free_order = [lk for lk in self.order if not lk.event]
        self.event_order = [lk for lk in self.order if lk.event]
        by_index = {lk.index: lk for lk in self.order}
        slack: dict[tuple[int, int], int] = {}  # (feeder, link) -> least delay from the feeder's arrival to here
        for (i, a), bs in self.children.items():
            feeder = by_index[a]
            d = self._frame[i] + feeder.prop_ns + feeder.latency_ns
            for b in bs:
                slack[(a, b.index)] = min(d, slack.get((a, b.index), NEVER))
        for link in self.event_order:
            link.feeders = [(by_index[a], d) for (a, b), d in sorted(slack.items()) if b == link.index]
        # below[link]: the event links a frame entering this link can reach, in order (served on a submit)
        self._below: dict[int, list[_Link]] = {}
        for link in self.event_order:
            reach = {link.index}
            for lk in self.event_order:
                if lk.index in reach:
                    reach |= kids.get(lk.index, set())
            self._below[link.index] = [lk for lk in self.event_order if lk.index in reach]
        # need[(message, link)]: least time from a frame's arrival at the link to the first instant something
        # observes it (a listened delivery); absent when nothing ever does (its results are needed at the end only)
        self.need: dict[tuple[int, int], int] = {}
        for link in reversed(self.order):
            for i in range(len(self.messages)):
                key = (i, link.index)
                if key not in self.downstream:
                    continue
                out = self._frame[i] + link.prop_ns
                best = NEVER
                consumer = self.deliver_to.get(key)
                if consumer is not None and (i, consumer) in self.listeners:
                    best = out + self.rx_delay.get(consumer, 0)
                for child in self.children.get(key, ()):
                    after = self.need.get((i, child.index))
                    if after is not None:
                        best = min(best, out + link.latency_ns + after)
                if best < NEVER:
                    self.need[key] = best

    def _build_routes_by_link(self) -> None:
        """Per event link and message: ((next link, its need or -1), ...) and what a delivery here needs, so that
        serving a frame looks nothing up by name."""
        for link in self.event_order:
            link.route = [((), None)] * len(self.messages)
            for i, m in enumerate(self.messages):
                key = (i, link.index)
                if key not in self.downstream:
                    continue
                kids = tuple((c, self.need.get((i, c.index), -1)) for c in self.children.get(key, ()))
                dest = None
                consumer = self.deliver_to.get(key)
                if consumer is not None:
                    dest = (
                        self.rx_delay.get(consumer, 0),
                        self.sc.crash_at.get(consumer, NEVER),
                        self._rel1[i],
                        self._end1[i],
                        self.servers.get(consumer),
                        self._proc_rel1[i],
                        self._proc_end1[i],
                        self.listeners.get((i, consumer)),
                        m.name,
                    )
                link.route[i] = (kids, dest)

    def lose_at(self, name: str, at_ns: int) -> None:
        """A scripted loss (fault lose:MESSAGE@T): the first frame of the message queued at or after at_ns."""
        self._lose.setdefault(self.index[name], []).append(at_ns)

    # -- running ----------------------------------------------------------------------------------------------
    def start(self) -> None:
        if self.duration > 0:
            self.sim.at(0, self._chunk, 0)

    def _chunk(self, t0: int) -> None:
        t1 = min(t0 + CHUNK_NS, self.duration)
        self._release(t0, t1)
        for link in self.free_order:
            batch = _take(link.pending, t1)
            if batch is not None:
                self._transmit(link, *batch)
            link.served = t1 - 1
        self._known = t1 - 1
        if self.event_order:
            self._advance(self.event_order)
        if t1 < self.duration:
            self.sim.at(t1, self._chunk, t1)

    def _release(self, t0: int, t1: int) -> None:
        """Free-running releases whose nominal instant falls in [t0, t1), message by message, to their first links
        tx_delay later (Tpre)."""
        if len(self.streams) == 1:
            rel, msg = self.streams[0](t0, t1)
        elif self.streams:
            parts = [stream(t0, t1) for stream in self.streams]
            rel = np.concatenate([p[0] for p in parts])
            msg = np.concatenate([p[1] for p in parts])
            order = np.argsort(msg, kind="stable")  # back in message order, each message's still in time order
            rel, msg = rel[order], msg[order]
        else:
            return
        edges = np.searchsorted(msg, self._free_edges).tolist()
        whole = t1 + self._jitter_max <= self.duration  # no release of this chunk falls after the run
        for i, lo, hi in zip(self._free, edges, edges[1:]):
            if lo == hi:
                continue
            r = rel[lo:hi]
            self.sent[i] += hi - lo if whole else int((r < self.duration).sum())
            a = r + self._tx_ns[i]
            if i in self._lose:
                keep = self._scripted_losses(i, a)
                a, r = a[keep], r[keep]
            self._enqueue(self.first[i], a, np.full(len(a), i, dtype=_I64), r)

    def _scripted_losses(self, i: int, arrive: np.ndarray) -> np.ndarray:
        """Which of these frames escape the scripted losses: each instant takes the first frame queued at or after
        it (counted as lost for every consumer); an instant no frame has reached yet waits for later ones."""
        keep = np.ones(len(arrive), dtype=bool)
        left = []
        for t in sorted(self._lose[i]):
            hit = np.flatnonzero(keep & (arrive >= t))
            if len(hit):
                keep[hit[np.argmin(arrive[hit])]] = False
                self.lost[i] += self.downstream[(i, self.first[i].index)]
            else:
                left.append(t)
        self._lose[i] = left
        return keep

    def _enqueue(self, link: _Link, t: np.ndarray, msg: np.ndarray, rel: np.ndarray) -> None:
        """Frames computed a chunk at a time reaching a link: a batch for a free-running link, else one by one."""
        if not link.event:
            link.pending.append((t, msg, rel))
            return
        waiting, fresh, seq, li = link.waiting, link.fresh, self._seq, link.index
        need = self.need
        for a, i, r in zip(t.tolist(), msg.tolist(), rel.tolist()):
            seq += 1
            heappush(waiting, (a, seq, i, r))
            off = need.get((i, li))
            if off is not None:
                fresh.append((a + off, a, seq))
        self._seq = seq

    def _transmit(self, link: _Link, t: np.ndarray, msg: np.ndarray, rel: np.ndarray) -> None:
        """Serve the frames reaching the link's FIFO (sorted by arrival), then pass them on."""
        c = self.frame_ns[msg]
        cum = np.cumsum(c)
        end = cum + np.maximum(np.maximum.accumulate(t - (cum - c)), link.busy_until)
        keep = len(t)
        if link.crash_ns < NEVER:  # a suffix: start times only grow
            keep = int(np.searchsorted(end - c, link.crash_ns, side="left"))
        # frames at the port when frame i arrives: earlier ones of this batch and of earlier ones not yet sent
        held = len(link.tail) - np.searchsorted(link.tail, t[:keep], side="right")
        queue = np.arange(keep) - np.searchsorted(end[:keep], t[:keep], side="right") + held
        if keep and int(queue.max()) >= self.queue_frames:
            ok, end = self._transmit_lossy(link, t, c)
            gone = np.ones(len(t), dtype=bool)
            gone[ok] = False
            self._count_lost(link, msg[gone])
            msg, rel, c = msg[ok], rel[ok], c[ok]
        else:
            if keep < len(t):
                self._count_lost(link, msg[keep:])
            msg, rel, end, c = msg[:keep], rel[:keep], end[:keep], c[:keep]
            if keep:
                link.max_queue = max(link.max_queue, int(queue.max()) + 1)
        if not len(end):
            return
        link.busy_until = int(end[-1])
        link.tail = np.concatenate([link.tail, end])[-self.queue_frames :]
        start = end - c
        d = self.duration
        link.frames += int((start < d).sum())
        link.busy_ns += int((np.minimum(end, d) - np.minimum(start, d)).sum())
        self._forward(link, end + link.prop_ns, msg, rel)

    def _transmit_lossy(self, link: _Link, t: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lindley's recursion frame by frame with tail drop at a full port: -> (accepted indices, their ends).

        Only the last queue_frames ends can still be at the port later (a frame is accepted only when fewer are),
        so link.tail keeps just those."""
        ends = deque(link.tail.tolist())
        busy, cap, crash = link.busy_until, self.queue_frames, link.crash_ns
        accepted: list[int] = []
        out: list[int] = []
        qmax = link.max_queue
        for i, (a, ci) in enumerate(zip(t.tolist(), c.tolist())):
            while ends and ends[0] <= a:
                ends.popleft()
            if len(ends) >= cap:
                continue
            s = a if a > busy else busy
            if s >= crash:
                continue
            busy = s + ci
            ends.append(busy)
            qmax = max(qmax, len(ends))
            accepted.append(i)
            out.append(busy)
        link.max_queue = qmax
        return np.asarray(accepted, dtype=_I64), np.asarray(out, dtype=_I64)

    def _count_lost(self, link: _Link, msg: np.ndarray) -> None:
        link.lost += len(msg)
        for i, n in zip(*np.unique(msg, return_counts=True)):
            self.lost[i] += int(n) * self.downstream[(int(i), link.index)]

    def _forward(self, link: _Link, recv: np.ndarray, msg: np.ndarray, rel: np.ndarray) -> None:
        """Frames completely received at the link's far end: on to the next links, or delivered."""
        for i in np.unique(msg).tolist():
            sel = msg == i
            r, e, mm = rel[sel], recv[sel], msg[sel]
            for child in self.children.get((i, link.index), ()):
                self._enqueue(child, e + link.latency_ns, mm, r)
            consumer = self.deliver_to.get((i, link.index))
            if consumer is not None:
                self._deliver(i, consumer, r, e + self.rx_delay.get(consumer, 0))

    def _deliver(self, i: int, consumer: str, rel: np.ndarray, end: np.ndarray) -> None:
        crash = self.sc.crash_at.get(consumer, NEVER)
        if crash < self.duration:  # a crashed consumer receives nothing more
            dead = end >= crash
            self.lost[i] += int(dead.sum())
            rel, end = rel[~dead], end[~dead]
        self._rel[i].append(rel)
        self._end[i].append(end)
        server = self.servers.get(consumer)
        if server is not None:
            server.batches.append((end, np.full(len(end), i, dtype=_I64), rel))
        else:  # nothing to wait for: consumed as it arrives
            self._proc_rel[i].append(rel)
            self._proc_end[i].append(end)
        listen = self.listeners.get((i, consumer))
        if listen is not None:
            name = self.messages[i].name
            at = self.sim.at
            for r, e in zip(rel.tolist(), end.tolist()):
                if e < self.duration:
                    at(e, self._delivered, (name, r, e, listen))

    def _delivered(self, arg: tuple[str, int, int, Listen]) -> None:
        name, release, end, (trackers, tasks) = arg
        for tr in trackers:
            tr.message_delivered(name, release, end)
        for task in tasks:
            self.sc.run_task(task, end)

    # -- event links: chained frames and whatever shares a link with them --------------------------------------
    def submit(self, name: str, data: bytes | None = None) -> None:
        """A chained frame handed to its producer's NIC now (its task has just finished, plus tx_delay); its release
        is taken tx_delay earlier, as a free-running frame's, so its latency is what the analysis' wcrt_ns bounds."""
        i = self.index[name]
        how = self._chained_how.get(i)
        if how is None:
            raise ValueError(f"message '{name}' is free-running on bus '{self.bus.name}': only chained ones are sent")
        link, dead, tx, off, below = how
        now = self.sim.now
        if link is None or now >= dead:
            return  # a message nobody else consumes goes nowhere; a crashed node sends nothing
        self.sent[i] += 1
        if self._lose:
            lose = self._lose.get(i)
            if lose and min(lose) <= now:
                lose.remove(min(lose))
                self.lost[i] += self.downstream[(i, link.index)]
                return
        self._seq = seq = self._seq + 1
        heappush(link.waiting, (now, seq, i, now - tx))
        if off >= 0:
            link.fresh.append((now + off, now, seq))
        self._advance(below)

    def _advance(self, links: list[_Link]) -> None:
        """Serve these event links (in path order) up to their horizons, then set a wake-up for what still waits."""
        now = self.sim.now
        nic = now if now < self._known else self._known
        for link in links:
            if link.takes_chained:
                k = nic
            else:
                k = NEVER
                for feeder, slack in link.feeders:
                    v = feeder.served + slack
                    if v < k:
                        k = v
            waiting = link.waiting
            if waiting and waiting[0][0] <= k:
                self._serve(link, k)
            link.served = k
            due = link.due
            if link.fresh:  # frames that arrived since the last pass and must be served by a given instant
                for item in link.fresh:
                    if item[1] > k:
                        heappush(due, item)
                link.fresh.clear()
            if due:
                while due:  # drop what has been served: everything before the first frame still waiting
                    _, a, seq = due[0]
                    if waiting and (a > waiting[0][0] or (a == waiting[0][0] and seq >= waiting[0][1])):
                        break
                    heappop(due)
                if due:
                    self._wake_by(due[0][0] - 1)

    def _wake_by(self, t: int) -> None:
        """Make sure the links are served again at or before t."""
        if not self._wakes or t < self._wakes[0]:
            heappush(self._wakes, t)
            self.sim.at(t, self._wake, None, LATE)

    def _wake(self, _: object) -> None:
        now = self.sim.now
        while self._wakes and self._wakes[0] <= now:
            heappop(self._wakes)
        self._advance(self.event_order)

    def _serve(self, link: _Link, horizon: int) -> None:
        """FIFO with tail drop, frame by frame, for the frames arriving at or before the horizon; each frame served
        goes on to the next links or is delivered (the scalar twin of _transmit and _forward)."""
        waiting, ends, frame, route = link.waiting, link.ends, self._frame, link.route
        busy, cap, crash, d = link.busy_until, self.queue_frames, link.crash_ns, self.duration
        prop, lat = link.prop_ns, link.latency_ns
        frames, busy_ns, qmax, seq = link.frames, link.busy_ns, link.max_queue, self._seq
        at, delivered, quiet = self.sim.at, self._delivered, self._finished
        while waiting and waiting[0][0] <= horizon:
            a, _, i, r = heappop(waiting)
            while ends and ends[0] <= a:
                ends.popleft()
            s = a if a > busy else busy
            if len(ends) >= cap or s >= crash:
                link.lost += 1
                self.lost[i] += self.downstream[(i, link.index)]
                continue
            busy = s + frame[i]
            ends.append(busy)
            if len(ends) > qmax:
                qmax = len(ends)
            if s < d:
                frames += 1
                busy_ns += (busy if busy < d else d) - s
            kids, dest = route[i]
            recv = busy + prop
            if kids:
                x = recv + lat
                for child, off in kids:
                    seq += 1
                    heappush(child.waiting, (x, seq, i, r))
                    if off >= 0:
                        child.fresh.append((x + off, x, seq))
            if dest is not None:
                rx, dead, rels, end1, server, prel, pend, listen, name = dest
                e = recv + rx
                if e >= dead:  # a crashed consumer receives nothing more
                    self.lost[i] += 1
                    continue
                rels.append(r)
                end1.append(e)
                if server is not None:
                    server.ends.append(e)
                    server.msgs.append(i)
                    server.rels.append(r)
                else:  # nothing to wait for: consumed as it arrives
                    prel.append(r)
                    pend.append(e)
                if listen is not None and e < d and not quiet:
                    at(e, delivered, (name, r, e, listen))
        link.busy_until = busy
        link.frames, link.busy_ns, link.max_queue, self._seq = frames, busy_ns, qmax, seq

    # -- after the run ----------------------------------------------------------------------------------------
    def _finish(self) -> None:
        """Once the run is over: serve what event links still hold (nothing observed it; every arrival before the
        end is known now), then the receiving nodes' FIFOs. Before the end, results are those so far."""
        if self._finished or self.sim.now < self.duration:
            return
        self._finished = True
        for link in self.event_order:
            self._serve(link, self.duration - 1)
        for server in self.servers.values():
            self._process(server)

    def _process(self, server: _Server) -> None:
        """The receiving node's FIFO over the run: Lindley's recursion with service times drawn in [BCET, WCET]."""
        one_by_one = (np.asarray(server.ends, _I64), np.asarray(server.msgs, _I64), np.asarray(server.rels, _I64))
        parts = [*server.batches, one_by_one]
        t = np.concatenate([p[0] for p in parts])
        msg = np.concatenate([p[1] for p in parts])
        rel = np.concatenate([p[2] for p in parts])
        order = np.argsort(t, kind="stable")
        order = order[t[order] < self.duration]
        t, msg, rel = t[order], msg[order], rel[order]
        if not len(t):
            return
        lo, hi = server.bcet[msg], server.wcet[msg]
        s = lo + (self.sc.rng.random(len(t)) * (hi - lo + 1)).astype(_I64)
        cum = np.cumsum(s)
        end = cum + np.maximum.accumulate(t - (cum - s))
        d = self.duration
        server.busy_ns = int((np.minimum(end, d) - np.minimum(end - s, d)).sum())
        for i in np.unique(msg).tolist():
            sel = msg == i
            self._proc_rel[i].append(rel[sel])
            self._proc_end[i].append(end[sel])

    # -- results ----------------------------------------------------------------------------------------------
    def _pairs(self, rel: list[np.ndarray], end: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """(release, end) of what completed within the run."""
        r = np.concatenate(rel) if rel else _EMPTY
        e = np.concatenate(end) if end else _EMPTY
        done = e < self.duration
        return r[done], e[done]

    def records(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Per message: (name, release_ns, end_ns) of every delivery within the run, one per consumer reached;
        end is when the consumer has the data (after rx_delay), the instant the analysis' wcrt_ns bounds."""
        self._finish()
        out = []
        for i, m in enumerate(self.messages):
            rel = [*self._rel[i], np.asarray(self._rel1[i], _I64)]
            end = [*self._end[i], np.asarray(self._end1[i], _I64)]
            out.append((m.name, *self._pairs(rel, end)))
        return out

    def processed_records(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Like records(), with end = when the receiving node has finished consuming the frame."""
        self._finish()
        out = []
        for i, m in enumerate(self.messages):
            rel = [*self._proc_rel[i], np.asarray(self._proc_rel1[i], _I64)]
            end = [*self._proc_end[i], np.asarray(self._proc_end1[i], _I64)]
            out.append((m.name, *self._pairs(rel, end)))
        return out

    def lost_by_message(self) -> dict[str, int]:
        """Deliveries that will never happen: dropped at a full port (one per consumer behind it), scripted losses
        (one per consumer) and deliveries to a crashed node."""
        self._finish()
        return {m.name: int(self.lost[i]) for i, m in enumerate(self.messages)}

    def in_flight(self) -> dict[str, int]:
        """Deliveries of frames released within the run that had not happened when it ended."""
        self._finish()
        n = np.zeros(len(self.messages), dtype=_I64)
        for link in self.links.values():
            for _, msg, rel in link.pending:
                for i, k in zip(*np.unique(msg[rel < self.duration], return_counts=True)):
                    n[i] += int(k) * self.downstream[(int(i), link.index)]
            for _, _, i, r in link.waiting:
                if r < self.duration:
                    n[i] += self.downstream[(i, link.index)]
        for i in range(len(self.messages)):
            for e in self._end[i]:
                n[i] += int((e >= self.duration).sum())
            n[i] += sum(1 for e in self._end1[i] if e >= self.duration)
        return {m.name: int(n[i]) for i, m in enumerate(self.messages)}

    def report(self) -> dict[str, Any]:
        """JSON-ready: per link direction, measured beside the analysis' utilisation; per message, what the run's
        summary (netcfg.sim.results.summary: deliveries, latency, wcrt, losses) does not say."""
        self._finish()
        d = self.duration
        links = []
        for link in sorted(self.links.values(), key=lambda lk: (lk.src, lk.dst)):
            held = sum(1 for e in link.ends if e > d) if link.event else int((link.tail > d).sum())
            links.append(
                {
                    "from": link.src,
                    "to": link.dst,
                    "frames": link.frames,
                    "utilization": round(link.busy_ns / d, 6) if d else 0.0,
                    "utilization_offered": round(link.offered, 6),
                    "max_queue": link.max_queue,
                    "queue_frames": self.queue_frames,
                    "queued_at_end": held,
                    "lost": link.lost,
                }
            )
        flying = self.in_flight()
        messages = [
            {
                "name": name,
                "chained": i in self.chained,
                "sent": int(self.sent[i]),
                "in_flight": flying[name],
                "processed_us": stats_us(end - rel),
            }
            for i, (name, rel, end) in enumerate(self.processed_records())
        ]
        servers = {s.node: {"utilization": round(s.busy_ns / d, 6) if d else 0.0} for s in self.servers.values()}
        return {
            "bus": self.bus.name,
            "bitrate": self.bus.bitrate,
            "duration_us": d / 1000,
            "links": links,
            "messages": messages,
            "receivers": servers,
        }


def _take(pending: list[Batch], horizon: int) -> Batch | None:
    """The waiting frames that arrive before the horizon, sorted by arrival (FIFO, earlier batches first on ties);
    the others stay."""
    if not pending:
        return None
    if len(pending) == 1:
        t, msg, rel = pending[0]
    else:
        t = np.concatenate([b[0] for b in pending])
        msg = np.concatenate([b[1] for b in pending])
        rel = np.concatenate([b[2] for b in pending])
    order = np.argsort(t, kind="stable")
    t, msg, rel = t[order], msg[order], rel[order]
    k = int(np.searchsorted(t, horizon, side="left"))
    pending.clear()
    if k < len(t):
        pending.append((t[k:], msg[k:], rel[k:]))
    if k == 0:
        return None
    return t[:k], msg[:k], rel[:k]


