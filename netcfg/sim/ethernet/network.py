"""EthernetNetwork: one switched Ethernet bus of a run, built from the runtime configuration (see the package)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from netcfg.runtime import Bus, Message
from netcfg.sim.engine import NEVER
from netcfg.sim.ethernet.links import _I64, Link
from netcfg.sim.ethernet.results import Results
from netcfg.timing.frames import udp_message_ns

if TYPE_CHECKING:
    from netcfg.sim.run import SimRun


class EthernetNetwork(Results):
    def __init__(
        self,
        sc: SimRun,
        bus: Bus,
        *,
        queue_frames: int | None = None,
        processing_ns: Mapping[str, tuple[int, int]] | None = None,
    ) -> None:
        """queue_frames, processing_ns: default to the options' eth_queue_frames and eth_processing_ns; queue_frames
        None: each NIC and port holds what the runtime configuration says (QUEUE_FRAMES if it says nothing). processing:
        node -> (BCET, WCET) of consuming one frame; by default a node's on_message task for that message, else 0
        (no server)."""
        self.sc = sc
        self.bus = bus
        self.sim = sc.sim
        self.duration = sc.opts.duration_ns
        q = queue_frames if queue_frames is not None else sc.opts.eth_queue_frames
        self.queue_frames = None if q is None else int(q)  # one depth for every queue, else each its own
        if self.queue_frames is not None and self.queue_frames < 1:
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
        self.heard = None  # (message, consumer) -> its listened deliveries (release, end), in whole-run mode only
        self._build_routes_by_link()
        # chained message -> (first link or None, producer's crash, tx_delay, need at the first link or -1, links)
        self._chained_how: dict[int, tuple[Link | None, int, int, int, list[Link]]] = {}
        for i in self.chained:
            m, link = self.messages[i], self.first.get(i)
            self._chained_how[i] = (
                link,
                self.sc.crash_at.get(m.producer, NEVER),
                self.tx_delay.get(m.producer, 0),
                -1 if link is None else self.need.get((i, link.index), -1),
                [] if link is None else self._below[link.index],
            )

    def lose_at(self, name: str, at_ns: int) -> None:
        """A scripted loss (fault lose:MESSAGE@T): the first frame of the message queued at or after at_ns."""
        self._lose.setdefault(self.index[name], []).append(at_ns)

    def start(self) -> None:
        if self.duration > 0:
            self.sim.at(0, self._chunk, 0)
