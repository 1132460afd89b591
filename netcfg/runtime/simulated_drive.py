"""SimulatedDrive: one simulated CANopen drive on a python-can bus (what it does: netcfg.runtime.drives).

Its object dictionary and PDO configuration are netcfg.runtime.drive_dictionary's; this module adds the bus: boot-up
and NMT, the answers to SYNC, the event-driven TPDOs, the RPDOs and their deadlines, and the faults a test injects
at run time (kill, reboot, emergency).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from pathlib import Path

import can
import canopen

from netcfg import cia301
from netcfg.cia301 import RPDO_COMM
from netcfg.runtime.cia402 import CONTROLWORD, PowerStateMachine
from netcfg.runtime.clock import Clock, SystemClock
from netcfg.runtime.drive_dictionary import DriveDictionary, PdoSlot
from netcfg.runtime.drive_responses import ResponseScheduler

log = logging.getLogger(__name__)

EMCY_RPDO_TIMEOUT = 0x8250  # CiA 301 table 21: "RPDO timeout" (the RPDO's deadline, its event timer, passed)
SYNC_GAP = 1.5  # a SYNC this many interpolation periods after the last one: the drive notes it missed some

DriveModel = Callable[["SimulatedDrive"], None]


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


class SimulatedDrive(DriveDictionary):
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
        super().__init__(
            node_id,
            object_dictionary,
            name=name,
            clear_pdos=clear_pdos,
            strict_pdo_writes=strict_pdo_writes,
            identity=identity,
            abort_writes=abort_writes,
        )
        self.response_delay_s = response_delay_s
        self.clock: Clock = clock or SystemClock()
        self.model = model
        self.silent = silent
        self.no_event_timer = no_event_timer
        self.network: canopen.Network | None = None
        self.bus: can.BusABC | None = None
        self._notifier: can.Notifier | None = None
        self._scheduler: ResponseScheduler | None = None
        self._own_scheduler = False
        # what happened, for tests and the bench
        self.syncs = 0  # SYNCs received while OPERATIONAL
        self.tpdos_sent = 0
        self.event_tpdos_sent: dict[int, int] = {}  # event-driven TPDO number -> sends
        self.rpdo_length_errors = 0  # CiA 301 would send EMCY 0x8210
        self.errors: list[str] = []
        self._sync_counts: dict[int, int] = {}
        self._sync_started: set[int] = set()
        self._last_acyclic: dict[int, bytes] = {}
        self._pending: dict[int, tuple[PdoSlot, bytes]] = {}
        self._rpdo_seen: dict[int, int] = {}  # RPDO number -> receptions, for its deadline
        self._last_sync_at: float | None = None
        # event-driven TPDOs, shared by the frame thread (application events at SYNC) and the scheduler (timers)
        self._event_lock = threading.Lock()
        self._event_epoch = 0  # counts entries to OPERATIONAL: timers of an earlier one do nothing
        self._event_last: dict[int, float] = {}  # TPDO number -> its last send (or the entry to OPERATIONAL)
        self._event_sent: dict[int, bytes] = {}  # TPDO number -> the payload it last sent
        self._event_held: set[int] = set()  # TPDOs with an application event held back by the inhibit time
        self.killed = False
        self.reboots = 0
        self.notes: list[str] = []  # what the drive did on its own that a test or the bench reports
        self.emcy_sent: list[tuple[int, int, bytes]] = []
        self._ending: list[threading.Thread] = []  # heartbeat threads told to stop, not yet joined

    # --- faults -----------------------------------------------------------------------------------------------------

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
        answers: list[tuple[PdoSlot, bytes]] = []
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

    def _event_slot(self, number: int, epoch: int) -> PdoSlot | None:
        """The TPDO as the drive holds it now, if its timers still apply (same spell in OPERATIONAL, event-driven)."""
        if epoch != self._event_epoch or self.silent or self.node.nmt.state != "OPERATIONAL":
            return None
        slot = next((s for s in self._tpdos if s.number == number), None)
        return slot if slot is not None and slot.event_driven else None

    def _application_event(self, slot: PdoSlot) -> None:
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

    def _event_send(self, slot: PdoSlot, payload: bytes) -> None:
        """Under _event_lock: one send of an event-driven TPDO; its timer restarts."""
        self._event_last[slot.number] = self.clock.now()
        self._event_sent[slot.number] = payload
        self._send(slot, payload)
        self.event_tpdos_sent[slot.number] = self.event_tpdos_sent.get(slot.number, 0) + 1

    def _send(self, slot: PdoSlot, payload: bytes) -> None:
        network, bus = self.network, self.bus
        if network is None or bus is None or self.silent:
            return  # detached or killed meanwhile (a delayed answer): the drive has left the bus
        with network.send_lock:
            bus.send(can.Message(arbitration_id=slot.can_id, is_extended_id=slot.extended, data=payload))
        self.tpdos_sent += 1

    def _send_later(self, answers: list[tuple[PdoSlot, bytes]]) -> None:
        """A delayed SYNC answer, on the scheduler thread; errors are kept like on_frame's."""
        for slot, payload in answers:
            try:
                self._send(slot, payload)
            except Exception as exc:
                log.exception("%s: error sending TPDO%d", self.name, slot.number)
                self.errors.append(f"TPDO{slot.number} 0x{slot.can_id:X}: {exc!r}")

    def _on_rpdo(self, slot: PdoSlot, data: bytes) -> None:
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

    def _rpdo_deadline(self, slot: PdoSlot, stamp: int) -> None:
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
