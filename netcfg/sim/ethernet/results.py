"""What a switched Ethernet run measured: deliveries (when the consumer has the data, and when it has consumed
it), losses, frames still in flight at the end, and the per-link report beside the analysis' utilisation."""

from __future__ import annotations

from typing import Any

import numpy as np

from netcfg.sim.ethernet.free import FreeRunning
from netcfg.sim.ethernet.links import _EMPTY, _I64, Server, counts_by_index
from netcfg.sim.stats import stats_us


class Results(FreeRunning):
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

    def _process(self, server: Server) -> None:
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
        draws = self.sc.random(f"processing {self.bus.name} {server.node}")
        s = lo + (draws.random(len(t)) * (hi - lo + 1)).astype(_I64)
        cum = np.cumsum(s)
        end = cum + np.maximum.accumulate(t - (cum - s))
        d = self.duration
        server.busy_ns = int((np.minimum(end, d) - np.minimum(end - s, d)).sum())
        for i, _ in counts_by_index(msg):
            sel = msg == i
            self._proc_rel[i].append(rel[sel])
            self._proc_end[i].append(end[sel])

    def _pairs(self, rel: list[np.ndarray], end: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """(release, end) of what completed within the run, in order of end, then release: the order frames of
        a multicast reach their consumers in depends on how the run was computed, the records do not."""
        r = np.concatenate(rel) if rel else _EMPTY
        e = np.concatenate(end) if end else _EMPTY
        late = e >= self.duration
        if late.any():
            r, e = r[~late], e[~late]
        if len(e) > 1 and (e[1:] <= e[:-1]).any():  # only a message with several consumers
            order = np.lexsort((r, e))
            r, e = r[order], e[order]
        return r, e

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
        delivered: list[tuple[str, np.ndarray, np.ndarray]] | None = None
        for i, m in enumerate(self.messages):
            if self._consumed_on_delivery(i):  # no receiving server: the same records as records()
                delivered = delivered or self.records()
                out.append(delivered[i])
                continue
            rel = [*self._proc_rel[i], np.asarray(self._proc_rel1[i], _I64)]
            end = [*self._proc_end[i], np.asarray(self._proc_end1[i], _I64)]
            out.append((m.name, *self._pairs(rel, end)))
        return out

    def _consumed_on_delivery(self, i: int) -> bool:
        """Every delivery of message i was consumed as it arrived (the same arrays and values in both records)."""
        same = len(self._proc_rel[i]) == len(self._rel[i]) and all(
            a is b and c is d
            for a, b, c, d in zip(self._proc_rel[i], self._rel[i], self._proc_end[i], self._end[i])
        )
        return same and self._proc_end1[i] == self._end1[i] and self._proc_rel1[i] == self._rel1[i]

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
                for i, k in counts_by_index(msg[rel < self.duration]):
                    n[i] += k * self.downstream[(i, link.index)]
            for _, r, i, _ in link.waiting:
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
                    "queue_frames": link.queue_frames,
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
