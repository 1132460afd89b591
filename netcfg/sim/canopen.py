"""A CANopen master and its drives (seed 000, sections 4.4 and 5).

PDO mode, the paper's Figure 7, one loop per period T:
  write the RxPDOs (each costs a write processing time), send SYNC, collect the synchronous TxPDOs until all
  arrived or the read window ends, process them (a read processing time), then wait dynamically
  (waiting = T - Pt - K, with a residual error) so the next cycle starts T after this one.
Drives answer each SYNC with their synchronous TxPDOs (transmission type n: every n-th SYNC) after their
processing delay, and tasks that run on SYNC start their offset after its reception.

SDO mode, the earlier approach the paper compares with (section 4.2, [8]): one concurrent loop per joint reads
three objects by confirmed SDO uploads (request 0x600 + node id, response 0x580 + node id) and a movement loop
writes commands by SDO; all of them share the master's processor, so samples come at a variable period.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from netcfg.cia301 import SDO_RX_BASE, SDO_TX_BASE, sync_every
from netcfg.runtime import Bus, Message
from netcfg.sim.can_bus import CanBus
from netcfg.sim.stats import spread

if TYPE_CHECKING:
    from netcfg.sim.run import SimRun

SDO_OBJECTS_PER_READ = 3  # position, velocity, current (seed 000, section 4.2)
SDO_TIMEOUT_NS = 300_000_000  # the canopen package's default SDO response timeout (SdoClient.RESPONSE_TIMEOUT)


@dataclass
class Cycle:
    start: int
    sync_queued: int | None = None
    done: int = 0  # collection finished (all arrived, or the read window ended)
    received: set[str] = field(default_factory=set)
    expected: tuple[str, ...] = ()


class CanopenMaster:
    def __init__(self, sc: SimRun, bus: Bus, can: CanBus) -> None:
        assert bus.canopen is not None
        self.sc = sc
        self.bus = bus
        self.can = can
        self.co = co = bus.canopen
        self.mode = sc.opts.canopen
        msgs = sc.cfg.messages_on(bus.name)
        self.master = co.sync_producer
        self.sync = next(m for m in msgs if m.implicit == "SYNC")
        self.rpdos = [m for m in msgs if m.pdo is not None and m.pdo.kind == "rpdo" and m.producer == self.master]
        every = {m.name: sync_every(m.pdo.transmission) for m in msgs if m.pdo is not None and m.pdo.kind == "tpdo"}
        # TPDOs answering SYNC, every how many SYNCs; type 0 answers every SYNC here, its worst case
        self.every = {name: n for name, n in every.items() if n is not None}
        self.tpdos = [m for m in msgs if m.name in self.every]
        self.drives = sorted({m.producer for m in self.tpdos} | {c for m in self.rpdos for c in m.consumers})
        self.owned = {self.sync.name} | {m.name for m in self.rpdos} | {m.name for m in self.tpdos}
        self.cycles: list[Cycle] = []
        self.samples: dict[str, list[int]] = {d: [] for d in self.drives}  # drive -> instants of complete samples
        self.missing: dict[str, int] = {d: 0 for d in self.drives}
        self._sync_count = 0
        self.late: dict[str, int] = {}  # TPDO -> answers that came after their cycle's read window
        self.sdo_timeouts: dict[str, int] = {}  # drive -> SDO transfers that timed out and were repeated
        self.overruns = 0  # cycles whose processing took longer than the period
        self.longest_ns = 0
        self._cpu_free = 0  # the master's one processor, shared by the SDO loops
        if self.mode in ("pdo", "external"):
            sc.listen(self.sync.name, self._on_sync)
            for m in self.tpdos:
                sc.listen(m.name, self._on_tpdo)
        elif self.mode == "sdo":
            self._sdo_sources()
        else:
            raise ValueError(f"CANopen master mode must be pdo, sdo or external, not {self.mode!r}")

    # -- timing draws -----------------------------------------------------------------------------------
    def _draw(self, spec: tuple[int, int, int, int]) -> int:
        mean, std, lo, hi = spec
        return int(np.clip(self.sc.rng.normal(mean, std), lo, hi))

    def _drive_delay(self, drive: str) -> int:
        d = self.sc.opts.drive_delay_ns
        return d if d is not None else self.sc.cfg.node(drive).tx_delay_ns

    def start(self) -> None:
        first = self.sc.clock[self.master].phase_ns
        if self.mode == "pdo":
            self.sc.sim.at(first, self._cycle)
        elif self.mode == "sdo":
            self._start_sdo(first)

    # -- PDO mode: Figure 7 -----------------------------------------------------------------------------
    def _cycle(self, _: object = None) -> None:
        sc = self.sc
        if not sc.alive(self.master):
            return
        cyc = Cycle(start=sc.sim.now)
        self.cycles.append(cyc)
        t = sc.sim.now
        first = len(self.cycles) == 1
        for m in self.rpdos:
            if m.kind == "on-demand" and not first:
                continue  # written once, at the start (the interpolation time of seed 000, section 4.4.1)
            t += self._draw(sc.opts.master.write)
            sc.sim.at(t, self._write, m)
        sc.sim.at(t, self._send_sync, cyc)

    def _write(self, m: Message) -> None:
        self.sc.submit(m.name)

    def _send_sync(self, cyc: Cycle) -> None:
        sc = self.sc
        cyc.sync_queued = sc.sim.now
        n = len(self.cycles)  # this cycle's SYNC is the n-th: a TPDO of type k answers every k-th (CiA 301)
        cyc.expected = tuple(m.name for m in self.tpdos if n % self.every[m.name] == 0)
        sc.submit(self.sync.name)
        window = self.co.collect_window_ns()
        sc.sim.at(sc.sim.now + window, self._read_window_over, cyc)

    def _on_sync(self, end: int, _src: int, _release: int, _data: bytes | None) -> None:
        sc = self.sc
        self._sync_count += 1
        n = self._sync_count
        for m in self.tpdos:
            if n % self.every[m.name] == 0 and sc.alive(m.producer):
                sc.sim.at(end + self._drive_delay(m.producer), self._tpdo, m)
        for task in sc.tasks_on_sync(self.bus.name):
            node = sc.cfg.node(task.node)
            sc.run_task(task, end + node.rx_delay_ns + task.offset_ns)

    def _tpdo(self, m: Message) -> None:
        self.sc.submit(m.name)

    def _on_tpdo(self, end: int, src: int, release: int, _data: bytes | None) -> None:
        name = self.can.sources[src].name
        cyc = self.cycles[-1] if self.cycles else None
        if cyc is None or cyc.done or cyc.sync_queued is None or release < cyc.sync_queued:
            # an answer to an earlier SYNC, after its read window: late, not a sample of this cycle
            self.late[name] = self.late.get(name, 0) + 1
            return
        cyc.received.add(name)
        if cyc.expected and all(n in cyc.received for n in cyc.expected):
            self._collected(cyc)

    def _read_window_over(self, cyc: Cycle) -> None:
        if not cyc.done:
            self._collected(cyc)

    def _collected(self, cyc: Cycle) -> None:
        sc = self.sc
        cyc.done = sc.sim.now
        for drive in self.drives:
            exp = [n for n in cyc.expected if sc.cfg.message(n).producer == drive]
            got = [n for n in exp if n in cyc.received]
            if exp and len(got) == len(exp):
                self.samples[drive].append(cyc.start)
            self.missing[drive] += len(exp) - len(got)
        t = sc.sim.now + self._draw(sc.opts.master.read)
        pt = t - cyc.start
        if pt > self.co.sync_period_ns:
            self.overruns += 1  # the next SYNC comes late: the master cannot keep its period
            self.longest_ns = max(self.longest_ns, pt)
        waiting = max(0, self.co.sync_period_ns - pt - sc.opts.master.k_ns)
        mean, std = sc.opts.master.wait_error
        err = int(sc.rng.normal(mean, std))
        sc.sim.at(max(t, t + waiting + err), self._cycle)

    # -- SDO mode ---------------------------------------------------------------------------------------
    def _sdo_sources(self) -> None:
        sc, can = self.sc, self.can
        for drive in self.drives:
            nid = sc.cfg.node(drive).node_id or 0
            req = can.add_source(f"{drive}_sdo_request", SDO_RX_BASE + nid, False, 8, self.master)
            rsp = can.add_source(f"{drive}_sdo_response", SDO_TX_BASE + nid, False, 8, drive)
            sc.msg_source[f"{drive}_sdo_request"] = (can, req)
            sc.msg_source[f"{drive}_sdo_response"] = (can, rsp)
            can.listen(req, self._sdo_served)
            can.listen(rsp, self._sdo_answered)
        # per drive, the confirmed transfers waiting for its SDO server (one at a time); the first is in flight
        self._transfers: dict[str, list[tuple[int, Callable[[int], None]]]] = {d: [] for d in self.drives}
        self._read_start: dict[str, int] = {}
        self._inflight: dict[str, int] = {}  # drive -> token of the request awaiting an answer

    def _cpu(self, work: int) -> int:
        """Run `work` ns on the master's processor (first come, first served); returns when it is done."""
        start = max(self.sc.sim.now, self._cpu_free)
        self._cpu_free = start + work
        return self._cpu_free

    def _transfer(self, drive: str, work: int, then: Callable[[int], None]) -> None:
        queue = self._transfers[drive]
        queue.append((work, then))
        if len(queue) == 1:
            self._issue(drive)

    def _issue(self, drive: str) -> None:
        work = self._transfers[drive][0][0]
        self.sc.sim.at(self._cpu(work), self._request, drive)

    def _request(self, drive: str) -> None:
        self._inflight[drive] = self._inflight.get(drive, 0) + 1
        self.sc.submit(f"{drive}_sdo_request")
        self.sc.sim.at(self.sc.sim.now + SDO_TIMEOUT_NS, self._sdo_timeout, (drive, self._inflight[drive]))

    def _sdo_timeout(self, arg: tuple[str, int]) -> None:
        """No answer in time: the client gives up on this request and sends it again (a real client would abort
        the transfer and the application repeat it)."""
        drive, token = arg
        if self._inflight.get(drive) == token and self._transfers[drive]:
            self.sdo_timeouts[drive] = self.sdo_timeouts.get(drive, 0) + 1
            self._request(drive)

    def _sdo_served(self, end: int, src: int, _release: int, _data: bytes | None) -> None:
        drive = self.can.sources[src].name.removesuffix("_sdo_request")
        if self.sc.alive(drive):
            self.sc.sim.at(end + self._drive_delay(drive), self._respond, drive)

    def _respond(self, drive: str) -> None:
        self.sc.submit(f"{drive}_sdo_response")

    def _sdo_answered(self, end: int, src: int, _release: int, _data: bytes | None) -> None:
        drive = self.can.sources[src].producer
        queue = self._transfers[drive]
        if not queue:
            return  # a late answer to a request already repeated and served
        self._inflight[drive] = self._inflight.get(drive, 0) + 1  # the pending timeout no longer applies
        _, then = queue.pop(0)
        if queue:
            self._issue(drive)
        then(end)

    def _start_sdo(self, first: int) -> None:
        for drive in self.drives:
            self.sc.sim.at(first, self._read_joint, drive)
        self.sc.sim.at(first, self._move)

    def _read_joint(self, drive: str) -> None:
        """Read one sample: three confirmed uploads in a row, then the next read one period after this one."""
        start = self.sc.sim.now
        work = self.sc.opts.master.sdo_read_ns

        def step(left: int) -> Callable[[int], None]:
            def done(end: int) -> None:
                if left > 1:
                    self._transfer(drive, work, step(left - 1))
                    return
                self.samples[drive].append(start)
                self.sc.sim.at(max(end, start + self.co.sync_period_ns), self._read_joint, drive)

            return done

        self._transfer(drive, work, step(SDO_OBJECTS_PER_READ))

    def _move(self, _: object = None) -> None:
        """The movement loop: compute and write every joint's command by SDO (Table 3's processing time for the
        whole write), once per period at most, on the same processor as the reading loops."""
        start = self.sc.sim.now
        left = len(self.drives)

        def done(_end: int) -> None:
            nonlocal left
            left -= 1
            if left == 0:
                self.sc.sim.at(max(self.sc.sim.now, start + self.co.sync_period_ns), self._move)

        for i, drive in enumerate(self.drives):
            self._transfer(drive, self.sc.opts.master.sdo_write_ns if i == 0 else 0, done)

    # -- report -----------------------------------------------------------------------------------------
    def report(self) -> dict[str, object]:
        period = self.co.sync_period_ns
        out: dict[str, object] = {"mode": self.mode, "period_us": period / 1000}
        per_drive: dict[str, object] = {}
        for drive, times in self.samples.items():
            gaps = np.diff(np.asarray(times, dtype=np.int64)) if len(times) > 1 else np.empty(0, np.int64)
            err = (gaps - period) / 1000 if len(gaps) else gaps
            per_drive[drive] = {
                "samples": len(times),
                "missing_frames": self.missing[drive],
                "sdo_timeouts": self.sdo_timeouts.get(drive, 0),
                "period_us": spread(gaps / 1000) if len(gaps) else None,
                "period_error_us": spread(err) if len(gaps) else None,
            }
        out["drives"] = per_drive
        if self.mode == "pdo":
            starts = np.asarray([c.start for c in self.cycles], dtype=np.int64)
            out["cycles"] = len(self.cycles)
            out["incomplete_cycles"] = sum(1 for c in self.cycles if c.done and set(c.expected) - c.received)
            if len(starts) > 1:
                out["cycle_period_us"] = spread(np.diff(starts) / 1000)
            out["overruns"] = self.overruns
            out["late_frames"] = sum(self.late.values())
            if self.overruns:
                out["findings"] = [
                    f"the master overran its {period / 1e6:g} ms period in {self.overruns} of {len(self.cycles)} "
                    f"cycles (processing up to {self.longest_ns / 1e6:.2f} ms with {len(self.rpdos)} RxPDO writes): "
                    "its SYNC is not periodic, so flows over this bus may leave the analysed bounds"
                ]
            done = [c.done - c.sync_queued for c in self.cycles if c.done and c.sync_queued is not None]
            if done:
                out["collection_us"] = spread(np.asarray(done) / 1000)
        return out
