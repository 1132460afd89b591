"""Simulated CANopen drives: real CANopen peers for tests and for the bench before the hardware arrives.

A SimulatedDrive is a `canopen.LocalNode` built from a node's generated EDS. The canopen package gives it an SDO
server and an NMT slave; this module adds what a LocalNode does not do on its own:

- it answers each SYNC with its synchronous TPDOs (transmission type n: every n-th SYNC since it entered
  OPERATIONAL; type 0: on a SYNC after the mapped data changed), built from the PDO configuration in its own object
  dictionary as the master wrote it over SDO, so a wrong configuration shows up on the wire;
- it sends its event-driven TPDOs (types 254/255) on application events, taken to be a change of the mapped values
  seen at a SYNC, and whenever one has been silent for its event timer (0x18xx sub 5), never sooner than its inhibit
  time (sub 3) after its last send, as CiA 301 7.3.3 has it;
- it applies received RPDOs to its object dictionary (types 0-240 at the next SYNC, 254/255 at once);
- it checks PDO writes the way CiA 301 devices do (mapping changed only while the PDO is disabled and sub-index 0 is 0,
  only mappable objects, at most 64 bits), so a master that skips a step fails here as it would on a drive;
- a CiA 402 drive (one with a controlword 0x6040 and statusword 0x6041) runs the power state machine of
  netcfg.runtime.cia402, commanded over SDO or an RPDO, shown in the statusword;
- optional faults for tests: wrong identity in 0x1018, never answering, aborting SDO writes to given objects; and
  at run time `kill()` (the drive drops off the bus: no heartbeat, no answers) and `emergency(code)` (an EMCY
  frame and the CiA 402 fault reaction);
- an optional processing delay before the TPDOs go out, and a model hook run at each SYNC. The delay does not hold
  up the thread that feeds the drive its frames: the TPDOs are sampled at the SYNC and handed to a scheduler thread
  that sends them `response_delay_s` later, so drives sharing a thread each answer that long after the SYNC, as
  separate devices do, instead of one after the other.

Its factory state (clear_pdos=True) has every PDO disabled and nothing mapped, so only a master that configures it
gets data. It imports only the standard library, python-can, canopen, netcfg.runtime and netcfg.cia301.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable
from canopen.objectdictionary.datatypes import NUMBER_TYPES, SIGNED_TYPES
from canopen.sdo import SdoAbortedError

from netcfg import cia301
from netcfg.cia301 import PDO_INVALID, RPDO_COMM, RPDO_MAP, TPDO_COMM, TPDO_MAP
from netcfg.runtime import RuntimeConfig
from netcfg.runtime.canopen_master import canopen_bus, canopen_slaves
from netcfg.runtime.cia402 import CONTROLWORD, STATUSWORD, PowerStateMachine
from netcfg.runtime.clock import Clock, SystemClock
from netcfg.runtime.codec import int_range

__all__ = ["DriveBench", "DriveModel", "ResponseScheduler", "SimulatedDrive", "follow_velocity"]

log = logging.getLogger(__name__)

PDO_SLOTS = cia301.MAX_PDOS
MAX_PDO_BITS = 64  # a classic CAN frame

# SDO abort codes (CiA 301, table 22) the drive answers with
ABORT_NOT_MAPPABLE = 0x06040041
ABORT_PDO_LENGTH = 0x06040042
ABORT_VALUE_RANGE = 0x06090030
ABORT_DEVICE_STATE = 0x08000022
EMCY_RPDO_TIMEOUT = 0x8250  # CiA 301 table 21: "RPDO timeout" (the RPDO's deadline, its event timer, passed)
SYNC_GAP = 1.5  # a SYNC this many interpolation periods after the last one: the drive notes it missed some

DriveModel = Callable[["SimulatedDrive"], None]


class ResponseScheduler:
    """One thread that runs actions at given times: the drives' delayed TPDO answers.

    `call_later(delay_s, action)` puts the action on a heap ordered by due time (clock.now() + delay_s); the thread
    sleeps on a condition variable until the earliest is due, runs every action that is due, and wakes early when an
    earlier one is added. It starts on the first call_later (a bench without delays starts no thread) and close() stops
    it, dropping what is still pending. Actions run on this thread one after the other, so each must be short (a few
    bus.send calls); one that raises is logged and does not stop the others.

    Waits are condition-variable timeouts in seconds, so `clock` must count real seconds (the drives run on threads
    in real time); an action runs at its due time plus the operating system's wake-up latency (tens of microseconds
    on an idle machine), never before it. It does not busy-wait: a spinning thread would hold the interpreter lock
    the dispatcher and the master need.
    """

    def __init__(self, clock: Clock | None = None, name: str = "netcfg-drive-responses") -> None:
        self.clock: Clock = clock or SystemClock()
        self.name = name
        self._cond = threading.Condition()
        self._heap: list[tuple[float, int, Callable[[], None]]] = []
        self._order = itertools.count()  # ties run in the order they were scheduled
        self._thread: threading.Thread | None = None
        self._closed = False
        self.dropped = 0  # actions still pending at close()

    def call_later(self, delay_s: float, action: Callable[[], None]) -> None:
        """Run `action` on the scheduler thread `delay_s` from now; ignored once the scheduler is closed."""
        due = self.clock.now() + delay_s
        with self._cond:
            if self._closed:
                return
            seq = next(self._order)
            heapq.heappush(self._heap, (due, seq, action))
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
                self._thread.start()
            elif self._heap[0][1] == seq:
                self._cond.notify()  # the new action is the earliest: the thread waits for it instead

    def close(self, timeout: float = 2.0) -> None:
        """Stop the thread; pending actions are dropped (counted in `dropped`)."""
        with self._cond:
            self._closed = True
            self.dropped += len(self._heap)
            self._heap.clear()
            self._cond.notify()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    @property
    def pending(self) -> int:
        with self._cond:
            return len(self._heap)

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._closed:
                    if not self._heap:
                        self._cond.wait()
                        continue
                    wait = self._heap[0][0] - self.clock.now()
                    if wait <= 0:
                        break
                    self._cond.wait(wait)
                if self._closed:
                    return
                now = self.clock.now()
                due = []
                while self._heap and self._heap[0][0] <= now:
                    due.append(heapq.heappop(self._heap)[2])
            for action in due:  # outside the lock: call_later from another thread must not wait for a send
                try:
                    action()
                except Exception:
                    log.exception("%s: a scheduled action failed", self.name)


@dataclass(frozen=True)
class _PdoSlot:
    """One PDO as the drive's object dictionary holds it now."""

    number: int  # 1-based
    can_id: int
    extended: bool
    valid: bool
    transmission: int
    sync_start: int
    entries: tuple[tuple[int, int, int], ...]  # (index, sub, bits)
    inhibit_100us: int = 0  # TPDOs: sub 3, the least gap between two sends
    event_timer_ms: int = 0  # sub 5: a TPDO's send due after this long without one; an RPDO's deadline (0: off)

    @property
    def event_driven(self) -> bool:
        return self.valid and bool(self.entries) and self.transmission >= 254

    @property
    def bits(self) -> int:
        return sum(b for _, _, b in self.entries)


def follow_velocity(drive: SimulatedDrive) -> None:
    """A stand-in for a drive in cyclic synchronous velocity mode (CiA 402), not a motor model.

    At each SYNC the velocity actual value (0x606C) becomes target velocity (0x60FF) + velocity offset (0x60B1), and
    the position actual value (0x6064) advances by that velocity times the interpolation period (0x60C2), as if the
    velocity were in position units per second. Drives without these objects are left alone.
    """
    if not (drive.has(0x60FF) and drive.has(0x606C)):
        return
    velocity = int(drive.value(0x60FF)) + (int(drive.value(0x60B1)) if drive.has(0x60B1) else 0)
    drive.set_value(0x606C, 0, velocity)
    if drive.has(0x6064) and drive.has(0x60C2, 1) and drive.has(0x60C2, 2):
        period_s = int(drive.value(0x60C2, 1)) * 10.0 ** int(drive.value(0x60C2, 2))
        drive.set_value(0x6064, 0, int(drive.value(0x6064)) + round(velocity * period_s))


class SimulatedDrive:
    """A CANopen slave on a python-can bus, built on canopen.LocalNode from an EDS/DCF.

    Faults (for tests): `identity=(vendor_id, product_code)` puts other values in 0x1018; `silent=True` answers
    nothing at all (a drive that is off, or has another node id or bit rate); `abort_writes={index: abort_code}`
    aborts every SDO write to those objects with that code ({(index, sub): code}: to one sub-index);
    `no_event_timer=True` ignores the TPDOs' event timers (a firmware without them that accepts the write anyway).

    `response_delay_s`: the TPDOs answering a SYNC are sampled when it arrives and sent that long after it (measured
    on `clock`, which must count real seconds), from a ResponseScheduler thread: the bench's, shared by its drives,
    or one of the drive's own. The thread handing the drive its frames never waits for it.
    """

    def __init__(
        self,
        node_id: int,
        object_dictionary: str | Path | canopen.ObjectDictionary,
        *,
        name: str | None = None,
        clear_pdos: bool = True,
        strict_pdo_writes: bool = True,
        response_delay_s: float = 0.0,
        clock: Clock | None = None,
        model: DriveModel | None = follow_velocity,
        identity: tuple[int, int] | None = None,
        silent: bool = False,
        abort_writes: Mapping[int | tuple[int, int], int] | None = None,
        no_event_timer: bool = False,
    ) -> None:
        od = object_dictionary if isinstance(object_dictionary, canopen.ObjectDictionary) else str(object_dictionary)
        self.node = canopen.LocalNode(node_id, od)
        self.name = name or f"node{node_id}"
        self.strict_pdo_writes = strict_pdo_writes
        self.response_delay_s = response_delay_s
        self.clock: Clock = clock or SystemClock()
        self.model = model
        self.silent = silent
        self.abort_writes = dict(abort_writes or {})
        self.no_event_timer = no_event_timer
        self.network: canopen.Network | None = None
        self.bus: can.BusABC | None = None
        self._notifier: can.Notifier | None = None
        self._scheduler: ResponseScheduler | None = None
        self._own_scheduler = False
        # what happened, for tests and the bench
        self.sdo_writes: list[tuple[int, int]] = []  # accepted SDO writes, in order
        self.syncs = 0  # SYNCs received while OPERATIONAL
        self.tpdos_sent = 0
        self.event_tpdos_sent: dict[int, int] = {}  # event-driven TPDO number -> sends
        self.rpdos_applied = 0
        self.rpdo_length_errors = 0  # CiA 301 would send EMCY 0x8210
        self.errors: list[str] = []
        # the PDO configuration, re-read from the object dictionary after any write to it
        self._dirty = True
        self._sync_id = 0x80
        self._tpdos: tuple[_PdoSlot, ...] = ()
        self._rpdos: dict[tuple[int, bool], _PdoSlot] = {}
        self._sync_counts: dict[int, int] = {}
        self._sync_started: set[int] = set()
        self._last_acyclic: dict[int, bytes] = {}
        self._pending: dict[int, tuple[_PdoSlot, bytes]] = {}
        self._rpdo_seen: dict[int, int] = {}  # RPDO number -> receptions, for its deadline
        self._last_sync_at: float | None = None
        # event-driven TPDOs, shared by the frame thread (application events at SYNC) and the scheduler (timers)
        self._event_lock = threading.Lock()
        self._event_epoch = 0  # counts entries to OPERATIONAL: timers of an earlier one do nothing
        self._event_last: dict[int, float] = {}  # TPDO number -> its last send (or the entry to OPERATIONAL)
        self._event_sent: dict[int, bytes] = {}  # TPDO number -> the payload it last sent
        self._event_held: set[int] = set()  # TPDOs with an application event held back by the inhibit time

        # the PDO slots the object dictionary has (0-based), looked up once
        self._rx_slots = tuple(n for n in range(PDO_SLOTS) if self.has(RPDO_COMM + n, 1))
        self._tx_slots = tuple(n for n in range(PDO_SLOTS) if self.has(TPDO_COMM + n, 1))
        self._identity, self._clear_on_boot = identity, clear_pdos
        self._fill_values(identity)
        if clear_pdos:
            self._clear_pdos()
        self.node.add_write_callback(self._on_sdo_write)
        # a CiA 402 drive (controlword and statusword in its dictionary) runs the power state machine
        self.power: PowerStateMachine | None = None
        if self.has(CONTROLWORD) and self.has(STATUSWORD):
            self.power = PowerStateMachine()
            self._show_state()
        self.killed = False
        self.reboots = 0
        self.notes: list[str] = []  # what the drive did on its own that a test or the bench reports
        self.emcy_sent: list[tuple[int, int, bytes]] = []
        self._ending: list[threading.Thread] = []  # heartbeat threads told to stop, not yet joined

    # --- object dictionary access ----------------------------------------------------------------------------

    def has(self, index: int, sub: int = 0) -> bool:
        return self._variable(index, sub) is not None

    def value(self, index: int, sub: int = 0) -> Any:
        """The object's current value, decoded by its data type."""
        var = self._require(index, sub)
        return var.decode_raw(self.node.get_data(index, sub))

    def set_value(self, index: int, sub: int, value: Any) -> None:
        """Set an object as the application would (no SDO checks); integers are clamped to the type's range."""
        var = self._require(index, sub)
        if var.data_type in NUMBER_TYPES and isinstance(value, int):
            lo, hi = int_range(len(var), var.data_type in SIGNED_TYPES)
            value = min(max(value, lo), hi)
        self._store(index, sub, var.encode_raw(value))

    def _variable(self, index: int, sub: int = 0) -> ODVariable | None:
        od = self.node.object_dictionary
        if index not in od:
            return None
        obj = od[index]
        if isinstance(obj, ODVariable):
            return obj if sub == 0 else None
        var: ODVariable | None = obj.subindices.get(sub)  # only the sub-indices the EDS lists
        return var

    def _require(self, index: int, sub: int) -> ODVariable:
        var = self._variable(index, sub)
        if var is None:
            raise KeyError(f"{self.name}: no object 0x{index:04X}:{sub:02X} in its object dictionary")
        return var

    def _store(self, index: int, sub: int, data: bytes) -> None:
        self.node.data_store.setdefault(index, {})[sub] = bytes(data)
        if index == 0x1005 or index in cia301.PDO_PARAMETERS:
            self._dirty = True

    def _int(self, index: int, sub: int, default: int = 0) -> int:
        if not self.has(index, sub):
            return default
        try:
            return int(self.value(index, sub))
        except SdoAbortedError:
            return default

    def _fill_values(self, identity: tuple[int, int] | None) -> None:
        """Give every number object without a value a zero, and 0x1018 an identity (the EDS may have no
        product code), as a powered-up device has."""
        od = self.node.object_dictionary
        for index in od:
            obj = od[index]
            variables = [obj] if isinstance(obj, ODVariable) else [obj[s] for s in obj]
            for var in variables:
                if var.value is None and var.default is None and var.data_type in NUMBER_TYPES:
                    self._store(var.index, var.subindex, var.encode_raw(0))
        info = od.device_information
        if self.has(0x1018, 2) and info.product_number is not None and self._int(0x1018, 2) == 0:
            self.set_value(0x1018, 2, int(info.product_number))
        if self.has(0x1018, 4) and self._int(0x1018, 4) == 0:
            self.set_value(0x1018, 4, self.node.id)  # a serial number that tells drives apart
        if identity is not None:
            self.set_value(0x1018, 1, identity[0])
            self.set_value(0x1018, 2, identity[1])

    def _clear_pdos(self) -> None:
        for comm, mapping, slots in ((RPDO_COMM, RPDO_MAP, self._rx_slots), (TPDO_COMM, TPDO_MAP, self._tx_slots)):
            for n in slots:
                self._store(comm + n, 1, (self._int(comm + n, 1) | PDO_INVALID).to_bytes(4, "little"))
                if self.has(comm + n, 2):
                    self._store(comm + n, 2, bytes([255]))
                if self.has(mapping + n, 0):
                    self._store(mapping + n, 0, bytes([0]))
                    for sub in range(1, self._map_capacity(mapping + n) + 1):
                        self._store(mapping + n, sub, bytes(4))

    def _map_capacity(self, map_index: int) -> int:
        obj = self.node.object_dictionary[map_index]
        return max((s for s in obj if isinstance(s, int)), default=0) if isinstance(obj, (ODRecord, ODArray)) else 0

    # --- CiA 402 and faults ---------------------------------------------------------------------------------------

    def _show_state(self) -> None:
        if self.power is not None:
            self._store(STATUSWORD, 0, self.power.statusword.to_bytes(2, "little"))

    def emergency(self, code: int, register: int = 0x01, vendor: bytes = b"") -> None:
        """Raise an error as a drive does: the power state machine's fault reaction (CiA 402 transition 13), the
        error register (0x1001) and an EMCY frame with `code`, `register` and up to 5 manufacturer bytes (CiA 301
        7.2.7)."""
        if self.power is not None:
            self.power.fault()
            self._show_state()
        if self.has(0x1001):
            self.set_value(0x1001, 0, register)
        self.emcy_sent.append((code, register, bytes(vendor)))
        if self.network is not None and not self.silent:
            self.node.emcy.send(code, register, bytes(vendor))

    def kill(self) -> None:
        """The drive drops off the bus (power lost, cable cut): no heartbeat, no answers, nothing sent."""
        self.killed = self.silent = True
        self._stop_heartbeat()

    def reboot(self, outage_s: float) -> None:
        """The drive resets (a brown-out, a watchdog): silent for `outage_s`, then it boots as after power-on, with
        its default object dictionary (the master's PDO configuration and start-up values gone): the boot-up message
        (heartbeat COB-ID, one byte 0x00, CiA 301 7.2.8.3.2.1), PRE-OPERATIONAL, CiA 402 SWITCH ON DISABLED."""
        self.kill()
        self.reboots += 1
        if self._scheduler is not None:
            self._scheduler.call_later(outage_s, self._boot)
        else:
            threading.Timer(outage_s, self._boot).start()

    def _boot(self) -> None:
        if self.network is None:
            return  # detached meanwhile
        self.node.data_store = {}
        self._fill_values(self._identity)
        if self._clear_on_boot:
            self._clear_pdos()
        self._dirty = True
        self.killed = self.silent = False
        self.node.nmt.send_command(0x81)  # reset node: the boot-up message
        self.node.nmt.send_command(0x80)  # PRE-OPERATIONAL, heartbeat at the default 0x1017
        if self.power is not None:
            self.power = PowerStateMachine()
            self.power.tick()  # NOT READY TO SWITCH ON -> SWITCH ON DISABLED
            self._show_state()

    def _stop_heartbeat(self) -> None:
        """Stop the heartbeat canopen sends from a python-can cyclic-send thread; the thread ends within one
        period, join_threads() waits for it."""
        task = getattr(self.node.nmt, "_send_task", None)
        self.node.nmt.stop_heartbeat()
        thread = getattr(getattr(task, "_task", None), "thread", None)
        if isinstance(thread, threading.Thread):
            self._ending.append(thread)

    def join_threads(self, timeout: float = 2.0) -> None:
        """Wait for the heartbeat threads stopped so far (so a test or a program leaves none behind)."""
        for thread in self._ending:
            if thread is not threading.current_thread():
                thread.join(timeout)
        self._ending.clear()

    # --- the PDO configuration ---------------------------------------------------------------------------------

    def _slot(self, comm: int, mapping: int, n: int) -> _PdoSlot:
        cob = self._int(comm + n, 1, PDO_INVALID)
        count = self._int(mapping + n, 0)
        entries = [cia301.unpack_mapping(self._int(mapping + n, sub)) for sub in range(1, count + 1)]
        can_id, extended = cia301.pdo_can_id(cob)
        return _PdoSlot(
            number=n + 1,
            can_id=can_id,
            extended=extended,
            valid=not cob & PDO_INVALID,
            transmission=self._int(comm + n, 2, 255),
            sync_start=self._int(comm + n, 6),
            entries=tuple(entries),
            inhibit_100us=self._int(comm + n, 3) if comm == TPDO_COMM else 0,
            event_timer_ms=self._int(comm + n, 5),  # an RPDO's: its deadline (CiA 301 7.5.2.35), 0 none
        )

    def _rebuild(self) -> None:
        self._dirty = False
        self._sync_id = self._int(0x1005, 0, 0x80) & 0x7FF
        self._tpdos = tuple(self._slot(TPDO_COMM, TPDO_MAP, n) for n in self._tx_slots)
        rpdos = (self._slot(RPDO_COMM, RPDO_MAP, n) for n in self._rx_slots)
        self._rpdos = {(slot.can_id, slot.extended): slot for slot in rpdos if slot.valid}

    def pdo_slots(self) -> tuple[tuple[str, int, int, bool, int, tuple[tuple[int, int, int], ...]], ...]:
        """(kind, number, CAN id, valid, transmission type, entries) of every PDO, as the drive holds them now."""
        rx = [self._slot(RPDO_COMM, RPDO_MAP, n) for n in self._rx_slots]
        tx = [self._slot(TPDO_COMM, TPDO_MAP, n) for n in self._tx_slots]
        return tuple(
            (kind, s.number, s.can_id, s.valid, s.transmission, s.entries)
            for kind, slots in (("rpdo", rx), ("tpdo", tx))
            for s in slots
        )

    # --- SDO writes: faults and CiA 301 checks --------------------------------------------------------------------

    def _on_sdo_write(self, index: int, subindex: int, od: ODVariable, data: bytes, **_: Any) -> None:
        code = self.abort_writes.get((index, subindex), self.abort_writes.get(index))
        if code is not None:
            raise SdoAbortedError(code)
        if self.strict_pdo_writes:
            self._check_pdo_write(index, subindex, od, data)
        self.sdo_writes.append((index, subindex))
        if index == CONTROLWORD and self.power is not None:
            self.power.controlword(int.from_bytes(data[:2], "little"))
            self._show_state()
        if index == 0x1005 or index in cia301.PDO_PARAMETERS:
            self._dirty = True  # LocalNode stores the value after this callback; re-read it at the next frame

    def _check_pdo_write(self, index: int, sub: int, od: ODVariable, data: bytes) -> None:
        is_map = RPDO_MAP <= index < RPDO_MAP + PDO_SLOTS or TPDO_MAP <= index < TPDO_MAP + PDO_SLOTS
        is_comm = RPDO_COMM <= index < RPDO_COMM + PDO_SLOTS or TPDO_COMM <= index < TPDO_COMM + PDO_SLOTS
        if not (is_map or is_comm) or od.data_type not in NUMBER_TYPES:
            return
        value = int(od.decode_raw(data))
        if is_comm:
            if sub == 1:
                old = self._int(index, 1, PDO_INVALID)
                # CiA 301: the identifier of a valid PDO cannot change; disable it first
                if not old & PDO_INVALID and not value & PDO_INVALID and (old ^ value) & cia301.COB_ID_MASK:
                    raise SdoAbortedError(ABORT_VALUE_RANGE)
            return
        comm = index - cia301.MAP_OFFSET
        if not self._int(comm, 1, PDO_INVALID) & PDO_INVALID:
            raise SdoAbortedError(ABORT_DEVICE_STATE)  # mapping of a valid PDO
        if sub == 0:
            if value > self._map_capacity(index):
                raise SdoAbortedError(ABORT_PDO_LENGTH)
            if sum(self._int(index, s) & 0xFF for s in range(1, value + 1)) > MAX_PDO_BITS:
                raise SdoAbortedError(ABORT_PDO_LENGTH)
            return
        if self._int(index, 0) != 0:
            raise SdoAbortedError(ABORT_DEVICE_STATE)  # entries change only while sub-index 0 is 0
        if value == 0:
            return
        target, target_sub, bits = cia301.unpack_mapping(value)
        if cia301.is_dummy(target, target_sub):  # a dummy entry just reserves bits
            return
        var = self._variable(target, target_sub)
        if var is None or not var.pdo_mappable or bits == 0 or bits > len(var):
            raise SdoAbortedError(ABORT_NOT_MAPPABLE)

    # --- the bus ------------------------------------------------------------------------------------------------------

    def attach(self, bus: can.BusABC, *, listen: bool = True, scheduler: ResponseScheduler | None = None) -> None:
        """Join a python-can bus: boot up (boot-up message, PRE-OPERATIONAL) and, with listen, serve it from a
        python-can Notifier thread. Without listen the caller feeds every frame to on_frame(). Delayed TPDOs go out
        from `scheduler` (its owner closes it); without one the drive makes its own, closed by detach()."""
        if self.network is not None:
            raise RuntimeError(f"{self.name} is already attached to a bus")
        self._own_scheduler = scheduler is None
        self._scheduler = scheduler or ResponseScheduler(self.clock, name=f"{self.name}-responses")
        self.bus = bus
        self.network = canopen.Network(bus)
        self.network.add_node(self.node)
        if not self.silent:
            self.node.nmt.send_command(0x81)  # reset node: the boot-up message (0x700 + id, 0x00)
            self.node.nmt.send_command(0x80)  # then PRE-OPERATIONAL, as CiA 301 devices boot
        if self.power is not None:
            self.power.tick()  # initialised: NOT READY TO SWITCH ON -> SWITCH ON DISABLED (CiA 402 transition 1)
            self._show_state()
        if listen:
            self._notifier = can.Notifier(bus, [self.on_frame], timeout=0.05)

    def detach(self, join: bool = True) -> None:
        """Stop serving the bus (the bus itself stays open: its owner shuts it down). join=False leaves the wait
        for the heartbeat thread to join_threads(), so a bench stops its drives' threads all at once."""
        if self._notifier is not None:
            self._notifier.stop(timeout=2.0)
            self._notifier = None
        if self._scheduler is not None and self._own_scheduler:
            self._scheduler.close()
        self._scheduler = None
        self._stop_heartbeat()
        if join:
            self.join_threads()
        if self.network is not None:
            del self.network[self.node.id]  # type: ignore[arg-type]  # a LocalNode's id is always set
            self.network = None
        self.bus = None

    def on_frame(self, msg: can.Message) -> None:
        """Handle one received frame."""
        if self.silent or msg.is_error_frame or msg.is_remote_frame or self.network is None:
            return
        try:
            self._handle(msg)
        except Exception as exc:  # a bad frame must not stop the drive; keep it for the test to see
            log.exception("%s: error handling frame 0x%X", self.name, msg.arbitration_id)
            self.errors.append(f"frame 0x{msg.arbitration_id:X}: {exc!r}")

    def _handle(self, msg: can.Message) -> None:
        assert self.network is not None
        if self._dirty:
            self._rebuild()
        can_id, extended, data = msg.arbitration_id, bool(msg.is_extended_id), bytes(msg.data)
        operational = self.node.nmt.state == "OPERATIONAL"
        if can_id == self._sync_id and not extended:
            if operational:
                self._on_sync(data)
            return
        rpdo = self._rpdos.get((can_id, extended))
        if rpdo is not None:
            if operational:
                self._on_rpdo(rpdo, data)
            return
        self.network.notify(can_id, bytearray(data), msg.timestamp)  # SDO server, NMT slave
        if not operational and self.node.nmt.state == "OPERATIONAL":
            self._sync_counts.clear()  # "every n-th SYNC" counts from the start
            self._sync_started.clear()
            self._last_acyclic.clear()
            self._last_sync_at = None
            self._pending.clear()
            self._rebuild()
            self._start_event_timers()

    def _on_sync(self, data: bytes) -> None:
        assert self.network is not None
        self.syncs += 1
        self._sync_gap()
        counter = data[0] if data else None
        for slot, payload in self._pending.values():
            self._apply(slot, payload)
        self._pending.clear()
        if self.power is not None:
            if self.has(CONTROLWORD) and self.power.last_controlword != (cw := self._int(CONTROLWORD, 0)):
                self.power.controlword(cw)  # written by an RPDO
            self.power.tick()  # its own transitions: a quick stop ends, a fault reaction becomes FAULT
            self._show_state()
        if self.model is not None:
            self.model(self)
        answers: list[tuple[_PdoSlot, bytes]] = []
        for slot in self._tpdos:
            if slot.event_driven:
                self._application_event(slot)
            if not slot.valid or not slot.entries:
                continue
            every = cia301.sync_every(slot.transmission)
            if every is None:
                continue  # event-driven or RTR-only: no answer to SYNC
            if slot.transmission == 0:
                # acyclic synchronous: sent at a SYNC after its data changed (every SYNC is only its worst case)
                payload = self._pack(slot)
                if self._last_acyclic.get(slot.number) != payload:
                    self._last_acyclic[slot.number] = payload
                    answers.append((slot, payload))
                continue
            if slot.sync_start and counter is not None and slot.number not in self._sync_started:
                if counter != slot.sync_start:
                    continue  # CiA 301: the first SYNC counted is the one carrying the start value
                self._sync_started.add(slot.number)
            count = self._sync_counts.get(slot.number, 0) + 1
            self._sync_counts[slot.number] = count
            if count % every == 0:
                answers.append((slot, self._pack(slot)))
        if not answers:
            return
        if self.response_delay_s > 0 and self._scheduler is not None:
            # sampled now, sent later from the scheduler thread: the caller goes on to the next drive or frame
            self._scheduler.call_later(self.response_delay_s, lambda: self._send_later(answers))
        else:
            for slot, payload in answers:
                self._send(slot, payload)

    # --- event-driven TPDOs (CiA 301 7.3.3) ------------------------------------------------------------------------

    def _start_event_timers(self) -> None:
        """Entering OPERATIONAL: every event-driven TPDO's timer starts now."""
        now = self.clock.now()
        with self._event_lock:
            self._event_epoch += 1
            self._event_last.clear()
            self._event_sent.clear()
            self._event_held.clear()
            for slot in self._tpdos:
                if slot.event_driven:
                    self._event_last[slot.number] = now
                    if slot.event_timer_ms and not self.no_event_timer:
                        self._later(slot.event_timer_ms / 1e3, slot.number, self._timer_due)

    def _later(self, delay_s: float, number: int, action: Callable[[int, int], None]) -> None:
        if self._scheduler is not None:
            epoch = self._event_epoch
            self._scheduler.call_later(max(delay_s, 0.0), lambda: self._guarded(action, number, epoch))

    def _guarded(self, action: Callable[[int, int], None], number: int, epoch: int) -> None:
        try:
            action(number, epoch)
        except Exception as exc:  # kept like on_frame's: the scheduler goes on
            log.exception("%s: error in TPDO%d's timing", self.name, number)
            self.errors.append(f"TPDO{number}: {exc!r}")

    def _event_slot(self, number: int, epoch: int) -> _PdoSlot | None:
        """The TPDO as the drive holds it now, if its timers still apply (same spell in OPERATIONAL, event-driven)."""
        if epoch != self._event_epoch or self.silent or self.node.nmt.state != "OPERATIONAL":
            return None
        slot = next((s for s in self._tpdos if s.number == number), None)
        return slot if slot is not None and slot.event_driven else None

    def _application_event(self, slot: _PdoSlot) -> None:
        """A SYNC saw the mapped values: changed since the last send, that is an application event; it goes out now
        or, within the inhibit time of the last send, once that has passed."""
        payload = self._pack(slot)
        with self._event_lock:
            if self._event_sent.get(slot.number) == payload or slot.number in self._event_held:
                return
            wait = slot.inhibit_100us / 1e4 - (self.clock.now() - self._event_last.get(slot.number, -1e9))
            if wait > 0:
                self._event_held.add(slot.number)
                self._later(wait, slot.number, self._inhibit_over)
                return
            self._event_send(slot, payload)

    def _inhibit_over(self, number: int, epoch: int) -> None:
        with self._event_lock:
            self._event_held.discard(number)
            slot = self._event_slot(number, epoch)
            if slot is not None:
                self._event_send(slot, self._pack(slot))

    def _timer_due(self, number: int, epoch: int) -> None:
        """The event timer: a send when the TPDO has been silent that long (the inhibit time permitting), and the next
        expiry one timer after the last send, whatever caused it."""
        with self._event_lock:
            slot = self._event_slot(number, epoch)
            if slot is None or not slot.event_timer_ms:
                return
            timer_s, inhibit_s = slot.event_timer_ms / 1e3, slot.inhibit_100us / 1e4
            silent = self.clock.now() - self._event_last.get(number, 0.0)
            if silent < timer_s - 1e-6:
                wait = timer_s - silent  # a send since restarted it
            elif silent < inhibit_s:
                wait = inhibit_s - silent  # due, but held back by the inhibit time
            elif number in self._event_held:
                wait = timer_s  # a held application event goes out now and restarts the timer
            else:
                self._event_send(slot, self._pack(slot))
                wait = timer_s
            self._later(wait, number, self._timer_due)

    def _event_send(self, slot: _PdoSlot, payload: bytes) -> None:
        """Under _event_lock: one send of an event-driven TPDO; its timer restarts."""
        self._event_last[slot.number] = self.clock.now()
        self._event_sent[slot.number] = payload
        self._send(slot, payload)
        self.event_tpdos_sent[slot.number] = self.event_tpdos_sent.get(slot.number, 0) + 1

    def _send(self, slot: _PdoSlot, payload: bytes) -> None:
        network, bus = self.network, self.bus
        if network is None or bus is None or self.silent:
            return  # detached or killed meanwhile (a delayed answer): the drive has left the bus
        with network.send_lock:
            bus.send(can.Message(arbitration_id=slot.can_id, is_extended_id=slot.extended, data=payload))
        self.tpdos_sent += 1

    def _send_later(self, answers: list[tuple[_PdoSlot, bytes]]) -> None:
        """A delayed SYNC answer, on the scheduler thread; errors are kept like on_frame's."""
        for slot, payload in answers:
            try:
                self._send(slot, payload)
            except Exception as exc:
                log.exception("%s: error sending TPDO%d", self.name, slot.number)
                self.errors.append(f"TPDO{slot.number} 0x{slot.can_id:X}: {exc!r}")

    def _pack(self, slot: _PdoSlot) -> bytes:
        """The mapped objects' current values, least significant bit first (CiA 301 PDO layout)."""
        acc, offset = 0, 0
        for index, sub, bits in slot.entries:
            raw = 0
            if not cia301.is_dummy(index, sub):
                raw = int.from_bytes(self.node.get_data(index, sub), "little") & ((1 << bits) - 1)
            acc |= raw << offset
            offset += bits
        return acc.to_bytes((offset + 7) // 8, "little")

    def _on_rpdo(self, slot: _PdoSlot, data: bytes) -> None:
        if 8 * len(data) < slot.bits:
            self.rpdo_length_errors += 1
            return
        if slot.event_timer_ms and self._scheduler is not None:
            # deadline monitoring (CiA 301 7.5.2.35, sub 5 of an RPDO): armed by each reception
            stamp = self._rpdo_seen[slot.number] = self._rpdo_seen.get(slot.number, 0) + 1
            self._scheduler.call_later(slot.event_timer_ms / 1e3, lambda: self._rpdo_deadline(slot, stamp))
        if cia301.sync_every(slot.transmission) is not None:
            self._pending[slot.number] = (slot, data)  # synchronous RPDO: takes effect at the next SYNC
        else:
            self._apply(slot, data)

    def _rpdo_deadline(self, slot: _PdoSlot, stamp: int) -> None:
        """No RPDO since the one that armed this: the drive reports an RPDO timeout and takes its fault reaction."""
        if self._rpdo_seen.get(slot.number) != stamp or self.silent or self.node.nmt.state != "OPERATIONAL":
            return
        comm = RPDO_COMM + slot.number - 1
        self.notes.append(
            f"RPDO{slot.number} not received within its deadline of {slot.event_timer_ms} ms (0x{comm:04X} sub 5): "
            f"EMCY 0x{EMCY_RPDO_TIMEOUT:04X} (RPDO timeout) and the fault reaction"
        )
        self.emergency(EMCY_RPDO_TIMEOUT)

    def _sync_gap(self) -> None:
        """At a SYNC: one that came more than SYNC_GAP interpolation periods (0x60C2) after the last is a gap the
        drive notes; without an RPDO deadline (above) or a consumer heartbeat time for the master (0x1016) it has no
        way to react, so it keeps its last command, and says so."""
        now = self.clock.now()
        last, self._last_sync_at = self._last_sync_at, now
        if last is None or not (self.has(0x60C2, 1) and self.has(0x60C2, 2)):
            return
        period_s = int(self.value(0x60C2, 1)) * 10.0 ** int(self.value(0x60C2, 2))
        if period_s <= 0 or now - last <= SYNC_GAP * period_s:
            return
        watches = any(s.event_timer_ms for s in self._rpdos.values()) or any(
            self._int(0x1016, sub) for sub in range(1, 128) if self.has(0x1016, sub)
        )
        if not watches:
            self.notes.append(
                f"no SYNC for {1e3 * (now - last):.1f} ms (interpolation period {1e3 * period_s:g} ms): no RPDO "
                "deadline (0x14xx sub 5) and no consumer heartbeat time (0x1016) to react with, so it kept its last "
                "command"
            )

    def _apply(self, slot: _PdoSlot, data: bytes) -> None:
        acc, offset = int.from_bytes(data, "little"), 0
        for index, sub, bits in slot.entries:
            raw = (acc >> offset) & ((1 << bits) - 1)
            offset += bits
            var = self._variable(index, sub)
            if var is None:
                continue  # dummy entry
            size = len(var)
            if var.data_type in SIGNED_TYPES and bits < size and raw >> (bits - 1):
                raw |= ((1 << size) - 1) ^ ((1 << bits) - 1)  # sign-extend a shortened signed value
            self._store(index, sub, raw.to_bytes(max(size // 8, (bits + 7) // 8), "little"))
        self.rpdos_applied += 1


class DriveBench:
    """The configured CANopen slaves of a runtime config as SimulatedDrives on python-can `channel`, built from
    `<canopen_dir>/<node>.eds`, or without canopen_dir from the EDS runtime.json names (node.eds, beside it).

        with DriveBench(cfg, "generated/allex2/canopen", channel="bench") as bench:
            ...  # a master on can.Bus(interface="virtual", channel="bench")

    By default the drives share one bus connection served by one thread, which hands every frame to each drive: on
    a virtual bus every connection receives every frame, so six connections would mean six threads waking for each
    of the others' frames and competing for the interpreter lock within the master's read window.
    `separate_connections=True` gives each drive its own connection and thread instead (closer to separate
    devices; needs more CPU). `options` gives per-node SimulatedDrive arguments (faults, delays) over the common
    `drive_options`.

    Either way the drives' delayed answers (response_delay_s) go out from one ResponseScheduler thread, timed on
    `drive_options["clock"]` (default SystemClock), so each drive answers its delay after the SYNC whatever the
    others' delays: six drives of 3 ms all answer at 3 ms, not at 3, 6, ... 18 ms. stop() closes it.
    """

    def __init__(
        self,
        cfg: RuntimeConfig,
        canopen_dir: str | Path | None = None,
        *,
        channel: str,
        interface: str = "virtual",
        bus_name: str | None = None,
        nodes: Iterable[str] | None = None,
        options: Mapping[str, Mapping[str, Any]] | None = None,
        separate_connections: bool = False,
        **drive_options: Any,
    ) -> None:
        bus = canopen_bus(cfg, bus_name)
        wanted = set(nodes) if nodes is not None else None
        self.channel, self.interface = channel, interface
        self.separate_connections = separate_connections
        self._notifier: can.Notifier | None = None
        self._clock: Clock = drive_options.get("clock") or SystemClock()
        self.scheduler: ResponseScheduler | None = None
        self.drives: dict[str, SimulatedDrive] = {}
        self._buses: list[can.BusABC] = []
        for node in canopen_slaves(cfg, bus):
            name = node.name
            if wanted is not None and name not in wanted:
                continue
            assert node.node_id is not None
            kwargs = {**drive_options, **(options or {}).get(name, {})}
            if canopen_dir is not None:
                eds = Path(canopen_dir) / f"{name}.eds"
            elif node.eds is not None:
                eds = cfg.path(node.eds)
            else:
                raise ValueError(f"runtime.json names no EDS for node '{name}': give canopen_dir")
            self.drives[name] = SimulatedDrive(node.node_id, eds, name=name, **kwargs)

    def start(self) -> DriveBench:
        scheduler = self.scheduler = ResponseScheduler(self._clock, name=f"{self.channel}-responses")
        if self.separate_connections:
            for drive in self.drives.values():
                bus = can.Bus(interface=self.interface, channel=self.channel)
                self._buses.append(bus)
                drive.attach(bus, scheduler=scheduler)
            return self
        bus = can.Bus(interface=self.interface, channel=self.channel)
        self._buses.append(bus)
        for drive in self.drives.values():
            drive.attach(bus, listen=False, scheduler=scheduler)
        self._notifier = can.Notifier(bus, [self._dispatch], timeout=0.05)
        return self

    def _dispatch(self, msg: can.Message) -> None:
        for drive in self.drives.values():
            drive.on_frame(msg)

    def stop(self) -> None:
        if self._notifier is not None:
            self._notifier.stop(timeout=2.0)
            self._notifier = None
        if self.scheduler is not None:  # before the buses close: no delayed answer is sent on a closed bus
            self.scheduler.close()
            self.scheduler = None
        for drive in self.drives.values():
            drive.detach(join=False)
        for drive in self.drives.values():
            drive.join_threads()
        for bus in self._buses:
            bus.shutdown()
        self._buses.clear()

    def __enter__(self) -> DriveBench:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def __getitem__(self, name: str) -> SimulatedDrive:
        return self.drives[name]
