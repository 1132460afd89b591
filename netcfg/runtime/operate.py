"""Operating a CANopen network from runtime.json, start to safe stop: what `netcfg run` does, as a library.

    with BusLog(can.Bus(interface="socketcan", channel="can0"), "run.log") as bus:
        result = operate(cfg, bus, Plan(cycles=400))

1. Set-up (`configure_network`): identity, PDOs, start-up SDO writes (heartbeat, synchronous window, SYNC counter,
   interpolation period), read back. Nothing starts when a node failed, unless `allow_missing`: then the others run.
2. Start: NMT start of every node set up, then each CiA 402 drive (one that has a statusword 0x6041) through the
   power state machine to OPERATION ENABLED (netcfg.runtime.cia402), with a timeout per transition: over SDO
   before the cycle, or, for a drive whose controlword is mapped into a periodic RxPDO of the master and whose
   statusword into a synchronous TPDO it collects, through those PDOs in the first cycles (one transition per
   cycle); such a drive's statusword also shows its state in every cycle.
3. Cycle: MasterCycle (seed 000's Figure 7) at the spec's SYNC period, with a Supervisor fed every frame the cycle
   does not take (heartbeats, EMCY) and checked after each cycle. A lost node or an EMCY does what the node's
   `on_loss`/`on_emcy` says: `stop_all` ends the cycle; `stop_node` sends that node NMT PRE-OPERATIONAL at once (it
   stops its PDOs and keeps answering SDO, so its drive can be stopped safely at the end); `continue` reports it.
   `stop()` (e.g. from a Ctrl-C handler) ends the cycle after the current iteration.
   A boot-up message (the node rebooted) does what its `on_reboot` says: `recover` sets it up again on a worker
   thread while the cycle runs (configure_node, the set-up's own steps; the cycle hands it its SDO answers, and
   reads the bus in its waits meanwhile) and enables it, over SDO or its PDOs; `stop_node` leaves it
   PRE-OPERATIONAL; `stop_all` ends the cycle. A set-up again that fails follows the node's `on_loss`. A SYNC more
   than half a period late is reported with the instants missed (a stalled host; `Plan.stalls` plays one), and a
   controller that is bus-off (python-can's bus state, or SocketCAN's error frames) holds the cycle until the bus
   is back (`BusLog.bus_off` plays one).
4. Safe stop, whatever ended the run: every started drive still answering gets its `safe_stop` command (quick stop
   or disable operation, CiA 402) over SDO, then every started node NMT PRE-OPERATIONAL.

`BusLog` wraps the python-can bus the master uses and writes every frame it sends or receives to a python-can
log file (`.log` candump -L, `.asc`, `.blf`, `.csv`, `.trc`: can.Logger picks by suffix), closed and flushed when it
closes, which also happens on Ctrl-C or an error.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import canopen
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from netcfg.runtime import RuntimeConfig
from netcfg.runtime.canopen_master import (
    CycleRecord,
    MasterCycle,
    MasterRun,
    Samples,
    SetupReport,
    canopen_bus,
    canopen_slaves,
    configure_network,
)
from netcfg.runtime.canopen_setup import NMT_PRE_OPERATIONAL, NMT_START, configure_node
from netcfg.runtime.cia402 import (
    CONTROLWORD,
    STATUSWORD,
    Cia402Error,
    PdoEnabler,
    enable_operation,
    safe_stop,
)
from netcfg.runtime.clock import Clock, SystemClock
from netcfg.runtime.codec import Number
from netcfg.runtime.supervision import Event, Supervisor

__all__ = ["BusLog", "NodeOutcome", "Outcome", "Plan", "operate"]

ABORT_NO_OBJECT = (0x06020000, 0x06090011)


CAN_ERR_BUSOFF, CAN_ERR_RESTARTED = 0x40, 0x100  # SocketCAN error frame classes (linux/can/error.h)
BUS_POLL_S = 0.001  # how often a master whose controller is bus-off looks whether the bus is back


class BusLog(can.BusABC):
    """A python-can bus that writes every frame sent or received through it to a log file (can.Logger).

    It also plays a bus-off of the controller for drills (`bus_off(duration_s)`), which python-can's virtual bus
    cannot: meanwhile `state` is can.BusState.ERROR, send() raises can.CanOperationError and nothing is received
    (what came is dropped, as a controller off the bus never sees it). Otherwise `state` is the interface's."""

    def __init__(self, bus: can.BusABC, path: str | Path | None) -> None:
        self.inner = bus
        self.path = Path(path) if path is not None else None
        self._logger: Any = can.Logger(str(path)) if path is not None else None
        self._lock = threading.Lock()
        self.channel_info = f"logged {bus.channel_info}"
        # the channel name the log gives the frames this side sends (received ones carry the interface's)
        names = (getattr(bus, attr, None) for attr in ("channel_id", "channel"))  # virtual's, socketcan's, ...
        self.channel_name = next((n for n in names if isinstance(n, (str, int))), None)
        self._filters = None
        self._is_shutdown = False
        self._last = 0.0  # the log's latest timestamp
        self._off_until: float | None = None  # time.monotonic() the simulated bus-off ends

    def bus_off(self, duration_s: float) -> None:
        """The controller goes bus-off now and is back on the bus after duration_s (a drill)."""
        self._off_until = time.monotonic() + duration_s

    def _off(self) -> bool:
        if self._off_until is not None and time.monotonic() >= self._off_until:
            self._off_until = None
        return self._off_until is not None

    @property
    def state(self) -> can.BusState:
        if self._off():
            return can.BusState.ERROR
        try:
            return self.inner.state
        except NotImplementedError:
            return can.BusState.ACTIVE

    @state.setter
    def state(self, new_state: can.BusState) -> None:
        self.inner.state = new_state

    def _log(self, msg: can.Message) -> None:
        if self._logger is not None:
            with self._lock:
                # in time order, as a log must be (netcfg verify reads it): a reply stamped by its sender can come
                # in before our own frame's stamp is logged; it is logged no earlier than the frame before it
                if msg.timestamp < self._last:
                    msg.timestamp = self._last
                self._last = msg.timestamp
                self._logger.on_message_received(msg)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self._off():
            raise can.CanOperationError("the CAN controller is bus-off")
        queued = time.time()
        self.inner.send(msg, timeout)
        sent = can.Message(
            timestamp=queued,
            arbitration_id=msg.arbitration_id,
            is_extended_id=msg.is_extended_id,
            is_remote_frame=msg.is_remote_frame,
            dlc=msg.dlc,
            data=msg.data,
            is_rx=False,
            channel=msg.channel or self.channel_name,
        )
        self._log(sent)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        if self._off():
            end = None if timeout is None else time.monotonic() + timeout
            while self._off():  # frames on the bus meanwhile never reach a controller that is off it
                left = None if end is None else end - time.monotonic()
                if left is not None and left <= 0:
                    return None
                self.inner.recv(min(left, BUS_POLL_S) if left is not None else BUS_POLL_S)
            timeout = None if end is None else max(0.0, end - time.monotonic())
        msg = self.inner.recv(timeout)
        if msg is not None:
            self._log(msg)
        return msg

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.recv(timeout), True  # pragma: no cover - recv is overridden

    def shutdown(self) -> None:
        """Flush and close the log, then the bus."""
        if self._is_shutdown:
            return
        self._is_shutdown = True
        with self._lock:
            if self._logger is not None:
                self._logger.stop()
                self._logger = None
        self.inner.shutdown()


@dataclass
class Plan:
    """What to run. `cycles` None: until stop(). `at_cycle` holds actions run after a cycle whose end is at least
    that many seconds into the cycle phase (fault drills on simulated drives: kill, EMCY)."""

    cycles: int | None
    bus_name: str | None = None
    allow_missing: bool = False
    transition_timeout_s: float = 0.5
    sdo_timeout_s: float | None = None  # None: each node's sdo_timeout_ns (runtime.json)
    drills: list[tuple[float, str, Callable[[], None]]] = field(default_factory=list)  # (at s, text, action)
    stalls: list[tuple[float, float]] = field(default_factory=list)  # (from s, to s): the master's loop pauses
    on_cycle: Callable[[CycleRecord, Outcome], None] | None = None  # e.g. a live view


@dataclass
class NodeOutcome:
    name: str
    node_id: int
    setup_ok: bool = False
    setup_error: str | None = None
    started: bool = False
    cia402: bool = False
    cia402_over: str | None = None  # "SDO", or "PDO" when its controlword and statusword are mapped
    state: str = "NOT STARTED"  # the drive's state as the master last knew it while running
    enable_path: list[str] = field(default_factory=list)  # CiA 402 states passed through on the way up
    safe_state: str | None = None  # the state after the safe stop
    stopped_at_s: float | None = None  # stop_node: when the master stopped it (cycle phase seconds)
    lost_at_s: float | None = None
    lost_silent_ms: float | None = None
    heartbeat_timeout_ms: float | None = None
    emcy: list[dict[str, Any]] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    # each boot-up while running: {"at_s", "action", "recovered_at_s", "recovery_ms", "result"}
    reboots: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class _Recovery:
    """A drive that rebooted being set up again beside the cycle, on a worker thread; the cycle hands its SDO answers
    to `network` (see _Operation._on_frame). `done` is the clock time it ended, `error` why it failed."""

    node: str
    booted: float  # clock time of the boot-up message
    network: canopen.Network
    thread: threading.Thread | None = None
    done: float | None = None
    error: str | None = None
    path: list[str] = field(default_factory=list)


@dataclass
class Outcome:
    bus: str
    nodes: dict[str, NodeOutcome]
    setup: SetupReport | None = None
    run: MasterRun | None = None
    events: list[tuple[float, Event]] = field(default_factory=list)  # (cycle phase seconds, event)
    drills: list[tuple[float, str]] = field(default_factory=list)
    ended_by: str = "cycles"  # cycles | stop_all:<node> | stop() | set-up
    started: bool = False
    sync_completion_ns: int | None = None
    master_jitter_ns: int = 0  # the analysed bound of how late the master's SYNC may come
    bad_emcy: int = 0
    # the CAN controller off the bus: {"detected_s", "back_s", "first_sync_s", "off_ms", "recovery_ms"}
    bus_offs: list[dict[str, Any]] = field(default_factory=list)
    # SYNC instants the master let pass (its loop stalled): {"from_s", "to_s", "missed", "instants_s"}
    sync_gaps: list[dict[str, Any]] = field(default_factory=list)
    t0: float = 0.0  # clock time the cycle phase began: the origin of every *_s time above

    def out_of_service(self, node: str, t: float) -> bool:
        """The master had stopped the node, or found it lost, by clock time t."""
        n = self.nodes[node]
        marks = [m for m in (n.stopped_at_s, n.lost_at_s) if m is not None]
        return bool(marks) and t - self.t0 >= min(marks)


class _Operation:
    def __init__(self, cfg: RuntimeConfig, bus: can.BusABC, plan: Plan, clock: Clock) -> None:
        self.cfg, self.bus, self.plan, self.clock = cfg, bus, plan, clock
        self.co_bus = canopen_bus(cfg, plan.bus_name)
        assert self.co_bus.canopen is not None
        self.slaves = canopen_slaves(cfg, self.co_bus)
        self.out = Outcome(
            self.co_bus.name,
            {n.name: NodeOutcome(n.name, n.node_id or 0) for n in self.slaves},
            sync_completion_ns=self.co_bus.canopen.sync_completion_ns,
            master_jitter_ns=self.co_bus.canopen.master_jitter_ns,
        )
        self.stop_requested: str | None = None
        self.supervisor: Supervisor | None = None
        self.pdo_drives = self._pdo_mapped()  # node -> (RxPDO, controlword field, TPDO, statusword field)
        self.enablers: dict[str, PdoEnabler] = {}
        self.first: float | None = None
        self.drills = sorted(plan.drills, key=lambda d: d[0])
        self.stalls = sorted(plan.stalls)
        self.last_sync: float | None = None
        self.error_frame_bus_off = False  # SocketCAN said bus-off in an error frame, and no restart since
        self.bus_back: tuple[float, float] | None = None  # (detected, back) of a bus-off the cycle resumes after
        self.master: MasterCycle | None = None
        self.recovering: dict[str, _Recovery] = {}
        self.sdo_routes: dict[int, _Recovery] = {}  # SDO response COB-ID -> the recovery awaiting it
        self.timeout_cycles = 1

    # --- SDO access for the CiA 402 phases (a canopen Network with its own Notifier, outside the cycle) -------

    def _with_sdo(self, job: Callable[[canopen.Network], None]) -> None:
        network = canopen.Network(self.bus)
        network.notifier = can.Notifier(self.bus, network.listeners, timeout=0.02)
        try:
            job(network)
        finally:
            network.notifier.stop(timeout=2.0)
            network.notifier = None

    def _remote(self, network: canopen.Network, node_id: int) -> canopen.RemoteNode:
        remote = canopen.RemoteNode(node_id, canopen.ObjectDictionary())
        node = self.cfg.node(self._name(node_id))
        timeout = self.plan.sdo_timeout_s
        remote.sdo.RESPONSE_TIMEOUT = timeout if timeout is not None else node.sdo_timeout_ns / 1e9
        remote.sdo.MAX_RETRIES = node.sdo_retries + 1
        network.add_node(remote)
        return remote

    def _pdo_mapped(self) -> dict[str, tuple[str, str, str, str]]:
        """Drives whose controlword (0x6040) a periodic RxPDO of the master carries and whose statusword (0x6041) a
        synchronous TPDO the master collects carries."""
        control: dict[str, tuple[str, str]] = {}
        status: dict[str, tuple[str, str]] = {}
        for m in self.cfg.messages_on(self.co_bus.name):
            if m.pdo is None:
                continue
            for e in m.pdo.entries:
                if (e.index, e.sub) == (CONTROLWORD, 0) and m.pdo.kind == "rpdo" and m.kind == "periodic":
                    control.setdefault(m.pdo.node, (m.name, e.name))
                elif (
                    (e.index, e.sub) == (STATUSWORD, 0) and m.pdo.kind == "tpdo" and m.pdo.transmission in range(1, 241)
                ):
                    status.setdefault(m.pdo.node, (m.name, e.name))
        return {n: (*control[n], *status[n]) for n in control if n in status}

    def _nmt(self, command: int, node_id: int) -> None:
        try:
            self.bus.send(can.Message(arbitration_id=0, is_extended_id=False, data=[command, node_id]))
        except can.CanError as exc:
            self.out.nodes[self._name(node_id)].errors.append(f"NMT 0x{command:02X} not sent: {exc}")

    def _name(self, node_id: int) -> str:
        return next(n.name for n in self.slaves if n.node_id == node_id)

    # --- the phases ---------------------------------------------------------------------------------------------

    def set_up(self) -> bool:
        report = configure_network(
            self.cfg, self.bus, bus_name=self.co_bus.name, sdo_timeout_s=self.plan.sdo_timeout_s, start=False
        )
        self.out.setup = report
        for ns in report.nodes:
            node = self.out.nodes[ns.node]
            node.setup_ok, node.setup_error = ns.ok, ns.error
            node.state = "SET UP" if ns.ok else "SET-UP FAILED"
        if not report.ok and not self.plan.allow_missing:
            self.out.ended_by = "set-up"
            return False
        return any(ns.ok for ns in report.nodes)

    def start(self) -> bool:
        ready = [n for n in self.slaves if self.out.nodes[n.name].setup_ok]
        for n in ready:
            assert n.node_id is not None
            self._nmt(NMT_START, n.node_id)
            self.out.nodes[n.name].started = True
            self.out.nodes[n.name].state = "OPERATIONAL"
        self.out.started = bool(ready)
        failed: list[str] = []

        def enable(network: canopen.Network) -> None:
            for n in ready:
                assert n.node_id is not None
                node = self.out.nodes[n.name]
                remote = self._remote(network, n.node_id)
                try:
                    remote.sdo.upload(STATUSWORD, 0)
                except SdoAbortedError as exc:
                    if exc.code in ABORT_NO_OBJECT:
                        continue  # not a CiA 402 drive: NMT OPERATIONAL is all it needs
                    node.errors.append(f"statusword 0x6041 not readable: {exc}")
                    failed.append(n.name)
                    continue
                except SdoCommunicationError as exc:
                    node.errors.append(f"no SDO answer after NMT start: {exc}")
                    failed.append(n.name)
                    continue
                node.cia402 = True
                if n.name in self.pdo_drives:
                    node.cia402_over = "PDO"  # enabled by the first cycles (cycle())
                    continue
                node.cia402_over = "SDO"
                try:
                    node.enable_path = enable_operation(
                        n.name,
                        *_sdo_io(remote),
                        timeout_s=self.plan.transition_timeout_s,
                    )
                    node.state = node.enable_path[-1]
                except (Cia402Error, SdoAbortedError, SdoCommunicationError) as exc:
                    node.errors.append(str(exc))
                    node.state = "ENABLE FAILED"
                    failed.append(n.name)

        self._with_sdo(enable)
        if failed and not self.plan.allow_missing:
            self.out.ended_by = "enable failed: " + ", ".join(failed)
            return False
        return True

    def cycle(self) -> None:
        running = [n for n, o in self.out.nodes.items() if o.started and o.state not in ("ENABLE FAILED",)]
        if not running:
            return
        supervisor = self.supervisor = Supervisor(self.cfg, self.co_bus, running)
        cycles = self.plan.cycles if self.plan.cycles is not None else 2**62
        period_ns = self.co_bus.canopen.sync_period_ns if self.co_bus.canopen else 1
        timeout_cycles = self.timeout_cycles = -(-round(self.plan.transition_timeout_s * 1e9) // period_ns)
        self.enablers = {n: PdoEnabler(n, timeout_cycles) for n in running if self.out.nodes[n].cia402_over == "PDO"}
        pdo_enabled = bool(self.enablers)
        master = self.master = MasterCycle(
            self.cfg,
            self.bus,
            self.clock,
            bus_name=self.co_bus.name,
            nodes=running,
            commands=self._commands if pdo_enabled else None,
            on_frame=self._on_frame,
            after_cycle=self._after_cycle,
            serve=lambda: bool(self.recovering),
        )
        self.first = self.out.t0 = self.clock.now()
        supervisor.start(self.first)
        try:
            self.out.run = master.run(cycles)
        finally:
            self._finish_recoveries()
        self.out.bad_emcy = supervisor.bad_emcy
        for name, w in supervisor.watched.items():
            node = self.out.nodes[name]
            node.emcy = [{"time_s": round(e.time - self.first, 6), **e.as_json(), "text": str(e)} for e in w.emcys]
            node.heartbeat_timeout_ms = None if w.timeout_s is None else 1e3 * w.timeout_s
            if w.lost_at is not None and w.silent_for_s is not None:
                node.lost_at_s = w.lost_at - self.first
                node.lost_silent_ms = 1e3 * w.silent_for_s
                node.state = "LOST"

    def _on_frame(self, frame: can.Message, t: float) -> None:
        """Frames the cycle does not take: SDO answers to a drive being set up again go to its recovery, the rest
        to supervision."""
        if frame.is_error_frame:  # SocketCAN reports controller states in error frames, not in bus.state
            if frame.arbitration_id & CAN_ERR_BUSOFF:
                self.error_frame_bus_off = True
            if frame.arbitration_id & CAN_ERR_RESTARTED:
                self.error_frame_bus_off = False
        route = self.sdo_routes.get(frame.arbitration_id) if not frame.is_extended_id else None
        if route is not None:
            route.network.notify(frame.arbitration_id, bytearray(frame.data), t)
            return
        assert self.supervisor is not None
        self.supervisor.feed(frame, t)

    # --- a drive that rebooted (on_reboot) ------------------------------------------------------------------------

    def _recover(self, name: str, booted: float) -> None:
        """Set the node up again (the set-up's own code path: identity, PDOs, start-up values, read-back, NMT start)
        and, over SDO, enable its CiA 402 power state machine, on a worker thread while the others cycle."""
        node_cfg = self.cfg.node(name)
        assert node_cfg.node_id is not None
        rec = _Recovery(name, booted, canopen.Network(self.bus))
        self.sdo_routes[0x580 + node_cfg.node_id] = rec  # CiA 301 default SDO server -> client COB-ID
        self.recovering[name] = rec
        outcome = self.out.nodes[name]

        def work() -> None:
            try:
                setup = configure_node(
                    self.cfg, rec.network, node_cfg, bus=self.co_bus, sdo_timeout_s=self.plan.sdo_timeout_s
                )
                if not setup.ok:
                    rec.error = f"set-up again failed at {setup.step}: {setup.error}"
                elif outcome.cia402_over == "SDO":
                    remote = self._remote(rec.network, node_cfg.node_id or 0)
                    try:
                        rec.path = enable_operation(name, *_sdo_io(remote), timeout_s=self.plan.transition_timeout_s)
                    finally:
                        del rec.network[node_cfg.node_id or 0]
            except (Cia402Error, SdoAbortedError, SdoCommunicationError, can.CanError) as exc:
                rec.error = f"enabling again failed: {exc}"
            finally:
                rec.done = self.clock.now()

        rec.thread = threading.Thread(target=work, name=f"netcfg-recover-{name}", daemon=True)
        rec.thread.start()

    def _poll_recoveries(self) -> None:
        """Recoveries that ended: a "recovered" event, or "recovery-failed" with the node's on_loss."""
        assert self.supervisor is not None and self.master is not None
        for name, rec in list(self.recovering.items()):
            if rec.done is None:
                continue
            enabler = self.enablers.get(name)
            if rec.error is None and self.out.nodes[name].cia402_over == "PDO":
                if enabler is None or enabler.error is not None:  # configured and started: now its PDO walk
                    self.enablers[name] = PdoEnabler(name, self.timeout_cycles)
                    self.master.muted.discard(name)
                    continue
                if not enabler.enabled:
                    continue
                rec.path = list(enabler.path)
            del self.recovering[name]
            self.sdo_routes = {k: v for k, v in self.sdo_routes.items() if v is not rec}
            node = self.out.nodes[name]
            took_ms = 1e3 * (rec.done - rec.booted)
            if rec.error is None:
                self.master.muted.discard(name)
                self.supervisor.quiet.discard(name)
                text = (
                    f"{name} recovered {took_ms:.1f} ms after its boot-up: identity checked, configuration written "
                    f"and read back, started, {' -> '.join(rec.path) or 'OPERATIONAL'}"
                )
                self.supervisor.events.append(Event(rec.done, name, "recovered", "continue", text))
                node.state = rec.path[-1] if rec.path else "OPERATIONAL"
            else:
                action = self.cfg.node(name).on_loss
                text = f"{name} not recovered ({took_ms:.1f} ms after its boot-up): {rec.error}"
                self.supervisor.events.append(Event(rec.done, name, "recovery-failed", action, text))
                node.errors.append(rec.error)
            node.reboots[-1].update(
                recovered_at_s=round(rec.done - (self.first or 0.0), 6) if rec.error is None else None,
                recovery_ms=round(took_ms, 3),
                result="recovered" if rec.error is None else rec.error,
            )

    def _finish_recoveries(self) -> None:
        """The cycle ended with a recovery under way: keep handing it its SDO answers until it ends."""
        for rec in list(self.recovering.values()):
            while rec.thread is not None and rec.thread.is_alive():
                frame = self.bus.recv(timeout=0.01)
                if frame is not None:
                    self._on_frame(frame, self.clock.now())
            if rec.done is not None and rec.error is None and self.out.nodes[rec.node].cia402_over == "PDO":
                rec.error = "the run ended before its CiA 402 walk over PDOs"
        if self.supervisor is not None and self.master is not None:
            self._poll_recoveries()
            while len(self.out.events) < len(self.supervisor.events):
                event = self.supervisor.events[len(self.out.events)]
                self.out.events.append((event.time - (self.first or 0.0), event))

    def _bus_is_off(self) -> bool:
        """The controller is off the bus: python-can's bus state says so (interfaces that report one), or a
        SocketCAN error frame did."""
        try:
            state = self.bus.state
        except NotImplementedError:
            state = can.BusState.ACTIVE
        return state is can.BusState.ERROR or self.error_frame_bus_off

    def _ride_out_bus_off(self) -> None:
        """Bus-off: nothing can be sent, so the master stops sending (no SYNC, no RxPDO) and looks every BUS_POLL_S
        whether the bus is back; then the cycle resumes. Supervision restarts its clocks then: no heartbeat could
        be heard meanwhile."""
        assert self.supervisor is not None and self.master is not None
        detected = self.clock.now()
        master = self.master.master.name
        self.supervisor.events.append(
            Event(
                detected,
                master,
                "bus-off",
                "hold",
                "the master's CAN controller is bus-off: it stops sending and waits for the bus",
            )
        )
        while self._bus_is_off() and self.stop_requested is None:
            frame = self.bus.recv(timeout=BUS_POLL_S)
            if frame is not None:
                self._on_frame(frame, self.clock.now())
        back = self.clock.now()
        self.supervisor.resume(back)
        self.bus_back = (detected, back)

    def _bus_recovered(self, record: CycleRecord) -> None:
        """The first cycle after a bus-off: how long the bus was off and how soon the SYNC followed its return."""
        if self.bus_back is None or self.supervisor is None or self.master is None or self.first is None:
            return
        (detected, back), self.bus_back = self.bus_back, None
        off_ms, recovery_ms = 1e3 * (back - detected), 1e3 * (record.sync_sent - back)
        self.out.bus_offs.append(
            {
                "detected_s": round(detected - self.first, 6),
                "back_s": round(back - self.first, 6),
                "first_sync_s": round(record.sync_sent - self.first, 6),
                "off_ms": round(off_ms, 3),
                "recovery_ms": round(recovery_ms, 3),
            }
        )
        text = (
            f"the bus is back after {off_ms:.1f} ms off (detected at {detected - self.first:.3f} s); the first SYNC "
            f"went out {recovery_ms:.1f} ms after its return"
        )
        self.supervisor.events.append(Event(record.sync_sent, self.master.master.name, "bus-on", "continue", text))

    def _missed_syncs(self, record: CycleRecord) -> None:
        """SYNC instants that passed without a SYNC: a SYNC more than half a period after its instant means the
        master's loop was held (a stalled host, a bus-off); the gap is reported with the instants missed."""
        assert self.supervisor is not None and self.master is not None and self.first is not None
        if not record.sync_ok:
            return  # no SYNC went out: this instant is among those the next SYNC reports missed
        last, self.last_sync = self.last_sync, record.sync_sent
        if last is None:
            return
        period = self.master.period_s
        gap = record.sync_sent - last
        missed = round(gap / period) - 1
        if missed < 1:
            return
        instants = [round(last - self.first + k * period, 6) for k in range(1, missed + 1)]
        from_s, to_s = last - self.first, record.sync_sent - self.first
        self.out.sync_gaps.append(
            {"from_s": round(from_s, 6), "to_s": round(to_s, 6), "missed": missed, "instants_s": instants}
        )
        text = (
            f"no SYNC for {1e3 * gap:.1f} ms ({from_s:.3f} s to {to_s:.3f} s): {missed} SYNC instants of the "
            f"{1e3 * period:g} ms period missed; the cycle resumed"
        )
        self.supervisor.events.append(Event(record.sync_sent, self.master.master.name, "missed-sync", "continue", text))

    def _commands(self, cycle: int, samples: Samples) -> dict[str, dict[str, Number]]:
        """The controlwords of the PDO-mapped drives, from the statuswords of the last cycle."""
        out: dict[str, dict[str, Number]] = {}
        for name, enabler in self.enablers.items():
            rpdo, cw_field, tpdo, sw_field = self.pdo_drives[name]
            sw = samples.get(tpdo, {}).get(sw_field)
            out[rpdo] = {cw_field: enabler.step(None if sw is None else int(sw))}
        return out

    def _after_cycle(self, record: CycleRecord) -> bool:
        assert self.supervisor is not None and self.first is not None
        now = self.clock.now()
        elapsed = now - self.first
        self._bus_recovered(record)
        self._missed_syncs(record)
        if self._bus_is_off():
            self._ride_out_bus_off()
        while self.drills and self.drills[0][0] <= elapsed:
            _, text, action = self.drills.pop(0)
            action()
            self.out.drills.append((elapsed, text))
        while self.stalls and self.stalls[0][0] <= elapsed:
            _, until = self.stalls.pop(0)
            self.out.drills.append((elapsed, f"the master's loop stalls until {until:g} s: no SYNC, no RxPDO"))
            self.clock.sleep_until(self.first + until)
        # every frame queued before the read ended has been fed (the queue is FIFO): check at that instant, so a
        # heartbeat still queued after a late wake-up is not mistaken for silence
        self.supervisor.check(record.read_done)
        self._poll_recoveries()
        while len(self.out.events) < len(self.supervisor.events):
            event = self.supervisor.events[len(self.out.events)]
            self.out.events.append((event.time - self.first, event))
            self._react(event, event.time - self.first)
        for name, enabler in self.enablers.items():
            node = self.out.nodes[name]
            node.enable_path = list(enabler.path)
            if node.lost_at_s is None and node.stopped_at_s is None and enabler.state is not None:
                node.state = enabler.state  # the statusword of this cycle's TPDO
            if enabler.error is not None and enabler.error not in node.errors:
                node.errors.append(enabler.error)
                node.state = "ENABLE FAILED"
                if self.stop_requested is None:
                    self.stop_requested = f"enable failed: {name}"
        if self.plan.on_cycle is not None:
            self.plan.on_cycle(record, self.out)
        return self.stop_requested is None

    def _react(self, event: Event, at_s: float) -> None:
        if event.node not in self.out.nodes:
            return  # the master's own (missed SYNCs, bus-off): reported, nothing to do for a node
        node = self.out.nodes[event.node]
        if event.kind == "lost":
            node.state = "LOST"
        elif event.kind == "back":
            node.state = "STOPPED (heartbeat back)" if node.stopped_at_s is not None else "BACK (heartbeat again)"
        elif event.kind == "emcy" and event.action != "continue":
            node.state = "FAULT"
        elif event.kind == "boot-up":
            self._rebooted(event, at_s)
            return
        if event.action == "stop_all" and self.stop_requested is None:
            self.stop_requested = f"stop_all: {event.text}"
        elif event.action == "stop_node" and node.stopped_at_s is None:
            node.stopped_at_s = at_s
            if self.supervisor is not None:
                self.supervisor.quiet.add(event.node)  # its TPDOs stop with it
            self._nmt(NMT_PRE_OPERATIONAL, node.node_id)  # its PDOs stop; SDO still answers for the safe stop

    def _rebooted(self, event: Event, at_s: float) -> None:
        """A boot-up message: the node is PRE-OPERATIONAL with its default object dictionary. Its RxPDOs stop (they
        would land in an unconfigured dictionary), its TPDOs are not expected; then the node's on_reboot."""
        assert self.supervisor is not None and self.master is not None
        node = self.out.nodes[event.node]
        node.reboots.append({"at_s": round(at_s, 6), "action": event.action})
        node.state = "REBOOTED (PRE-OPERATIONAL)"
        node.lost_at_s = node.lost_silent_ms = None
        self.master.muted.add(event.node)
        self.supervisor.quiet.add(event.node)
        self.enablers.pop(event.node, None)
        if event.action == "recover" and event.node not in self.recovering:
            node.stopped_at_s = None
            node.state = "RECOVERING"
            self._recover(event.node, event.time)
            return
        if node.stopped_at_s is None:
            node.stopped_at_s = at_s  # it stays PRE-OPERATIONAL: nothing is sent to it
        node.reboots[-1]["result"] = "left stopped"
        if event.action == "stop_all" and self.stop_requested is None:
            self.stop_requested = f"stop_all: {event.text}"

    def stop(self, reason: str = "stop()") -> None:
        if self.stop_requested is None:
            self.stop_requested = reason

    def safe_stop(self) -> None:
        started = [n for n in self.slaves if self.out.nodes[n.name].started]
        if not started:
            return

        def stop_drives(network: canopen.Network) -> None:
            for n in started:
                node = self.out.nodes[n.name]
                if not node.cia402 or node.lost_at_s is not None:
                    continue  # a lost node cannot answer; it stops on its own heartbeat/communication error
                assert n.node_id is not None
                remote = self._remote(network, n.node_id)
                try:
                    node.safe_state = safe_stop(
                        n.name,
                        *_sdo_io(remote),
                        n.safe_stop,
                        timeout_s=self.plan.transition_timeout_s,
                    )
                except (Cia402Error, SdoAbortedError, SdoCommunicationError) as exc:
                    node.errors.append(f"safe stop ({n.safe_stop}) failed: {exc}")

        try:
            self._with_sdo(stop_drives)
        finally:
            for n in started:
                assert n.node_id is not None
                self._nmt(NMT_PRE_OPERATIONAL, n.node_id)


def _sdo_io(remote: canopen.RemoteNode) -> tuple[Callable[[], int], Callable[[int], None]]:
    """Read the statusword, write the controlword of one drive over SDO."""

    def read() -> int:
        return int.from_bytes(remote.sdo.upload(STATUSWORD, 0)[:2], "little")

    def write(controlword: int) -> None:
        remote.sdo.download(CONTROLWORD, 0, controlword.to_bytes(2, "little"))

    return read, write


def operate(
    cfg: RuntimeConfig,
    bus: can.BusABC,
    plan: Plan,
    clock: Clock | None = None,
    ready: Callable[[Callable[[str], None]], None] | None = None,
) -> Outcome:
    """Set up, start, cycle and stop safely (module docstring). `ready(stop)` is called once the cycle is about to
    begin with a function that ends it (for a signal handler). The safe stop runs however the cycle ended,
    including an exception, which is re-raised after it."""
    op = _Operation(cfg, bus, plan, clock or SystemClock())
    if not op.set_up():
        return op.out
    try:
        if op.start():
            if ready is not None:
                ready(op.stop)
            op.cycle()
            if op.stop_requested is not None:
                op.out.ended_by = op.stop_requested
    finally:
        op.safe_stop()
    return op.out
