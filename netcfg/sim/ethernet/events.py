"""Event links: chained frames and every link they can reach, frame by frame.

Chained messages (sent by a flow task as it finishes, Scenario.sends) are not known ahead: submit() hands one to
the NIC at the current instant. A chunk computed ahead on a link such a frame crosses could be wrong (the frame
would have to be served before frames already served after it), so those links, and every link downstream of
them, run frame by frame in arrival order instead ("event links"). They are still served lazily: a link serves
its waiting frames up to a horizon before which every arrival is known, which is now for a NIC that takes chained
frames, the chunk's end for a free-running link, and for a switch port the least, over the links feeding it, of
their horizon plus the shortest frame time, cable and switch latency from them (a frame not yet known there
reaches the port no sooner). Serving happens on each submit (along the submitted frame's links) and at wake-ups
set just before the earliest instant a waiting frame could matter (a listened delivery), so nothing is served too
late and a link never serves a frame before one that arrives earlier. Frames reaching a port at the same instant
leave in order of release, then of message index (links.ARRIVAL_ORDER), so a NIC serves only what arrived before
now: another task may still hand it a frame at this very instant.
"""

from __future__ import annotations

from heapq import heappop, heappush

from netcfg.sim.engine import LATE
from netcfg.sim.ethernet.links import Link, Listen
from netcfg.sim.ethernet.topology import Topology


class EventLinks(Topology):
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
        heappush(link.waiting, (now, now - tx, i, seq))
        if off >= 0:
            link.fresh.append((now + off, now, now - tx, i, seq))
        self._advance(below)

    def _advance(self, links: list[Link]) -> None:
        """Serve these event links (in path order) up to their horizons, then set a wake-up for what still waits."""
        now = self.sim.now
        # a NIC has every frame arriving before now: more may still be submitted at this very instant
        nic = now - 1 if now - 1 < self._known else self._known
        last = self.duration - 1
        for link in links:
            if link.takes_chained:
                k = nic
            else:
                k = last  # a frame reaching a port after the run's end is not served within it
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
                    if waiting and due[0][1:] >= waiting[0]:
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

    def _serve(self, link: Link, horizon: int) -> None:
        """FIFO with tail drop, frame by frame, for the frames arriving at or before the horizon; each frame served
        goes on to the next links or is delivered (the scalar twin of _transmit and _forward)."""
        waiting, ends, frame, route = link.waiting, link.ends, self._frame, link.route
        busy, cap, crash, d = link.busy_until, link.queue_frames, link.crash_ns, self.duration
        prop, lat = link.prop_ns, link.latency_ns
        frames, busy_ns, qmax, seq = link.frames, link.busy_ns, link.max_queue, self._seq
        at, delivered, quiet = self.sim.at, self._delivered, self._finished
        while waiting and waiting[0][0] <= horizon:
            a, r, i, _ = heappop(waiting)
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
                    heappush(child.waiting, (x, r, i, seq))
                    if off >= 0:
                        child.fresh.append((x + off, x, r, i, seq))
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

    def _delivered(self, arg: tuple[str, int, int, Listen]) -> None:
        name, release, end, (trackers, tasks) = arg
        for tr in trackers:
            tr.message_delivered(name, release, end)
        for task in tasks:
            self.sc.run_task(task, end)
