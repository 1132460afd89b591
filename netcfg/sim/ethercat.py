"""An EtherCAT segment in the simulation: the master's cyclic frames through the slaves in wire order, each slave's
delays and cables, the master's send jitter, distributed clocks' SYNC0 events against the frame's passing, and a
lost frame or a lost slave seen as the master sees it, a working-counter mismatch. Only runtime.json's EtherCAT
section is read (netcfg.protocols.ethercat.runtime_section), and the run is held against the analysis' bounds it
carries.

Time is the reference clock's (the first DC slave's): the master's cycle is locked to it, as SOEM's and IgH's DC
modes lock it, so cycle n starts at n * cycle. Per cycle:

- the master sends the first frame of the image late by a draw in [0, master_jitter]; the image's frames (each one
  LRW datagram, runtime.json's `frames`) follow back to back, each its bytes on the wire at the bus's bit rate;
- a slave's `forwarding_ns` is what it adds to the round trip (the analysis' figure): half on the way out, through
  its EtherCAT processing unit, half on the way back alongside it (ESCs' processing and forwarding delays differ
  by a few tens of ns: Beckhoff, EtherCAT Slave Controller Section I, "Propagation delay"). Each pass is shorter by
  a draw in [0, 40 ns): the 25 MHz receive clock of 100BASE-TX's MII (IEEE 802.3 clause 22) sets the phase at
  which a frame enters the slave's receive FIFO. Cables take their length at 0.7 c (netcfg.timing.ethernet);
- the frame's end has passed slave k once its last byte has left k's processing unit; it is back at the master
  after the last slave's loop-back and the way back;
- a DC slave's SYNC0 fires at n * cycle + its shift on its own clock, which distributed clocks hold to the
  reference within `dc_precision_ns`: a fixed offset per slave (what the propagation-delay compensation leaves)
  and a jitter per event, each drawn within half of it; the slave's oscillator drifts by its node's drift, which
  the ESC's drift compensation removes between the master's system-time writes (each cycle);
- the working counter of each frame: +2 from every slave whose outputs it writes and +1 from every slave whose
  inputs it reads (ETG.1000.4's LRW); a lost frame (`--fault lose:BUS@t`) comes back with none, and a crashed
  slave (`crash:NODE@t`) breaks the line there: its neighbour closes the port and loops the frame back, without
  the slaves behind it; a crashed master sends no more cycles.

What is held against the analysis: the frame back at the master within `latency_ns`, its passing each slave within
that slave's `frame_passed_ns`, and, where the analysis found the shift long enough, every SYNC0 after the frame
has passed. Lost frames and mismatches are findings: the analysis assumes none.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from netcfg.runtime import Bus, Task
from netcfg.sim.engine import NEVER, TASKS
from netcfg.timing.ethernet import PROPAGATION_M_PER_S

if TYPE_CHECKING:
    from netcfg.sim.run import SimRun

RX_CLOCK_NS = 40  # 100BASE-TX's MII receive clock, 25 MHz: a nibble every 40 ns
MISMATCHES_SHOWN = 5
DEFAULT_FORWARDING_NS = 1000  # a runtime.json written before the key: the analysis' default of its time
CHUNK = 20_000  # cycles computed at once: a long run's arrays stay a few MB


class _Tally:
    """What a run's windows of cycles add up to."""

    def __init__(self, slaves: int) -> None:
        self.samples = 0
        self.latency_sum = 0.0
        self.latency_sq = 0.0
        self.latency_min = float("inf")
        self.latency_max = float("-inf")
        self.lost = 0
        self.mismatched = 0
        self.mismatches: list[dict[str, Any]] = []
        self.passed = [-1] * slaves  # ns after the cycle's start, the latest seen
        self.margin = [float("inf")] * slaves  # SYNC0 after the frame's passing, the least seen
        self.early = [0] * slaves  # SYNC0 events before the frame had passed
        self.dc_error = [(float("inf"), float("-inf"))] * slaves

    def add_latency(self, x: np.ndarray) -> None:
        if len(x):
            self.samples += len(x)
            self.latency_sum += float(x.sum())
            self.latency_sq += float((x * x).sum())
            self.latency_min = min(self.latency_min, float(x.min()))
            self.latency_max = max(self.latency_max, float(x.max()))

    def latency_us(self) -> dict[str, float]:
        mean = self.latency_sum / self.samples
        std = max(self.latency_sq / self.samples - mean * mean, 0.0) ** 0.5
        return {k: round(v / 1000, 3) for k, v in
                (("min", self.latency_min), ("mean", mean), ("std", std), ("max", self.latency_max))}


class EthercatSegment:
    """The cyclic frames of one EtherCAT bus, computed a cycle per row (nothing feeds back into them)."""

    def __init__(self, sc: SimRun, bus: Bus) -> None:
        assert bus.ethercat is not None
        self.sc, self.bus = sc, bus
        self.ec: Mapping[str, Any] = bus.ethercat
        self.slaves: list[Mapping[str, Any]] = list(self.ec["slaves"])
        self.lose_at: list[int] = []  # lose:BUS@t: the first cycle sent at or after t loses its frame
        self.result: dict[str, Any] | None = None
        self._acc = _Tally(len(self.slaves))
        self._master_stopped = False

    # -- faults -----------------------------------------------------------------------------------------
    def lose_cycle_at(self, at_ns: int) -> None:
        self.lose_at.append(at_ns)

    # -- the run ----------------------------------------------------------------------------------------
    def start(self) -> None:
        """Every cycle of the run, as arrays of cycles x slaves, a window of CHUNK cycles at a time."""
        ec, sc = self.ec, self.sc
        cycle = int(ec["cycle_ns"])
        until = min(sc.opts.duration_ns, sc.crash_at.get(ec.get("master") or "", NEVER))  # a crashed master sends none
        n = max(0, -(-until // cycle))
        self._master_stopped = until < sc.opts.duration_ns
        name = self.bus.name
        frames = list(ec.get("frames") or [{"data_bytes": ec["out_bytes"] + ec["in_bytes"], "wire_bytes": 0}])
        self._wire = sum(int(f["wire_bytes"]) for f in frames) * 8e9 / self.bus.bitrate
        self._fwd = np.array([s.get("forwarding_ns", DEFAULT_FORWARDING_NS) for s in self.slaves], dtype=float)
        cables = np.array([s.get("cable_m", 0.0) for s in self.slaves], dtype=float)
        self._prop = cables / PROPAGATION_M_PER_S * 1e9
        self._crash = np.array([sc.crash_at.get(s["node"], NEVER) for s in self.slaves], dtype=np.int64)
        self._expected, self._counts = self._working_counters(frames)
        self._rng = {part: sc.random(f"ethercat {name} {part}") for part in ("master", "slaves", "dc")}
        precision = float(ec.get("dc_precision_ns", 0))
        self._dc_offset = self._rng["dc"].uniform(-precision / 2, precision / 2, len(self.slaves))
        self._acc = _Tally(len(self.slaves))
        self._lost_cycles = sorted({c for c in (self._cycle_at(at, n) for at in self.lose_at) if c is not None})
        self._pdos = list(ec.get("messages") or ())
        self._deliveries: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {
            p["name"]: [] for p in self._pdos
        }
        for first in range(0, n, CHUNK):
            self._window(first, min(n, first + CHUNK), cycle)
        self.result = self._summary(n, cycle, len(frames))
        for p in self._pdos:
            self._deliver(p["name"])
        if sc.synchronised:  # unsynchronised, they run free at the cycle's period (SimRun.free_running_tasks)
            for task in sc.tasks_on_sync(name):
                self._cycle_task(task, n * cycle)

    def _cycle_at(self, at_ns: int, n: int) -> int | None:
        """The first cycle starting at or after at_ns (None: after the run)."""
        cycle = int(self.ec["cycle_ns"])
        k = -(-at_ns // cycle)
        return k if k < n else None

    def _window(self, first: int, last: int, cycle: int) -> None:
        ec, acc = self.ec, self._acc
        n, k = last - first, len(self.slaves)
        starts = np.arange(first, last, dtype=np.int64) * cycle
        send = starts + self._rng["master"].uniform(0, ec["master_jitter_ns"], n)
        draws = self._rng["slaves"]
        out_pass = np.maximum(self._fwd / 2 - draws.uniform(0, RX_CLOCK_NS, (n, k)), 0.0)  # processing direction
        back_pass = np.maximum(self._fwd / 2 - draws.uniform(0, RX_CLOCK_NS, (n, k)), 0.0)  # forwarding direction
        reached = np.cumsum(out_pass, axis=1) + np.cumsum(self._prop)[None, :]  # its last byte left slave j
        # the line is broken before the first slave that has crashed by the time the frame reaches it
        reach = send[:, None] + reached - out_pass
        alive = np.cumprod(reach < self._crash[None, :], axis=1).astype(bool)
        passed = send[:, None] + self._wire + reached
        back = send + self._wire + np.where(alive, out_pass + back_pass + 2 * self._prop[None, :], 0.0).sum(axis=1)
        lost = np.zeros(n, dtype=bool)
        for c in self._lost_cycles:
            if first <= c < last:
                lost[c - first] = True
        wkc = np.where(lost, 0, (alive * self._counts[None, :]).sum(axis=1))
        for i in np.flatnonzero(wkc != self._expected)[: max(0, MISMATCHES_SHOWN - len(acc.mismatches))]:
            missing = [s["node"] for s, ok in zip(self.slaves, alive[i]) if not ok]
            acc.mismatches.append({
                "time_us": round(float(send[i]) / 1000, 3),
                "wkc": int(wkc[i]),
                "why": "frame lost" if lost[i] else "slaves missing: " + ", ".join(missing),
            })
        acc.mismatched += int((wkc != self._expected).sum())
        acc.lost += int(lost.sum())
        got = ~lost
        acc.add_latency(np.rint(back - starts)[got])
        for p in self._pdos:  # each PDO message: its capture and its delivery, in the cycles that carried it
            j = int(p["slave"])
            seen = got & alive[:, j]
            if p["direction"] == "inputs":  # read as the datagram passes the slave, delivered with the frame's return
                capture = send + float(p["read_offset_ns"]) + reached[:, j]
                end = back
            else:  # copied as the master sends, the slave's once the frame has passed it (its check sequence good)
                capture, end = send, passed[:, j]
            self._deliveries[p["name"]].append(
                (starts[seen], np.rint(capture[seen]).astype(np.int64), np.rint(end[seen]).astype(np.int64))
            )
        precision = float(ec.get("dc_precision_ns", 0))
        dc = self._rng["dc"]
        for j, s in enumerate(self.slaves):
            seen = got & alive[:, j]
            done = np.rint(passed[seen, j] - starts[seen])
            if not len(done):
                continue
            acc.passed[j] = max(acc.passed[j], int(done.max()))
            if s["dc"]["assign_activate"]:
                error = self._dc_offset[j] + dc.uniform(-precision / 2, precision / 2, len(done))
                margin = int(s["dc"]["sync0_shift_ns"]) + error - done
                lo, hi = acc.dc_error[j]
                acc.dc_error[j] = (min(lo, float(error.min())), max(hi, float(error.max())))
                acc.margin[j] = min(acc.margin[j], float(margin.min()))
                acc.early[j] += int((margin < 0).sum())

    def _summary(self, n: int, cycle: int, frames: int) -> dict[str, Any]:
        ec, acc = self.ec, self._acc
        out: dict[str, Any] = {
            "cycle_name": "cycle",
            "cycle_us": cycle / 1000,
            "cycles": n,
            "frames_on_wire": n * frames - acc.lost,
            "lost_frames": acc.lost,
            "expected_wkc": self._expected,
            "wkc_mismatches": acc.mismatched,
            "mismatches": acc.mismatches,
        }
        violations: list[str] = []
        findings: list[str] = []
        bound = ec.get("latency_ns")
        if acc.samples:
            worst = int(acc.latency_max)
            out["latency_us"] = {**acc.latency_us(), "analysed": None if bound is None else bound / 1000}
            out["mailbox_room_us"] = round((cycle - worst) / 1000, 3)
            if bound is not None and worst > bound:
                violations.append(
                    f"the cycle's frames came back up to {worst / 1000:g} us after the cycle started, analysed "
                    f"{bound / 1000:g} us"
                )
        if self._master_stopped:
            findings.append(f"the master '{ec['master']}' crashed: no cycle after {n} cycles")
        if acc.lost or acc.mismatched:
            first = acc.mismatches[0] if acc.mismatches else None
            findings.append(
                f"{acc.mismatched} of {n} cycles with a working-counter mismatch (expected {self._expected}; "
                f"{acc.lost} frames lost)"
                + (f", the first at {first['time_us'] / 1000:.3f} ms: {first['why']}" if first else "")
            )
        precision = int(ec.get("dc_precision_ns", 0))
        slaves: dict[str, dict[str, Any]] = {}
        for j, s in enumerate(self.slaves):
            row: dict[str, Any] = slaves.setdefault(s["node"], {})
            limit = s.get("frame_passed_ns")
            if acc.passed[j] < 0:
                continue  # the frame never passed it (lost, or the slave crashed before the run)
            row["frame_passed_us"] = {"max": acc.passed[j] / 1000, "analysed": None if limit is None else limit / 1000}
            if limit is not None and acc.passed[j] > limit:
                violations.append(
                    f"the frame passed slave '{s['node']}' up to {acc.passed[j] / 1000:g} us after the cycle "
                    f"started, analysed {limit / 1000:g} us"
                )
            if s["dc"]["assign_activate"]:
                lo, hi = acc.dc_error[j]
                row["sync0_error_ns"] = {"min": round(lo, 1), "max": round(hi, 1)}
                row["sync0_margin_us"] = round(acc.margin[j] / 1000, 3)
                if acc.early[j]:
                    promised = limit is not None and int(s["dc"]["sync0_shift_ns"]) - precision >= limit
                    text = (
                        f"slave '{s['node']}': SYNC0 fired before the frame had passed in {acc.early[j]} cycles (by up "
                        f"to {-acc.margin[j] / 1000:.3f} us)" + (", analysed in time" if promised else "")
                    )
                    (violations if promised else findings).append(text)
        out["slaves"] = slaves
        if findings:
            out["findings"] = findings
        if violations:
            out["violations"] = violations
        return out

    def _working_counters(self, frames: list[Mapping[str, Any]]) -> tuple[int, np.ndarray]:
        """Each slave's share of a cycle's working counters (LRW: +2 for outputs written, +1 for inputs read, per
        frame whose datagram covers them), and their sum when every slave answers."""
        spans: list[tuple[int, int]] = []
        start = 0
        for f in frames:
            spans.append((start, start + int(f["data_bytes"])))
            start += int(f["data_bytes"])
        counts = []
        for s in self.slaves:
            c = 0
            for m in s.get("fmmu", ()):
                lo, hi = int(m["logical"]), int(m["logical"]) + int(m["length"])
                c += sum(1 for a, b in spans if lo < b and a < hi) * (2 if m["direction"] == "outputs" else 1)
            counts.append(c)
        arr = np.array(counts, dtype=np.int64)
        return int(arr.sum()), arr

    def report(self) -> dict[str, Any]:
        if self.result is None:
            self.start()
        assert self.result is not None
        return self.result

    def _delivered(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        parts = self._deliveries.get(name) or []
        if not parts:
            return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
        return tuple(np.concatenate([x[k] for x in parts]) for k in range(3))  # type: ignore[return-value]

    def _deliver(self, name: str) -> None:
        """Each delivery of a PDO message as an event, in time order: the flows it is a step of measure it (their
        data taken at the capture), and the tasks it starts run."""
        sc = self.sc
        trackers = sc.trackers_of(name)
        tasks = sc.tasks_on_message(name)  # at the delivery: a node's rx_delay is its CAN controller's, not this
        if not trackers and not tasks:
            return
        _, capture, end = self._delivered(name)
        captures, ends = capture.tolist(), end.tolist()
        k = 0

        def deliver(_: object) -> None:
            nonlocal k
            for tr in trackers:
                tr.message_delivered(name, captures[k], ends[k])
            for task in tasks:
                sc.run_task(task)
            k += 1
            if k < len(ends):
                sc.sim.at(ends[k], deliver)

        if ends:
            sc.sim.at(ends[0], deliver)

    def _cycle_task(self, task: Task, until: int) -> None:
        """A task on the cycle (`sync: true`), started every period until the master's last cycle: the master's a
        draw in [0, master_jitter] after the cycle's start and its offset (its wake-up, as for the frames), a DC
        slave's at its SYNC0 (the shift, and distributed clocks' error as for its SYNC0 check) and its offset."""
        sc, period = self.sc, int(task.period_ns or self.ec["cycle_ns"])
        rng = sc.random(f"ethercat {self.bus.name} task {task.ref}")
        k = np.arange(-(-until // period), dtype=np.int64) * period + task.offset_ns
        j = next((i for i, s in enumerate(self.slaves) if s["node"] == task.node), None)
        if j is None:
            at = k + rng.uniform(0, self.ec["master_jitter_ns"], len(k))
        else:
            precision = float(self.ec.get("dc_precision_ns", 0))
            error = self._dc_offset[j] + rng.uniform(-precision / 2, precision / 2, len(k))
            at = k + int(self.slaves[j]["dc"]["sync0_shift_ns"]) + error
        starts = np.rint(at).astype(np.int64).tolist()
        n = 0

        def fire(_: object) -> None:
            nonlocal n
            sc.run_task(task)
            n += 1
            if n < len(starts):
                sc.sim.at(starts[n], fire, None, TASKS)

        if starts:
            sc.sim.at(starts[0], fire, None, TASKS)

    def records(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """The PDO messages' deliveries from each cycle's start (results.collect holds them to their wcrt_ns, the
        analysis' latest delivery); the cyclic frame itself is the report's."""
        if self.result is None:
            self.start()
        out = []
        for p in getattr(self, "_pdos", ()):
            release, _, end = self._delivered(p["name"])
            out.append((p["name"], release, end))
        return out

    def lost_by_message(self) -> dict[str, int]:
        """The cyclic frames lost, under the bus's name: the run's lost total counts them."""
        lost = 0 if self.result is None else int(self.result["lost_frames"])
        return {f"{self.bus.name} cyclic frame": lost} if lost else {}
