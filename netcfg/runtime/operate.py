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

This module runs the phases; the state they share is netcfg.runtime.operate_state's, a rebooted drive's recovery
operate_recovery's, the plan and the outcome operate_outcome's and BusLog bus_log's.
"""

from __future__ import annotations

from collections.abc import Callable

import can
import canopen
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from netcfg.runtime import RuntimeConfig
from netcfg.runtime.bus_log import BUS_POLL_S, BusLog
from netcfg.runtime.canopen_master import CycleRecord, MasterCycle, Samples, configure_network
from netcfg.runtime.canopen_setup import NMT_PRE_OPERATIONAL, NMT_START
from netcfg.runtime.cia402 import STATUSWORD, Cia402Error, PdoEnabler, enable_operation, safe_stop
from netcfg.runtime.clock import Clock, SystemClock
from netcfg.runtime.codec import Number
from netcfg.runtime.drills import Drill
from netcfg.runtime.operate_outcome import NodeOutcome, Outcome, Plan
from netcfg.runtime.operate_recovery import RecoveringOperation
from netcfg.runtime.operate_state import sdo_io
from netcfg.runtime.supervision import BUS_OFF_TEXT, Event, Supervisor, bus_back, sync_gap

__all__ = ["BusLog", "NodeOutcome", "Outcome", "Plan", "operate"]

ABORT_NO_OBJECT = (0x06020000, 0x06090011)


class _Operation(RecoveringOperation):
    """The phases of one run, in order: set_up, start, cycle (with what happens after each cycle), safe_stop."""

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
                        *sdo_io(remote),
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
                BUS_OFF_TEXT,
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
        found, text = bus_back(detected, back, record.sync_sent, self.first)
        self.out.bus_offs.append(found)
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
        found = sync_gap(last, record.sync_sent, self.master.period_s, self.first)
        if found is None:
            return
        self.out.sync_gaps.append(found[0])
        self.supervisor.events.append(
            Event(record.sync_sent, self.master.master.name, "missed-sync", "continue", found[1])
        )

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
            self.out.drills.append((elapsed, Drill("stall", until_ns=round(until * 1e9)).description()))
            self.clock.sleep_until(self.first + until)
        # the statuswords of this cycle first: an event of this cycle (an EMCY's FAULT) has the last word on a state
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
        # every frame queued before the read ended has been fed (the queue is FIFO): check at that instant, so a
        # heartbeat still queued after a late wake-up is not mistaken for silence
        self.supervisor.check(record.read_done)
        self._poll_recoveries()
        while len(self.out.events) < len(self.supervisor.events):
            event = self.supervisor.events[len(self.out.events)]
            self.out.events.append((event.time - self.first, event))
            self._react(event, event.time - self.first)
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
                        *sdo_io(remote),
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
