"""Free-running links, a chunk of simulated time at a time.

Speed: free-running traffic does not depend on the rest of the simulation, so the links that carry only such
traffic (and are fed only by such links) are computed a chunk of simulated time at a time with numpy: releases are
generated per chunk, and each of these links, in path order, serves every frame that reaches it before the chunk's
end (Lindley's recursion, vectorised when nothing is dropped). A frame released later cannot reach any port earlier
than that, so those results are final. Only deliveries that someone listens to (a flow, a message-activated task)
become events. The cabling is taken to be a tree, as a switched Ethernet without spanning tree must be; paths are
its tree paths, as in the analysis.
"""

from __future__ import annotations

from collections import deque
from heapq import heappush

import numpy as np

from netcfg.sim.engine import NEVER
from netcfg.sim.ethernet.events import EventLinks
from netcfg.sim.ethernet.links import _I64, CHUNK_NS, Link, counts_by_index, take


class FreeRunning(EventLinks):
    def _chunk(self, t0: int) -> None:
        t1 = min(t0 + CHUNK_NS, self.duration)
        self._release(t0, t1)
        for link in self.free_order:
            batch = take(link.pending, t1)
            if batch is not None:
                self._transmit(link, *batch)
            link.served = t1 - 1
        self._known = t1 - 1
        if self.event_order:
            self._advance(self.event_order)
        if t1 < self.duration:
            self.sim.at(t1, self._chunk, t1)

    # -- the whole run at once (netcfg.sim.whole_run) ------------------------------------------------------------
    def whole_run_begin(self) -> None:
        """Every link is computed as a free-running one, a window at a time, when whole_run_link() says (after all
        that feeds it); listened deliveries are kept in self.heard instead of becoming events."""
        for link in self.order:
            link.event = False
        self.free_order, self.event_order = list(self.order), []
        self.heard = {}

    def whole_run_release(self, t0: int, t1: int) -> None:
        """The free-running releases whose nominal instant falls in [t0, t1); jittered ones a chunk at a time, so
        their draws come in the event path's order."""
        step = CHUNK_NS if self._jitter_max else t1 - t0
        assert step == t1 - t0 or (t0 % CHUNK_NS == 0 and (t1 % CHUNK_NS == 0 or t1 == self.duration)), "chunk edges"
        for a in range(t0, t1, step):
            self._release(a, min(a + step, t1))

    def whole_run_send(self, i: int, at: np.ndarray) -> None:
        """Frames of chained message i handed to its producer's NIC at these instants (submit(), all at once)."""
        link = self.first.get(i)
        if link is None or not len(at):
            return  # a message nobody else consumes goes nowhere
        self.sent[i] += len(at)
        self._enqueue(link, at, np.full(len(at), i, dtype=_I64), at - self._tx_ns[i])

    def whole_run_link(self, link: Link, horizon: int) -> None:
        """Serve every frame reaching the link before the horizon (all of them are known by now)."""
        batch = take(link.pending, horizon)
        if batch is not None:
            self._transmit(link, *batch)
        link.served = self._known = horizon - 1

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

    def _enqueue(self, link: Link, t: np.ndarray, msg: np.ndarray, rel: np.ndarray) -> None:
        """Frames computed a chunk at a time reaching a link: a batch for a free-running link, else one by one."""
        if not link.event:
            link.pending.append((t, msg, rel))
            return
        waiting, fresh, seq, li = link.waiting, link.fresh, self._seq, link.index
        need = self.need
        for a, i, r in zip(t.tolist(), msg.tolist(), rel.tolist()):
            seq += 1
            heappush(waiting, (a, r, i, seq))
            off = need.get((i, li))
            if off is not None:
                fresh.append((a + off, a, r, i, seq))
        self._seq = seq

    def _transmit(self, link: Link, t: np.ndarray, msg: np.ndarray, rel: np.ndarray) -> None:
        """Serve the frames reaching the link's FIFO (sorted by arrival), then pass them on."""
        c = self.frame_ns[msg]
        cum = np.cumsum(c)
        end = cum + np.maximum(np.maximum.accumulate(t - (cum - c)), link.busy_until)
        keep = len(t)
        if link.crash_ns < NEVER:  # a suffix: start times only grow
            keep = int(np.searchsorted(end - c, link.crash_ns, side="left"))
        # frames at the port when frame i arrives: earlier ones of this batch and of earlier ones not yet sent;
        # none for a frame that starts as it arrives, so only the frames that wait are counted
        waits = np.flatnonzero(end[:keep] - c[:keep] > t[:keep])
        queue = 0
        if len(waits):
            tw = t[waits]
            held = len(link.tail) - np.searchsorted(link.tail, tw, side="right")
            queue = int((waits - np.searchsorted(end[:keep], tw, side="right") + held).max())
        if keep and queue >= link.queue_frames:
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
                link.max_queue = max(link.max_queue, queue + 1)
        if not len(end):
            return
        link.busy_until = int(end[-1])
        link.tail = np.concatenate([link.tail, end[-link.queue_frames :]])[-link.queue_frames :]
        start = end - c
        d = self.duration
        link.frames += int((start < d).sum())
        link.busy_ns += int((np.minimum(end, d) - np.minimum(start, d)).sum())
        self._forward(link, end + link.prop_ns, msg, rel)

    def _transmit_lossy(self, link: Link, t: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lindley's recursion frame by frame with tail drop at a full port: -> (accepted indices, their ends).

        Only the last queue_frames ends can still be at the port later (a frame is accepted only when fewer are),
        so link.tail keeps just those."""
        ends = deque(link.tail.tolist())
        busy, cap, crash = link.busy_until, link.queue_frames, link.crash_ns
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

    def _count_lost(self, link: Link, msg: np.ndarray) -> None:
        link.lost += len(msg)
        for i, n in counts_by_index(msg):
            self.lost[i] += n * self.downstream[(i, link.index)]

    def _forward(self, link: Link, recv: np.ndarray, msg: np.ndarray, rel: np.ndarray) -> None:
        """Frames completely received at the link's far end: on to the next links, or delivered."""
        present = np.flatnonzero(np.bincount(msg)).tolist()
        for i in present:
            if len(present) == 1:
                r, e, mm = rel, recv, msg
            else:
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
        if listen is not None and self.heard is not None:  # the whole run at once: kept for its tasks and flows
            heard = end < self.duration
            self.heard.setdefault((i, consumer), []).append((rel[heard], end[heard]))
        elif listen is not None:
            name = self.messages[i].name
            at = self.sim.at
            for r, e in zip(rel.tolist(), end.tolist()):
                if e < self.duration:
                    at(e, self._delivered, (name, r, e, listen))
