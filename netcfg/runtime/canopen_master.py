"""A live CANopen master driven by runtime.json: network set-up over SDO, then the SYNC cycle of seed 000.

Two phases, as in the ALLEX-2 exoskeleton (seed 000, sections 4.3-4.4):

1. `configure_network(cfg, bus)` - the "network management" phase. For each configured slave, through the
   `canopen` package's SDO client: check the device identity (0x1018), switch it to PRE-OPERATIONAL, and for each of
   its PDOs in runtime.json disable it (COB-ID bit 31), write the communication parameters and the mapping, re-enable
   it; disable the device's other PDOs; write the start-up SDO values (the interpolation time period 0x60C2 of a
   CiA 402 drive); read everything back and compare; start the node (NMT). A node that fails is reported with what
   to do and left in PRE-OPERATIONAL; the others carry on. That holds for bus-level failures too: a frame the CAN
   interface refuses to send (python-can's can.CanError, e.g. socketcan's "Transmit buffer full" when nothing
   acknowledges on an unterminated or unpowered bus) or a receive thread that stopped (canopen re-raises its error on
   the next send) fails the node being set up, not the whole set-up. This phase may use canopen's threads (a
   python-can Notifier); it stops them before returning.

2. `MasterCycle(cfg, bus, clock).run(n)` - Figure 7: each period compute and write the RxPDOs, send SYNC, collect
   the synchronous TxPDOs until all have arrived or the read window ends, store the samples, and wait dynamically
   (eq. (1): waiting = T - Pt - K). When the spec gives the master a SYNC task, its computation starts that task's
   offset after SYNC and the SYNC waits for its instant instead of following the writes (see MasterCycle).
   It uses nothing but `bus.send(msg)`, `bus.recv(timeout)` and the clock (no
   threads, no time module, no Notifier), so the same code runs in real time (SystemClock, any python-can bus) and in
   virtual time (a simulator's clock, and a bus whose recv(timeout) advances that clock; recv(0) must not wait).
   Such a bus overrides recv() itself, not just _recv_internal(): python-can's BusABC.recv() re-checks the timeout
   against the wall clock and would call _recv_internal() again until real time has passed.

Identifiers, mappings, periods and windows all come from runtime.json, and so do the device facts: the expected
identity (node.identity), the COB-ID values (pdo.cob_id), how many PDOs the device has (node.rpdo_count/tpdo_count)
and the start-up SDO writes (node.sdo_init). A runtime.json written before those keys lacks them; the master then
does what it did before they existed: the identity from the node's generated EDS/DCF (`identities_from_dir`), the
COB-ID flag bits netcfg's DCF uses, PDOs 1-4 of the pre-defined connection set, and 0x60C2 = the SYNC period.

Where the pieces are: canopen_setup (phase 1 over SDO), canopen_identity (what 0x1018 must hold),
canopen_network (the bus and its slaves), canopen_records (what a cycle run records and its statistics), and this
module (phase 2, MasterCycle); the names of all of them are importable from here. They import only the standard
library, python-can, canopen, netcfg.runtime and netcfg.cia301 (the standard's numbers, which import nothing).
"""

from __future__ import annotations

import gc
import math
from collections import Counter
from collections.abc import Callable, Iterable, Mapping

import can

from netcfg import cia301
from netcfg.runtime import Bus, Message, RuntimeConfig, interpolation_period
from netcfg.runtime.canopen_identity import (
    Identity,
    identities_from_dir,
    identity_from_eds,
    identity_from_runtime,
)
from netcfg.runtime.canopen_network import canopen_bus, canopen_slaves, master_node
from netcfg.runtime.canopen_records import CommandFn, CycleRecord, MasterRun, PeriodStats, Samples, TimeStats
from netcfg.runtime.canopen_setup import NodeSetup, PdoReadback, SetupReport, configure_network
from netcfg.runtime.clock import Clock, CycleTiming
from netcfg.runtime.codec import CodecError, Number

__all__ = [
    "CommandFn",
    "CycleHook",
    "CycleRecord",
    "CycleTiming",
    "FrameHook",
    "Identity",
    "MasterCycle",
    "MasterRun",
    "NodeSetup",
    "PdoReadback",
    "PeriodStats",
    "SetupReport",
    "TimeStats",
    "canopen_bus",
    "canopen_slaves",
    "configure_network",
    "identities_from_dir",
    "identity_from_eds",
    "identity_from_runtime",
    "interpolation_period",
]


SERVE_MARGIN_S = 0.0005  # a serving wait hands its last half millisecond to the clock's precise sleep
DUE_PATTERNS = 240  # the due TxPDOs of at most this many SYNCs in a row are remembered (transmission types 1-240)

FrameHook = Callable[[can.Message, float], object]  # a frame the cycle does not take, and the clock time it came
CycleHook = Callable[[CycleRecord], bool | None]  # after each cycle; False ends the run there


class MasterCycle:
    """The master cycle of seed 000, Figure 7, driven by runtime.json.

    Each iteration: ask `commands(cycle_index, samples_of_the_previous_cycle)` for RxPDO values
    ({message: {field: value}}), send every periodic RxPDO of the master (with the last values given, zeros before
    any) plus any on-demand RxPDO the commands name (e.g. the interpolation time at gait start), send SYNC, collect
    the TxPDOs due at this SYNC (transmission type n: every n-th SYNC) until all arrived or the read window ends,
    store the samples, then wait dynamically (eq. (1)). A TxPDO that did not arrive is counted as missing for that
    cycle and node, and its cells stay empty: nothing is filled in.

    Dynamic waiting: the paper waits T - Pt - K after measuring the iteration's processing time Pt, i.e. until
    start + T - K. K absorbs what Pt does not measure (the equation itself, the sleep's wake-up latency). The paper
    gives K = 132 "ms", which cannot be milliseconds: with T = 20 ms every wait would be negative. Microseconds
    (0.132 ms) would fit the order of a Raspberry Pi's sleep latency, but the paper does not say, and K is tuned per
    machine anyway. Default 0: SystemClock spins the last 0.5 ms, so the residual error is a few microseconds.
    With drift_free=True the iteration ends at first_start + (i + 1) T - K instead, so errors do not accumulate over
    a run (the paper's anchoring lets them add up to its 1.266 ms per 8 s gait cycle). A loop held for more than a
    period (a stalled host, a bus-off) goes on at the next instant of its grid: the instants it missed are skipped,
    not sent in a burst.

    The SYNC instant. In the paper's loop the SYNC follows the writes at once, so it moves with the writing time
    (Table 5: 0.23 to 8.56 ms). A spec that gives the master a SYNC task (`sync: true` on the SYNC producer, e.g.
    ALLEX-2's control step 10 ms after SYNC) fixes it instead: the iteration, which computes and writes, starts at
    that task's offset after the previous SYNC, and the SYNC waits until `sync_lead_s` = T - offset after the
    iteration's start. The SYNC then keeps its period whatever the computation takes, as long as offset + WCET (+ the
    wake-up latency) fits the period, which `netcfg check` verifies. Without such a task sync_lead_s is 0: the
    paper's loop. The offset is never taken shorter than the read window: the master computes on complete samples.

    `timing` is a simulator's hook (None on real hardware, where time passes by itself): how long the computation
    takes in virtual time, and how late each wait ends. `on_frame` sees every frame the cycle does not take itself
    (heartbeats, EMCY, ...) and every event-driven TxPDO (types 254/255, whose event timers supervision watches)
    with the clock's time, `after_cycle` each cycle's record (False ends the run there):
    supervision and a live view hang on them.

    With a SYNC counter on the bus (runtime.json's sync_overflow, CiA 301 0x1019) the SYNC carries one byte: 1 on
    the first SYNC, one more on each, back to 1 after the overflow value.
    """

    def __init__(
        self,
        cfg: RuntimeConfig,
        bus: can.BusABC,
        clock: Clock,
        *,
        bus_name: str | None = None,
        nodes: Iterable[str] | None = None,
        commands: CommandFn | None = None,
        k_s: float = 0.0,
        period_s: float | None = None,
        read_window_s: float | None = None,
        drift_free: bool = False,
        pause_gc: bool = True,
        collect_after: bool = True,
        sync_lead_s: float | None = None,
        timing: CycleTiming | None = None,
        on_frame: FrameHook | None = None,
        after_cycle: CycleHook | None = None,
        serve: Callable[[], bool] | None = None,
    ) -> None:
        self.cfg, self.bus, self.clock = cfg, bus, clock
        # while serve() is true the waits read the bus and hand on_frame what comes (SDO answers to a set-up
        # running beside the cycle); a node in `muted` gets none of its RxPDOs (it rebooted: not configured)
        self.serve = serve
        self.muted: set[str] = set()
        self._late_in_wait = 0
        self.on_frame, self.after_cycle = on_frame, after_cycle
        self.pause_gc, self.collect_after = pause_gc, collect_after
        self.timing = timing
        co_bus = canopen_bus(cfg, bus_name)
        params = co_bus.canopen
        assert params is not None
        self.bus_name = co_bus.name
        self.master = master_node(cfg, co_bus)
        slaves = [n.name for n in canopen_slaves(cfg, co_bus)]
        wanted = set(nodes) if nodes is not None else set(slaves)
        if unknown := wanted - set(slaves):
            raise ValueError(f"not CANopen slaves of bus '{co_bus.name}': {', '.join(sorted(unknown))}")
        self.period_s = period_s if period_s is not None else params.sync_period_ns / 1e9
        self.read_window_s = read_window_s if read_window_s is not None else params.collect_window_ns() / 1e9
        self.k_s = k_s
        self.drift_free = drift_free
        if sync_lead_s is None:
            offset_ns = master_task_offset_ns(cfg, co_bus)
            computes_at_s = None if offset_ns is None else max(offset_ns / 1e9, self.read_window_s)
            sync_lead_s = 0.0 if computes_at_s is None else max(0.0, self.period_s - computes_at_s)
        self.sync_lead_s = sync_lead_s
        self.commands = commands
        on_bus = cfg.messages_on(co_bus.name)
        sync = [m for m in on_bus if m.implicit == "SYNC"]
        self.sync_frame = can.Message(
            arbitration_id=sync[0].id if sync else params.sync_id, is_extended_id=False, dlc=0, data=b""
        )
        self.sync_overflow = params.sync_overflow
        self.rpdos = tuple(
            m
            for m in on_bus
            if m.pdo is not None and m.pdo.kind == "rpdo" and m.producer == self.master.name and m.pdo.node in wanted
        )
        tpdos = [
            m
            for m in on_bus
            if m.pdo is not None and m.pdo.kind == "tpdo" and m.pdo.node in wanted and self.master.name in m.consumers
        ]
        # transmission type 0 answers only SYNCs after its data changed: taken when it comes, never waited for nor
        # counted missing (the analysis and the simulator assume it every SYNC, the worst case for the bus)
        self._every = {
            m.name: every
            for m in tpdos
            if m.pdo is not None and m.pdo.transmission != 0 and (every := cia301.sync_every(m.pdo.transmission))
        }
        self.expected = tuple(m for m in tpdos if m.name in self._every)
        self._due_every = math.lcm(*self._every.values())  # the pattern of due TxPDOs repeats this often
        self._due_at: dict[int, tuple[str, ...]] = {}  # sync_number % _due_every -> due TxPDOs (_due)
        self._by_id = {(m.id, m.extended): m for m in tpdos}
        self._event_ids = {(m.id, m.extended) for m in tpdos if m.pdo is not None and m.pdo.transmission >= 254}
        # TxPDOs the cycle does not wait for (type 0, events): one still queued at the next SYNC is not late
        self._unwaited = {(m.id, m.extended) for m in tpdos if m.name not in self._every}
        # a periodic RxPDO goes every n-th cycle, n = its period over the SYNC period (rounded up: never more often
        # than the spec says, which is what the analysis counts): large_plant's position axes every 2nd SYNC
        sync_ns = params.sync_period_ns
        self._rpdo_every = {
            m.name: max(1, -(-m.period_ns // sync_ns)) for m in self.rpdos if m.kind == "periodic" and m.period_ns
        }
        self._last: dict[str, dict[str, Number]] = {m.name: _rest_values(m) for m in self.rpdos}
        self._rpdo_names = {m.name for m in self.rpdos}
        self._frames: dict[str, can.Message] = {}  # RxPDO -> its frame for the values in _last (_frame)
        self.syncs = 0  # SYNCs sent; the drives count theirs from NMT start, so "every n-th" agrees

    def _due(self, sync_number: int) -> tuple[str, ...]:
        """The names of the TxPDOs due at this SYNC. The answer repeats every lcm(n) SYNCs, so it is worked out
        once per phase of that pattern (when the pattern is at most DUE_PATTERNS SYNCs long)."""
        cached = self._due_every <= DUE_PATTERNS
        phase = sync_number % self._due_every
        due = self._due_at.get(phase) if cached else None
        if due is None:
            due = tuple(m.name for m in self.expected if sync_number % self._every[m.name] == 0)
            if cached:
                self._due_at[phase] = due
        return due

    def run(self, cycles: int, *, until_s: float | None = None) -> MasterRun:
        """Run `cycles` iterations, or fewer: none starts at or after the clock time `until_s`.
        With pause_gc, Python's cyclic garbage collector is off meanwhile (and, with collect_after, collects
        once afterwards): a full collection of a large heap holds the interpreter for tens of milliseconds, stalling
        this loop and any drive threads in the process past the read window. Reference counting still frees memory.
        A simulation that runs many masters in one process passes collect_after=False: there each full collection
        cost more than the run it followed (the soundness suite's CANopen sweep, 63 ms a run).
        """
        was_enabled = gc.isenabled()
        if self.pause_gc:
            gc.disable()
        try:
            return self._run(cycles, until_s)
        finally:
            if self.pause_gc and was_enabled:
                gc.enable()
                if self.collect_after:
                    gc.collect()

    def _sleep_until(self, t: float) -> None:
        if self.serve is not None and self.on_frame is not None and self.serve():
            while (left := t - self.clock.now()) > SERVE_MARGIN_S:
                frame = self.bus.recv(timeout=left - SERVE_MARGIN_S)
                if frame is None:
                    continue
                key = (frame.arbitration_id, bool(frame.is_extended_id))
                if key in self._by_id and key not in self._event_ids:
                    self._late_in_wait += 1  # a synchronous TxPDO after its window: late, as at the cycle's start
                else:
                    self.on_frame(frame, self.clock.now())
        self.clock.sleep_until(t + (self.timing.late_s() if self.timing is not None else 0.0))

    def _run(self, cycles: int, until_s: float | None) -> MasterRun:
        clock, bus, timing = self.clock, self.bus, self.timing
        records: list[CycleRecord] = []
        duplicates: Counter[str] = Counter()
        bad: Counter[str] = Counter()
        unsent: Counter[str] = Counter()
        previous: Samples = {}
        first = start = clock.now()
        for i in range(cycles):
            if until_s is not None and start >= until_s:
                break
            # writing (red in Figure 7): this cycle's commands, computed from the last samples
            asked = self.commands(i, previous) if self.commands is not None else None
            if timing is not None:
                clock.sleep_until(clock.now() + timing.work_s(i))
            on_demand = self._take(asked or {})
            for msg in self.rpdos:
                if msg.pdo is not None and msg.pdo.node in self.muted:
                    continue
                if (msg.kind == "periodic" and i % self._rpdo_every.get(msg.name, 1) == 0) or msg.name in on_demand:
                    try:
                        bus.send(self._frame(msg))
                    except can.CanError:
                        unsent[msg.name] += 1
            written = clock.now()
            if self.sync_lead_s > 0:  # the SYNC keeps its instant, whatever the computation took
                anchor = first + i * self.period_s if self.drift_free else start
                self._sleep_until(anchor + self.sync_lead_s - self.k_s)  # K absorbs the wake-up latency here too
            # anything already queued cannot answer the SYNC about to go out
            late, other, self._late_in_wait = self._late_in_wait, 0, 0
            while (stale := bus.recv(timeout=0)) is not None:
                key = (stale.arbitration_id, bool(stale.is_extended_id))
                if key in self._by_id and key not in self._unwaited:
                    late += 1
                else:  # an event-driven or acyclic TxPDO answers no SYNC of its own: it is not late
                    other += 1
                    if self.on_frame is not None:
                        self.on_frame(stale, clock.now())
            # reading (orange): SYNC, then the due TxPDOs until all are in or the window is over
            sync_frame = self.sync_frame
            if self.sync_overflow:
                counter = self.syncs % self.sync_overflow + 1
                sync_frame = can.Message(arbitration_id=sync_frame.arbitration_id, is_extended_id=False, data=[counter])
            sync_ok = True
            try:
                bus.send(sync_frame)
            except can.CanError:
                sync_ok = False
                unsent[f"SYNC 0x{self.sync_frame.arbitration_id:X}"] += 1
            sync_sent = clock.now()
            self.syncs += 1
            due = self._due(self.syncs)
            pending = set(due)
            arrivals: dict[str, float] = {}
            values: dict[str, dict[str, Number]] = {}
            deadline = sync_sent + self.read_window_s
            now, recv, by_id = clock.now, bus.recv, self._by_id  # once per cycle, not per frame
            while pending:
                remaining = deadline - now()
                # once the window is over, still take what is already queued: a master descheduled by its operating
                # system looks late, but those frames did arrive; only frames not yet received are missing
                frame = recv(timeout=max(remaining, 0.0))
                if frame is None:
                    if remaining <= 0:
                        break
                    continue
                t = now()
                got = (
                    None
                    if frame.is_error_frame or frame.is_remote_frame
                    else by_id.get((frame.arbitration_id, bool(frame.is_extended_id)))
                )
                if got is None:
                    other += 1
                    if self.on_frame is not None:
                        self.on_frame(frame, t)
                    continue
                if self.on_frame is not None and (got.id, got.extended) in self._event_ids:
                    self.on_frame(frame, t)  # taken as a sample too, and seen by supervision
                if got.name in arrivals:
                    duplicates[got.name] += 1
                    continue
                try:
                    values[got.name] = got.decode(bytes(frame.data))
                except CodecError:
                    bad[got.name] += 1
                    continue
                arrivals[got.name] = t
                pending.discard(got.name)
            read_done = clock.now()
            # storage: kept in memory until the run ends, as the paper does; missing frames stay missing
            missing = tuple(name for name in due if name not in arrivals)
            previous = values
            processed = clock.now()
            processing = processed - start
            waiting = self.period_s - processing - self.k_s  # eq. (1)
            if self.drift_free:
                target = first + (i + 1) * self.period_s - self.k_s
                behind = clock.now() - target
                if behind > self.period_s:  # a held loop (a stalled host, a bus-off): the instants it missed are
                    first += math.floor(behind / self.period_s) * self.period_s  # gone, not caught up in a burst
                    target = first + (i + 1) * self.period_s - self.k_s
            else:
                target = start + self.period_s - self.k_s
            self._sleep_until(target)
            end = clock.now()
            record = CycleRecord(
                index=i,
                sync_number=self.syncs,
                start=start,
                written=written,
                sync_sent=sync_sent,
                read_done=read_done,
                end=end,
                due=due,
                arrivals=arrivals,
                values=values,
                missing=missing,
                late=late,
                other=other,
                processing_s=processing,
                waiting_s=waiting,
                sync_ok=sync_ok,
            )
            records.append(record)
            start = end
            if self.after_cycle is not None and self.after_cycle(record) is False:
                break
        return MasterRun(
            bus=self.bus_name,
            period_s=self.period_s,
            read_window_s=self.read_window_s,
            k_s=self.k_s,
            expected=tuple(m.name for m in self.expected),
            producers={m.name: m.producer for m in self.expected},
            fields={m.name: tuple(f.name for f in m.fields) for m in self.expected},
            records=tuple(records),
            duplicates=dict(duplicates),
            bad_frames=dict(bad),
            send_errors=dict(unsent),
        )

    def _take(self, asked: Mapping[str, Mapping[str, Number]]) -> set[str]:
        """Merge commanded values into the last ones; the names of the RxPDOs commanded."""
        for name, fields in asked.items():
            if name not in self._rpdo_names:
                msg = self.cfg.message(name)  # an unknown name raises, with close matches
                raise ValueError(f"'{msg.name}' is not an RxPDO this master sends on bus '{self.bus_name}'")
            self._last[name].update(fields)
            self._frames.pop(name, None)
        return set(asked)

    def _frame(self, msg: Message) -> can.Message:
        """The RxPDO's frame for its last commanded values, encoded once per change of them, not every cycle (a
        bus's send() only reads the frame it is given)."""
        frame = self._frames.get(msg.name)
        if frame is None:
            if not msg.is_can:
                raise TypeError(f"message '{msg.name}' travels on {msg.protocol} bus '{msg.bus}', not CAN")
            frame = self._frames[msg.name] = msg.frame(msg.encode(**self._last[msg.name]))
        return frame


def master_task_offset_ns(cfg: RuntimeConfig, bus: Bus) -> int | None:
    """When the master's computation starts after SYNC: the earliest offset of its SYNC tasks on this bus (the tasks
    of the SYNC producer that run on this bus's SYNC); None when it has none."""
    assert bus.canopen is not None
    producer = cfg.node(bus.canopen.sync_producer)
    offsets = [t.offset_ns for t in producer.tasks if t.sync_bus == bus.name]
    return min(offsets) if offsets else None


def _rest_values(msg: Message) -> dict[str, Number]:
    """Zero for every field (a drive at rest), or the field's minimum when zero is out of range."""
    out: dict[str, Number] = {}
    for f in msg.fields:
        zero: Number = 0
        if f.minimum is not None and f.minimum > 0:
            zero = f.minimum
        elif f.maximum is not None and f.maximum < 0:
            zero = f.maximum
        out[f.name] = zero
    return out
