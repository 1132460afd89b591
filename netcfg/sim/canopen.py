"""A CANopen bus's master and drives (seed 000, sections 4.4 and 5).

PDO mode, the paper's Figure 7: the master is the live one, netcfg.runtime.canopen_master.MasterCycle, unchanged,
on the simulator's python-can bus and clock (netcfg.sim.pybus), so what is simulated is the code that runs on the
robot. The spec gives its timing: its SYNC task's BCET..WCET is the computation of each cycle (drawn per cycle),
and the bus's master_jitter bounds how late each of its waits ends (drawn per wait); the cycle is anchored
(drift_free), as the analysis assumes. Drives answer each SYNC with their synchronous TPDOs (transmission type n:
every n-th SYNC) after their processing delay, and their tasks that run on SYNC start their offset after its
reception.

SDO mode, the earlier approach the paper compares with (section 4.2, [8]): one concurrent loop per joint reads
three objects by confirmed SDO uploads (request 0x600 + node id, response 0x580 + node id) and a movement loop
writes commands by SDO; all of them share the master's processor, so samples come at a variable period.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from netcfg.cia301 import NMT_STATE_OPERATIONAL, SDO_RX_BASE, SDO_TX_BASE, sync_every
from netcfg.runtime import Bus, Task
from netcfg.runtime.canopen_master import CycleRecord, MasterCycle, MasterRun
from netcfg.runtime.supervision import Supervisor
from netcfg.sim.can_bus import CanBus
from netcfg.sim.canopen_drills import DrillPlayer
from netcfg.sim.engine import NEVER
from netcfg.sim.stats import spread

if TYPE_CHECKING:
    from netcfg.sim.pybus import Program
    from netcfg.sim.run import SimRun

K = TypeVar("K")
V = TypeVar("V")

SDO_OBJECTS_PER_READ = 3  # position, velocity, current (seed 000, section 4.2)
SDO_TIMEOUT_NS = 300_000_000  # the canopen package's default SDO response timeout (SdoClient.RESPONSE_TIMEOUT)


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
        # the run starts with every node started (NMT start precedes it): their heartbeats say OPERATIONAL
        for m in msgs:
            if m.implicit == "heartbeat" and m.name in can.by_name:
                can.by_name[m.name].rest = bytes([NMT_STATE_OPERATIONAL])
        # the master's own SYNC tasks are its computation, run by the live master (work_s), not on SYNC reception
        self.master_tasks = [t for t in sc.cfg.node(self.master).tasks if t.sync_bus == bus.name]
        self.samples: dict[str, list[int]] = {d: [] for d in self.drives}  # SDO mode: drive -> instants of samples
        self.missing: dict[str, int] = {d: 0 for d in self.drives}
        self._sync_count = 0
        # who answers a SYNC, grouped by how long after its reception: (delay, [(every n-th SYNC, when its producer
        # crashes, the TPDO's source on the bus)])
        self._answers: list[tuple[int, list[tuple[int, int, int, str]]]] | None = None
        # tasks a SYNC starts, grouped by how long after its reception they start: (after, [task])
        self._sync_tasks: list[tuple[int, list[Task]]] = []
        self.sdo_timeouts: dict[str, int] = {}  # drive -> SDO transfers that timed out and were repeated
        self._cpu_free = 0  # the master's one processor, shared by the SDO loops
        self.run: MasterRun | None = None
        self.supervisor: Supervisor | None = None
        self._lead = 0.0  # how long after a cycle's start its SYNC is due (MasterCycle.sync_lead_s)
        self.drills = DrillPlayer(self)  # `--fault KIND:ARG` drills on this bus (netcfg.sim.canopen_drills)
        if self.mode in ("pdo", "external"):
            sc.listen(self.sync.name, self._on_sync)
        elif self.mode == "sdo":
            self._sdo_sources()
        else:
            raise ValueError(f"CANopen master mode must be pdo, sdo or external, not {self.mode!r}")

    def _drive_delay(self, drive: str) -> int:
        d = self.sc.opts.drive_delay_ns
        return d if d is not None else self.sc.cfg.node(drive).tx_delay_ns

    def start(self) -> None:
        if self.mode == "sdo":
            self._start_sdo(self.sc.clock[self.master].phase_ns)

    # -- PDO mode: the live master (Figure 7) --------------------------------------------------------------
    @property
    def live(self) -> bool:
        """This bus's master is the live MasterCycle, run by drive()."""
        return self.mode == "pdo"

    @property
    def start_ns(self) -> int:
        return self.sc.clock[self.master].phase_ns

    def drive(self, until_ns: int, host: Program | None = None) -> None:
        """Run the live master until its next cycle would start at or after `until_ns` (its last cycle ends at most
        one period later); the whole simulation advances as it waits. `host`: when it shares the run with others,
        in a thread of its own (netcfg.sim.pybus.run_programs), which starts it at start_ns."""
        from netcfg.sim.pybus import SimCanBus, VirtualClock

        sc = self.sc
        if host is None:
            sc.sim.run_until(self.start_ns)
        pybus = SimCanBus(sc, self.bus.name, node=self.master, host=host)
        clock = VirtualClock(sc, host)
        # the live master's supervision too: heartbeats against their consumer times, EMCY (as `netcfg run` has it)
        supervisor = self.supervisor = Supervisor(sc.cfg, self.bus, [d for d in self.drives if self._watched(d)])

        drills = self.drills

        def after_cycle(record: CycleRecord) -> bool:
            go = drills.after_cycle(record) if drills else True
            supervisor.check(record.read_done)
            return drills.react(record) and go if drills else True

        try:
            cycle = MasterCycle(
                sc.cfg,
                pybus,
                clock,
                bus_name=self.bus.name,
                drift_free=True,  # anchored, as the analysis assumes (SYNC k within master_jitter of its instant)
                pause_gc=True,  # as on the robot: no collection in the loop (in virtual time, only a speed-up)
                collect_after=False,  # nor a full one after it: a Monte Carlo batch or a sweep runs many masters
                timing=self,
                on_frame=supervisor.feed,
                after_cycle=after_cycle,
            )
            self._lead = cycle.sync_lead_s
            if drills:
                drills.bind(cycle, pybus, clock, supervisor)
            supervisor.start(clock.now())
            self.run = cycle.run(1 << 62, until_s=until_ns / 1e9)
        finally:
            pybus.shutdown()

    def _watched(self, drive: str) -> bool:
        node = self.sc.cfg.node(drive)
        return node.role != "master" and node.node_id is not None

    def work_s(self, cycle: int) -> float:
        """The master's computation this cycle: its SYNC tasks, each for a time between its BCET and WCET."""
        sc = self.sc
        if not sc.alive(self.master):
            return 0.0
        now_s = sc.sim.now / 1e9
        work = 0
        for task in self.master_tasks:
            start = sc.sim.now + work
            work += sc.exec_ns(task)
            # it ends where the clock will land: the same float arithmetic as MasterCycle's sleep_until(now + work)
            sc.task_ran(task, start, max(start, round((now_s + work / 1e9) * 1e9)))
        return work / 1e9

    def late_s(self) -> float:
        jitter = self.co.master_jitter_ns
        return int(self.sc.rng.integers(0, jitter + 1)) / 1e9 if jitter else 0.0

    def _on_sync(self, end: int, _src: int, _release: int, _data: bytes | None) -> None:
        """The drives answer and start their SYNC tasks: one event per instant at which something happens (the
        answers of drives with the same delay go out in the same instant, in the order they were listed)."""
        sc = self.sc
        self._sync_count += 1
        n = self._sync_count
        answers = self._answers
        if answers is None:  # who answers a SYNC and how late, looked up at the first one
            answers = self._answers = _grouped(
                (
                    self._drive_delay(m.producer),
                    (self.every[m.name], sc.crash_at.get(m.producer, NEVER), sc.msg_source[m.name][1], m.producer),
                )
                for m in self.tpdos
            )
            self._sync_tasks = _runs(
                (sc.cfg.node(task.node).rx_delay_ns + task.offset_ns, task)
                for task in sc.tasks_on_sync(self.bus.name)
                if task.node != self.master  # the master's computation, which the live master runs (work_s)
            )
        at = sc.sim.at
        for delay, tpdos in answers:
            stopped = self.drills.stopped  # drives an NMT command stopped (a drill's reaction)
            due = [
                (crash, src)
                for every, crash, src, producer in tpdos
                if n % every == 0 and end < crash and (not stopped or end < stopped.get(producer, NEVER))
            ]
            if due:
                at(end + delay, self._tpdos, due)
        now = sc.sim.now
        for after, tasks in self._sync_tasks:
            if end + after > now:
                at(end + after, self._start_tasks, tasks)
            else:
                self._start_tasks(tasks)

    def _tpdos(self, due: list[tuple[int, int]]) -> None:
        """The drives' answers: (when the producer crashes, the TPDO's source); a crashed drive's is lost."""
        can, now = self.can, self.sc.sim.now
        for crash, src in due:
            if now < crash:
                can.submit(src)
            else:
                can.drop(src)

    def _start_tasks(self, tasks: list[Task]) -> None:
        for task in tasks:
            self.sc.run_task(task)

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
        if self.mode == "sdo":
            out["drives"] = {
                drive: self._drive_report([t / 1000 for t in times], self.missing[drive], drive)
                for drive, times in self.samples.items()
            }
            return out
        run = self.run
        if run is None:  # "external": a program ran its own master
            return out
        missing = run.missing_by_node()
        sampled = _sample_starts(run, self.drives)
        out["drives"] = {
            drive: self._drive_report(sampled[drive], missing.get(drive, 0), drive) for drive in self.drives
        }
        starts = np.asarray([1e6 * rec.start for rec in run.records])
        out["cycles"] = run.cycles
        out["incomplete_cycles"] = sum(1 for rec in run.records if rec.missing)
        if len(starts) > 1:
            out["cycle_period_us"] = spread(np.diff(starts))
        # an overrun: the SYNC left later than its instant (plus the wake-up latency), or the cycle outgrew its period
        slack_s = (self.co.master_jitter_ns + 1000) / 1e9  # 1 us for float rounding of the clock
        late = [
            rec
            for rec in run.records
            if (self._lead > 0 and rec.sync_sent - rec.start > self._lead + slack_s)
            or rec.period_s > run.period_s + slack_s
        ]
        out["overruns"] = len(late)
        out["late_frames"] = run.late
        if self.supervisor is not None and self.supervisor.events:  # a crashed drive's silence, an EMCY
            out["supervision"] = [
                {"time_s": round(e.time, 6), "node": e.node, "kind": e.kind, "action": e.action, "text": e.text}
                for e in self.supervisor.events
            ]
        findings = []
        if late:
            longest = max(rec.processing_s for rec in late)
            findings.append(
                f"the master overran its {period / 1e6:g} ms period in {len(late)} of {run.cycles} cycles "
                f"(processing up to {1e3 * longest:.2f} ms with {len(self.rpdos)} RxPDO writes): its SYNC is not "
                "periodic, so flows over this bus may leave the analysed bounds"
            )
        done = [1e6 * rec.read_s for rec in run.records]
        if done:
            out["collection_us"] = spread(np.asarray(done))
        violations, as_analysed = self._held_to_analysis(run, out)
        findings += as_analysed
        self.drills.report(out)
        findings += self.drills.findings
        if findings:
            out["findings"] = findings
        if violations:
            out["violations"] = violations
        return out

    def _held_to_analysis(self, run: MasterRun, out: dict[str, object]) -> tuple[list[str], list[str]]:
        """The cycles held against the SYNC-cycle analysis: its bound (runtime.json's sync_completion_ns, from
        SYNC's queueing to the last due TPDO's end) against each complete cycle's SYNC -> last TPDO, and the read
        window it was checked to fit against every incomplete cycle (a due TPDO of a drive in service not in by
        the window's end) and every late TPDO (one queued before the next SYNC, an answer to an earlier one).
        With a bound beyond the window (a refused spec, simulated with --force) those are what was analysed:
        findings, not violations. Returns (violations, findings); the measured and analysed figures go into `out`."""
        bound = self.co.sync_completion_ns
        window = round(run.read_window_s * 1e9)
        quiet = self.drills.quiet_from  # a crashed, rebooted or stopped drive's TPDOs are not due
        incomplete = sum(
            1
            for rec in run.records
            if rec.sync_ok and any(round(rec.sync_sent * 1e9) < quiet(run.producers[m]) for m in rec.missing)
        )
        # a SYNC or TPDO a `lose` fault took leaves one cycle incomplete: the fault's doing, not the timing's
        incomplete = max(0, incomplete - self._lost_by_faults())
        complete = [round(rec.read_s * 1e9) for rec in run.records if rec.due and not rec.missing]
        measured = max(complete, default=None)
        out["sync_completion_us"] = {
            "max": None if measured is None else measured / 1000,
            "analysed": None if bound is None else bound / 1000,
        }
        violations: list[str] = []
        findings: list[str] = []
        if incomplete or run.late:
            text = (
                f"{incomplete} of {run.cycles} SYNC cycles incomplete (a due TPDO not in by the end of the "
                f"{window / 1000:g} us read window), {run.late} TPDOs after their window"
            )
            if bound is not None and bound <= window:
                violations.append(f"{text}; the analysis bounds the last TPDO at {bound / 1000:g} us after SYNC")
            else:
                analysed = "no bound" if bound is None else f"{bound / 1000:g} us"
                findings.append(f"{text}, as analysed (the last TPDO at {analysed} after SYNC)")
        if measured is not None and bound is not None and measured > bound:
            violations.append(f"SYNC -> last TPDO took up to {measured / 1000:g} us, analysed {bound / 1000:g} us")
        return violations, findings

    def _lost_by_faults(self) -> int:
        """This bus's SYNC and synchronous TPDO frames that `lose` faults took."""
        names = {self.sync.name} | {m.name for m in self.tpdos}
        aimed = sum(1 for f in self.sc.opts.faults if f.kind == "lose" and f.target in names)
        left = sum(len(self.can.lose.get(self.sc.msg_source[name][1], ())) for name in names)
        return aimed - left

    def _drive_report(self, times_us: list[float], missing: int, drive: str) -> dict[str, object]:
        period_us = self.co.sync_period_ns / 1000
        gaps = np.diff(np.asarray(times_us)) if len(times_us) > 1 else np.empty(0)
        return {
            "samples": len(times_us),
            "missing_frames": missing,
            "sdo_timeouts": self.sdo_timeouts.get(drive, 0),
            "period_us": spread(gaps) if len(gaps) else None,
            "period_error_us": spread(gaps - period_us) if len(gaps) else None,
        }


def _grouped(pairs: Iterable[tuple[K, V]]) -> list[tuple[K, list[V]]]:
    """Values grouped by key, keys in the order of their first value, values in their order."""
    groups: dict[K, list[V]] = {}
    for key, value in pairs:
        groups.setdefault(key, []).append(value)
    return list(groups.items())


def _runs(pairs: Iterable[tuple[K, V]]) -> list[tuple[K, list[V]]]:
    """Values in their order, in runs of the same key (tasks: one that starts at once may schedule something,
    so tasks that start later are not merged across it)."""
    runs: list[tuple[K, list[V]]] = []
    for key, value in pairs:
        if runs and runs[-1][0] == key:
            runs[-1][1].append(value)
        else:
            runs.append((key, [value]))
    return runs


def _sample_starts(run: MasterRun, drives: list[str]) -> dict[str, list[float]]:
    """Per drive, the starts (us) of the cycles that sampled it: the drive's TPDOs due in the cycle all arrived.
    Which drive is due for which TPDOs is worked out once per pattern of due TxPDOs, not per cycle and drive."""
    out: dict[str, list[float]] = {d: [] for d in drives}
    by_due: dict[tuple[str, ...], dict[str, set[str]]] = {}
    for rec in run.records:
        due = by_due.get(rec.due)
        if due is None:
            due = by_due[rec.due] = {}
            for m in rec.due:
                due.setdefault(run.producers[m], set()).add(m)
        start = 1e6 * rec.start
        lost = set(rec.missing)
        for drive, msgs in due.items():
            if drive in out and not (lost and msgs & lost):
                out[drive].append(start)
    return out
