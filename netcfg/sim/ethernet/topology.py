"""Set-up of a switched Ethernet run: the cabling as a tree, per message the links its frames cross and the consumers
they reach, the free-running senders' release streams, the receiving nodes' servers, who listens to which delivery,
and which links must run frame by frame (events.py). Also the state every part of the run shares, declared once.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from fractions import Fraction
from itertools import pairwise
from typing import TYPE_CHECKING, Any

import numpy as np

from netcfg.runtime import Bus, Message
from netcfg.sim.engine import NEVER, Simulator
from netcfg.sim.ethernet.links import _I64, Link, Listen, Server
from netcfg.sim.streams import PeriodicStreams
from netcfg.timing import load
from netcfg.timing.ethernet import QUEUE_FRAMES, propagation_ns

if TYPE_CHECKING:
    from netcfg.sim.run import SimRun


class Topology:
    """The network's state (filled by EthernetNetwork.__init__ and the set-up below) and its set-up."""

    sc: SimRun
    bus: Bus
    sim: Simulator
    duration: int
    queue_frames: int | None  # every queue's depth when the run's options set one
    messages: list[Message]
    index: dict[str, int]  # message name -> index
    owned: set[str]
    chained: set[int]  # messages sent by their task as it finishes (submit), not free-running
    frame_ns: np.ndarray  # per message, its frame time on every link
    _frame: list[int]
    rx_delay: dict[str, int]
    tx_delay: dict[str, int]
    sent: np.ndarray
    lost: np.ndarray
    _lose: dict[int, list[int]]
    _rel: list[list[np.ndarray]]
    _end: list[list[np.ndarray]]
    _rel1: list[list[int]]
    _end1: list[list[int]]
    _proc_rel: list[list[np.ndarray]]
    _proc_end: list[list[np.ndarray]]
    _proc_rel1: list[list[int]]
    _proc_end1: list[list[int]]
    _known: int
    heard: dict[tuple[int, str], list[tuple[np.ndarray, np.ndarray]]] | None  # whole-run mode: listened deliveries
    _seq: int
    _wakes: list[int]
    _finished: bool
    _chained_how: dict[int, tuple[Link | None, int, int, int, list[Link]]]

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
        self.depth: dict[tuple[str, str], int | None] = {}  # (from, to) -> its transmit queue's depth, if given
        for sw in switches:
            self.switch_latency[sw.name] = sw.latency_ns
            for port in sw.ports:
                edge(sw.name, port.to, port.cable_m)
                self.depth[(sw.name, port.to)] = port.queue
        queue = {sw.name: sw.queue for sw in switches}  # a port the file does not list (a cable listed at its far end)
        for a, b in cables:
            if a in queue:
                self.depth.setdefault((a, b), queue[a])
            elif bus.ethernet is not None:
                self.depth[(a, b)] = bus.ethernet.nic_queue(a)
        if not switches and len(bus.nodes) == 2:
            edge(bus.nodes[0], bus.nodes[1], 0.0)
        self.adj = adj
        self.cables = cables
        self.links: dict[tuple[str, str], Link] = {}

    def _link(self, a: str, b: str) -> Link:
        link = self.links.get((a, b))
        if link is None:
            prop = propagation_ns(self.cables.get((a, b), 0.0))  # per hop, as the analysis' Tprop
            crash = NEVER if a in self.switch_latency else self.sc.crash_at.get(a, NEVER)
            latency = self.switch_latency.get(b, 0)
            depth = self.queue_frames or self.depth.get((a, b)) or QUEUE_FRAMES
            link = self.links[(a, b)] = Link(len(self.links), a, b, prop, latency, crash, depth)
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
        self.first: dict[int, Link] = {}
        self.children: dict[tuple[int, int], list[Link]] = {}  # (message, link) -> next links
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

    def _topological(self) -> list[Link]:
        """Links in an order where every link comes after those that feed it (a tree has no cycle of them)."""
        feeds: dict[int, set[int]] = {lk.index: set() for lk in self.links.values()}
        for (_, a), kids in self.children.items():
            for b in kids:
                feeds[b.index].add(a)
        by_index = {lk.index: lk for lk in self.links.values()}
        done: list[Link] = []
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
                    rng=self.sc.random(f"jitter {self.bus.name}"),
                )
            )
        self._free = free  # message indices, ascending
        self._free_edges = np.array([*free, len(self.messages)], dtype=_I64)  # where each one's releases start
        self._tx_ns = [self.tx_delay.get(m.producer, 0) for m in self.messages]
        self._jitter_max = max((self.messages[i].jitter_ns for i in free), default=0)

    def _build_servers(self, nodes: Mapping[str, Any], processing: Mapping[str, tuple[int, int]]) -> None:
        n = len(self.messages)
        self.servers: dict[str, Server] = {}
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
                self.servers[node] = Server(node, bcet, wcet)

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
        self._below: dict[int, list[Link]] = {}
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
