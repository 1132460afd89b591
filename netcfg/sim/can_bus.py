"""One CAN bus: arbitration at every bus-idle instant, non-preemptive frames, bit errors and retransmission.

Speed comes from two things. Frames whose release instants do not depend on the simulation (free-running
periodic and sporadic traffic) arrive as precomputed, sorted release streams that the bus merges itself, in
chunks, without one event per frame. And the bus runs its arbitration loop for as long as nothing else in the
simulation can happen before the next decision, handing control back only when a delivered frame has a listener
or another event is due. What it carries and exact stuffing's frame times are netcfg.sim.can_frames'.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable

import numpy as np

from netcfg.links.arbitration import frame_priority
from netcfg.runtime.codec import Field, resting_payload
from netcfg.sim.can_frames import CanSource, ExactFrames, Gate, Listener, Pending, Record, Stream, TxFifo
from netcfg.sim.engine import EARLY, LATE, NEVER, Simulator
from netcfg.timing.frames import FrameStuffing, bits_to_ns, frame_bits

# An error flag (6 bits), other nodes' superposed flags (up to 6 more), the error delimiter (8) and the
# intermission (3): ISO 11898-1's active error frame at its longest.
ERROR_FRAME_BITS = 6 + 6 + 8 + 3
INTERMISSION_BITS = 3  # the end of every frame time: nothing to corrupt there
# the bus's stuffing modes as the timing core names them (can_frame_bits_of)
FRAME_BITS: dict[str, FrameStuffing] = {"worst": "worst", "none": "nominal", "exact": "exact"}
CHUNK_NS = 200_000_000  # release streams are expanded this much simulated time at a time
# ... or this much, when the releases are the same however time is cut: no stream draws random numbers or counts
# crash losses per chunk (PeriodicStreams.chunk_free), and frames carry no random payloads. An expansion has a
# fixed cost (its numpy calls) beside its releases': 2 s chunks take 3 % off a fully loaded 1 Mbit/s bus's run.
LONG_CHUNK_NS = 2_000_000_000
LONG_CHUNK_RELEASES = 32_768  # at most this many releases per long chunk, at the rate of the last one (memory)


class CanBus:
    def __init__(
        self,
        sim: Simulator,
        name: str,
        bitrate: int,
        stuffing: str = "worst",
        trace: bool = False,
        data_bitrate: int | None = None,
    ) -> None:
        if stuffing not in FRAME_BITS:
            raise ValueError(f"stuffing must be exact, worst or none, not {stuffing!r}")
        self.sim = sim
        self.name = name
        self.bitrate = bitrate
        self.data_bitrate = data_bitrate or bitrate  # CAN FD: the data phase of frames with bit-rate switch
        self.stuffing = stuffing
        self.trace = trace
        self.sources: list[CanSource] = []
        self._keys: list[int] = []  # per source, for the loop
        self._durs: list[int] = []
        self.by_name: dict[str, CanSource] = {}
        self.streams: list[Stream] = []
        self.listeners: dict[int, list[Listener]] = {}
        self.monitors: list[Listener] = []  # see every frame (python-can endpoints), except those they are deaf to
        self._deaf: dict[Listener, set[int]] = {}  # monitor -> sources it does not hear (its own frames)
        self._hear: dict[int, tuple[Listener, ...]] = {}  # source -> who hears its frames (listeners, monitors)
        self.gate: Gate | None = None
        self.record = Record()
        self.error_times: list[int] = []
        self.error_frames = 0
        self.error_log: list[int] = []  # instants of bit errors that hit a frame (traces; the error-model check)
        self.dropped: dict[int, int] = {}  # message index -> frames lost before reaching the bus
        self.babble: tuple[int, int, int] | None = None  # (source index, from, until)
        self.lose: dict[int, list[int]] = {}  # message index -> instants: the next frame queued after is lost
        self.retries: dict[int, int] = {}  # message index -> retransmissions after bit errors
        self._pending: list[Pending] = []
        self.fifos: list[TxFifo] = []
        self._fifo_of: list[int] = []  # per source: its FIFO's index, -1 when priority-queued
        self._seq = 0
        self._rel_t: list[int] = []
        self._rel_src: list[int] = []
        self._rel_data: list[bytes | None] = []  # payloads of free-running frames (exact stuffing only)
        self._exact = ExactFrames(sim, self.sources, bitrate, self.data_bitrate)  # exact stuffing's frame times
        self._rel_i = 0
        self._chunk_end = 0
        self._chunk_ns = CHUNK_NS  # how much simulated time the next refill expands
        self._chunk_free = False  # the releases do not depend on the chunks (start)
        self._free_at = 0  # the bus is busy until then
        self._step_at: int | None = None  # when the arbitration loop is due to run next
        self._err_i = 0
        self.error_ns = bits_to_ns(ERROR_FRAME_BITS, bitrate)
        self.ifs_ns = bits_to_ns(INTERMISSION_BITS, bitrate)

    # -- set-up -----------------------------------------------------------------------------------------
    def add_source(
        self,
        name: str,
        can_id: int,
        extended: bool,
        size: int,
        producer: str,
        gated: bool = False,
        fd: bool = False,
        brs: bool = False,
        fields: tuple[Field, ...] = (),
        remote: bool = False,
    ) -> int:
        src = CanSource(len(self.sources), name, can_id, extended, size, producer, gated=gated, fd=fd, brs=brs)
        src.fields, src.rest = fields, resting_payload(fields, size)
        src.key = frame_priority(can_id, extended, remote)  # a data frame wins over a remote frame of its id
        # in exact mode each frame's length comes from its payload (_duration); dur_ns is then the worst case
        mode: FrameStuffing = "worst" if self.stuffing == "exact" else FRAME_BITS[self.stuffing]
        assert mode != "exact"
        src.dur_ns = frame_bits(size, extended, fd, brs, mode).ns(self.bitrate, self.data_bitrate)
        self.sources.append(src)
        self.by_name[name] = src
        self._keys.append(src.key)
        self._durs.append(src.dur_ns)
        self._fifo_of.append(-1)
        return src.index

    def fifo_queue(self, producer: str, depth: int, drop: bool) -> TxFifo:
        """The sources of `producer` (added so far) share one FIFO transmit queue from now on."""
        q = TxFifo(depth, drop)
        for src in self.sources:
            if src.producer == producer:
                self._fifo_of[src.index] = len(self.fifos)
        self.fifos.append(q)
        return q

    def add_stream(self, stream: Stream) -> None:
        self.streams.append(stream)

    def listen(self, source: int, fn: Listener) -> None:
        self.listeners.setdefault(source, []).append(fn)
        self._hear.clear()

    def listen_only(self, source: int, fn: Listener) -> None:
        """fn replaces whoever listened to the source's frames (a whole run records them instead)."""
        self.listeners[source] = [fn]
        self._hear.clear()

    def monitor(self, fn: Listener) -> None:
        """fn hears every frame (but those of the sources it is deafened to)."""
        self.monitors.append(fn)
        self._deaf[fn] = set()
        self._hear.clear()

    def deafen(self, fn: Listener, source: int) -> None:
        """Monitor fn no longer hears the source's frames (a python-can endpoint's own): a frame nobody hears is
        no event, so the arbitration loop carries on past it."""
        self._deaf[fn].add(source)
        self._hear.clear()

    def unmonitor(self, fn: Listener) -> None:
        if fn in self._deaf:
            self.monitors.remove(fn)
            del self._deaf[fn]
            self._hear.clear()

    def _hearers(self, m: int) -> tuple[Listener, ...]:
        """Who hears a frame of source m: its listeners, then the monitors not deaf to it."""
        hear = self._hear.get(m)
        if hear is None:
            hear = (*self.listeners.get(m, ()), *(fn for fn in self.monitors if m not in self._deaf[fn]))
            self._hear[m] = hear
        return hear

    def start(self) -> None:
        self._chunk_free = self.stuffing != "exact" and all(getattr(s, "chunk_free", False) for s in self.streams)
        self._refill(0)
        self._wake(0)

    # -- traffic ----------------------------------------------------------------------------------------
    def submit(self, source: int, data: bytes | None = None) -> None:
        """Queue a frame now (a reactive sender: a task, the CANopen master, the FTT-CAN master)."""
        now = self.sim.now
        if data is None and self.stuffing == "exact" and self.sources[source].size:
            data = self._exact.payloads(self.sources[source], 1)[0].tobytes()
        self._seq += 1
        item = (self._keys[source], now, self._seq, source, data)
        if self._fifo_of[source] < 0:
            heapq.heappush(self._pending, item)
        else:
            self._enqueue(item)
        # _wake(now), inline: reactive senders submit a frame per event
        t = now if now > self._free_at else self._free_at
        if self._step_at is None or t < self._step_at:
            self._step_at = t
            self.sim.at(t, self._step, t, LATE)

    def _enqueue(self, item: Pending) -> None:
        """A frame reaches its node's transmit queue: priority-queued frames all compete; a FIFO's only at its head."""
        qi = self._fifo_of[item[3]]
        if qi < 0:
            heapq.heappush(self._pending, item)
            return
        q = self.fifos[qi]
        if q.size >= q.depth:
            q.overflows += 1
            if q.drop:
                self.drop(item[3])
                return
            # a blocked writer puts its frame in as soon as a slot frees: the order stays the order of the writes
        q.size += 1
        q.max_size = max(q.max_size, q.size)
        if q.size == 1:
            heapq.heappush(self._pending, item)
        else:
            q.behind.append(item)

    def _dequeue(self, source: int) -> None:
        """The head of a FIFO left the queue (sent or lost): the next frame moves up to arbitration."""
        q = self.fifos[self._fifo_of[source]]
        q.size -= 1
        if q.behind:
            heapq.heappush(self._pending, q.behind.popleft())

    def queued_unsent(self, source: int, release: int) -> None:
        """A frame queued at `release` that the run ended before sending (a whole run's, for pending_count)."""
        self._seq += 1
        heapq.heappush(self._pending, (self._keys[source], release, self._seq, source, None))

    def drop(self, source: int) -> None:
        """A frame that never reached the bus (its sender crashed, a scripted loss): counted, not sent."""
        self.dropped[source] = self.dropped.get(source, 0) + 1

    def remove_pending(self, keep: Callable[[int], bool]) -> None:
        """Forget queued frames of sources for which keep() is false (a node that crashed), counting them."""
        kept = []
        for item in self._pending:
            if keep(item[3]):
                kept.append(item)
            else:
                self.drop(item[3])
                if self._fifo_of[item[3]] >= 0:  # its node's whole FIFO goes with it
                    q = self.fifos[self._fifo_of[item[3]]]
                    for behind in q.behind:
                        self.drop(behind[3])
                    q.behind.clear()
                    q.size = 0
        heapq.heapify(kept)
        self._pending = kept
        # releases the bus has not reached yet, although due: the sender had queued them, and loses them too
        now = self.sim.now
        rest = range(self._rel_i, len(self._rel_t))
        gone = [i for i in rest if self._rel_t[i] <= now and not keep(self._rel_src[i])]
        if gone:
            for i in gone:
                self.drop(self._rel_src[i])
            drop = set(gone)
            left = [i for i in rest if i not in drop]
            self._rel_t = [self._rel_t[i] for i in left]
            self._rel_src = [self._rel_src[i] for i in left]
            self._rel_data = [self._rel_data[i] for i in left]
            self._rel_i = 0

    def pending_count(self) -> dict[int, int]:
        out: dict[int, int] = {}
        for item in [*self._pending, *(b for q in self.fifos for b in q.behind)]:
            out[item[3]] = out.get(item[3], 0) + 1
        for i in range(self._rel_i, len(self._rel_t)):
            if self._rel_t[i] < self.sim.now:
                out[self._rel_src[i]] = out.get(self._rel_src[i], 0) + 1
        return out

    # -- the loop ---------------------------------------------------------------------------------------
    def _wake(self, t: int) -> None:
        if t < self._free_at:
            t = self._free_at
        if self._step_at is None or t < self._step_at:
            self._step_at = t
            self.sim.at(t, self._step, t, LATE)

    def _refill(self, t0: int) -> None:
        """Expand the release streams for [t0, t0 + the chunk length) and merge them with what is left."""
        t1 = t0 + self._chunk_ns
        left = slice(self._rel_i, None)
        times = [np.asarray(self._rel_t[left], dtype=np.int64)]
        srcs = [np.asarray(self._rel_src[left], dtype=np.int64)]
        for stream in self.streams:
            ts, ss = stream(t0, t1)
            times.append(ts)
            srcs.append(ss)
        all_t = np.concatenate(times)
        all_s = np.concatenate(srcs)
        order = np.argsort(all_t, kind="stable")
        if self.stuffing == "exact":
            data: list[bytes | None] = self._rel_data[left] + [None] * (len(all_t) - len(times[0]))
            data = self._exact.random_payloads(all_s, data, len(times[0]))
            self._rel_data = [data[i] for i in order.tolist()]
        else:  # only exact stuffing gives free-running frames payloads
            self._rel_data = [None] * len(all_t)
        self._rel_t = all_t[order].tolist()
        self._rel_src = all_s[order].tolist()
        self._rel_i = 0
        self._chunk_end = t1
        new = len(all_t) - len(times[0])
        long = self._chunk_free and new * (LONG_CHUNK_NS // (t1 - t0)) <= LONG_CHUNK_RELEASES
        self._chunk_ns = LONG_CHUNK_NS if long else CHUNK_NS

    def _duration(self, src: CanSource, data: bytes | None) -> int:
        if self.stuffing != "exact":
            return src.dur_ns
        return self._exact.duration(src, data)

    def _step(self, token: int) -> None:
        if token != self._step_at:
            return  # superseded by an earlier wake-up
        self._step_at = None
        sim = self.sim
        queue = sim._queue
        until = sim.until
        pending = self._pending
        push, pop = heapq.heappush, heapq.heappop
        sources = self.sources
        keys, durs = self._keys, self._durs
        rec_msg, rec_resp = self.record.msg, self.record.response
        rel_t, rel_src, rel_data = self._rel_t, self._rel_src, self._rel_data
        ri, rn = self._rel_i, len(self._rel_t)
        listeners = self.listeners
        monitors = self.monitors
        lose = self.lose
        errors = self.error_times
        ei, en = self._err_i, len(errors)
        gate = self.gate
        exact = self.stuffing == "exact"
        keep_data = self.trace
        babble = self.babble
        seq = self._seq
        ifs = self.ifs_ns
        streams = bool(self.streams)
        chunk_end = self._chunk_end
        fifo_of = self._fifo_of
        fifos = bool(self.fifos)
        busy = self._free_at
        now = sim.now
        t = busy if busy > now else now  # the next arbitration instant
        hearers = self._hear
        many = len(monitors) > 1  # several python-can endpoints: one delivery event each
        # none of the per-frame special cases: frames nobody hears go through the short loop below
        plain = babble is None and gate is None and not exact and not fifos and not keep_data
        chunk_stop = chunk_end if streams else NEVER
        while True:
            # whatever else is due before this decision (or at it, and must happen first) runs first
            if queue:
                head = queue[0]
                ht = head[0]
                if ht < t or (ht == t and head[1] < LATE):
                    break
                horizon = ht if ht < until else until  # equal to t when another bus decides at this instant
            else:
                horizon = until
            if t >= until:
                break
            if t >= chunk_end and streams:
                self._rel_i = ri
                self._refill(chunk_end)
                rel_t, rel_src, rel_data = self._rel_t, self._rel_src, self._rel_data
                ri, rn = 0, len(rel_t)
                chunk_end = self._chunk_end
                chunk_stop = chunk_end
            if plain and ei >= en and not monitors and not lose:
                # The loop below, cut to what these frames need: it runs them while a decision at t would come
                # before the next event (the tests at its top), and leaves the rest to it: at its top, the next
                # event or a refill; else, at the same t, a frame someone hears or an idle stretch to the horizon.
                if queue:
                    stop_at = ht if head[1] < LATE else ht + 1  # a decision at ht comes after an EARLY event
                    if stop_at > until:
                        stop_at = until
                else:
                    stop_at = until
                while t < stop_at and t < chunk_stop:
                    while ri < rn and rel_t[ri] <= t:
                        s = rel_src[ri]
                        seq += 1
                        push(pending, (keys[s], rel_t[ri], seq, s, None))  # no payload outside exact stuffing
                        ri += 1
                    if not pending:
                        nxt = rel_t[ri] if ri < rn else NEVER
                        if nxt >= horizon or nxt >= chunk_stop:
                            break
                        t = nxt
                        continue
                    if pending[0][3] in listeners:
                        break
                    frame = pop(pending)
                    m = frame[3]
                    end = t + durs[m]
                    rec_msg.append(m)
                    rec_resp.append(end - frame[1])
                    t = busy = end
                if t >= stop_at or t >= chunk_stop:
                    continue
            while ri < rn and rel_t[ri] <= t:
                s = rel_src[ri]
                seq += 1
                if fifos and fifo_of[s] >= 0:
                    self._enqueue((keys[s], rel_t[ri], seq, s, rel_data[ri]))
                else:
                    push(pending, (keys[s], rel_t[ri], seq, s, rel_data[ri]))
                ri += 1
            item: Pending | None
            if babble is not None and babble[1] <= t < babble[2] and (not pending or keys[babble[0]] < pending[0][0]):
                item = (keys[babble[0]], t, -1, babble[0], None)
            elif pending:
                item = pop(pending)
                if gate is not None and sources[item[3]].gated:
                    item = self._gated_pick(item, t)
            else:
                item = None
            if item is None:  # nothing may start now: jump to the next release or window
                nxt = rel_t[ri] if ri < rn else NEVER
                if streams and chunk_end < nxt:
                    nxt = chunk_end
                if pending:
                    nxt = min(nxt, self._next_gate_time(t))
                if babble is not None and t < babble[1]:
                    nxt = min(nxt, babble[1])
                if nxt >= horizon:
                    t = nxt  # nothing happens on this bus before then, unless a frame is submitted
                    break
                t = nxt
                continue
            release, m, data = item[1], item[3], item[4]
            if lose and m in lose and self._lost(m, release):
                if fifos and fifo_of[m] >= 0:
                    self._dequeue(m)
                continue
            end = t + (self._duration(sources[m], data) if exact else durs[m])
            if ei < en:
                while ei < en and errors[ei] < t:
                    ei += 1
                if ei < en and errors[ei] < end - ifs:  # an error in the intermission spoils no frame
                    # a bit error: error frame, then the frame competes again (automatic retransmission)
                    self.error_log.append(errors[ei])
                    t = busy = errors[ei] + self.error_ns
                    ei += 1
                    self.error_frames += 1
                    self.retries[m] = self.retries.get(m, 0) + 1
                    if item[2] >= 0:  # a babbler's frame is not queued: it simply comes back
                        push(pending, (item[0], release, item[2], m, data))
                    continue
            if fifos and fifo_of[m] >= 0 and item[2] >= 0:
                self._dequeue(m)
            rec_msg.append(m)
            rec_resp.append(end - release)
            if keep_data:
                self.record.end.append(end)
                self.record.data.append(data)
            t = busy = end
            if m in listeners or monitors:
                hear = hearers.get(m) or self._hearers(m)
                if not hear:  # a monitor's own frame: no event, unless another bus decides at this instant first
                    if queue and queue[0][0] <= end:
                        break
                    continue
                # (events compare as tuples (t, priority, number, ...): one before (end, EARLY + 1) runs before a
                # delivery event at end would)
                if many or end >= until or (queue and queue[0] < (end, EARLY + 1)):
                    # others come first: a delivery event per hearer (one per frame when only a monitor can end
                    # a run_until(stop=...), as the last of them), then this loop again
                    if not many:
                        sim.at(end, _deliver_all, (hear, end, m, release, data))
                    else:
                        for fn in hear:
                            sim.at(end, _deliver, (fn, end, m, release, data))
                    break
                # Nothing else happens before this delivery: it happens here, as that event would have. The step
                # that event left behind (when the bus had more to do) keeps its place in the order of events: the
                # next number is taken now, before anything the hearers schedule.
                self._seq, self._rel_i, self._err_i, self._free_at = seq, ri, ei, busy
                more = pending or ri < rn or streams or babble is not None
                rewake = next(sim._seq) if more else None
                self._step_at = end if more else None
                sim.now = end
                for fn in hear:
                    fn(end, m, release, data)
                seq, pending, ri = self._seq, self._pending, self._rel_i
                many = len(monitors) > 1
                if self._rel_t is not rel_t:  # a crash dropped releases (remove_pending)
                    rel_t, rel_src, rel_data = self._rel_t, self._rel_src, self._rel_data
                    rn = len(rel_t)
                stop = sim.stop
                if (
                    rewake is None
                    or (stop is not None and stop())
                    or (queue and queue[0] < (end, LATE, rewake))
                ):
                    if rewake is not None:
                        heapq.heappush(queue, (end, LATE, rewake, self._step, end))
                    self._err_i = ei
                    return  # the state is written back; the step that comes next is in place
                self._step_at = None  # this loop is that step: it carries on
        self._seq = seq
        self._rel_i = ri
        self._err_i = ei
        self._free_at = busy
        if t < NEVER and (pending or ri < rn or self.streams or babble is not None):
            self._wake(t)

    def _lost(self, m: int, release: int) -> bool:
        due = [t for t in self.lose[m] if t <= release]
        if not due:
            return False
        self.lose[m].remove(min(due))
        self.drop(m)
        return True

    def _gated_pick(self, item: Pending, t: int) -> Pending | None:
        """FTT-CAN: an asynchronous frame may start only if it ends inside the asynchronous window.
        The highest-priority frame that fits wins; the others wait (put back)."""
        assert self.gate is not None
        tried = [item]
        chosen = None
        while True:
            m, data = tried[-1][3], tried[-1][4]
            src = self.sources[m]
            if not src.gated or self.gate(t, self._duration(src, data)) == t:
                chosen = tried.pop()
                break
            if not self._pending:
                break
            tried.append(heapq.heappop(self._pending))
        for other in tried:
            heapq.heappush(self._pending, other)
        return chosen

    def _next_gate_time(self, t: int) -> int:
        """The next instant at which some queued gated frame could start."""
        assert self.gate is not None
        best = NEVER
        for item in self._pending:
            src = self.sources[item[3]]
            best = min(best, self.gate(t, self._duration(src, item[4])) if src.gated else t)
        return best


def _deliver(arg: tuple[Listener, int, int, int, bytes | None]) -> None:
    fn, end, m, release, data = arg
    fn(end, m, release, data)


def _deliver_all(arg: tuple[tuple[Listener, ...], int, int, int, bytes | None]) -> None:
    fns, end, m, release, data = arg
    for fn in fns:
        fn(end, m, release, data)
