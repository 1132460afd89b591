"""The fault drills of `netcfg run` in the simulator: `netcfg simulate --fault KIND:ARG`, one grammar with run's
`--KIND ARG` (netcfg.runtime.drills), played on a CANopen bus whose master is the live MasterCycle
(netcfg.sim.canopen), in virtual time, so a spec's fault reactions are checked without a bus or a host's timing.

What each drill does here, and what the master does about it (its Supervisor and the node's on_loss, on_emcy,
on_reboot, as in netcfg.runtime.operate):
- kill (= crash): the node sends nothing more; its heartbeat's silence is a loss.
- emcy: the node sends its EMCY (COB-ID 0x80 + node id: error code, error register 0x01, five manufacturer
  bytes 0, CiA 301 7.2.7.3); its PDOs go on (a CiA 402 fault shows in the statusword, which the simulator does
  not model). on_emcy `stop_node`: the master sends the node NMT "enter pre-operational" (CiA 301 7.2.8.3.1.1) and
  stops its RxPDOs; the node stops its PDOs when that frame reaches it. `stop_all`: the cycle ends and every node
  gets NMT "enter pre-operational" (the safe stop's SDO commands, quick stop or disable operation, are not played:
  the simulated drives have no object dictionary). `continue`: nothing.
- reset: the node is silent from T, and at T + OUTAGE sends its boot-up message (heartbeat COB-ID, one byte 0x00,
  CiA 301 7.2.8.3.2.1) and is PRE-OPERATIONAL with its default dictionary: no PDO, and no heartbeat the
  configuration could give the period of. The master stops its RxPDOs at the boot-up and does what on_reboot
  says; `recover` (set-up again over SDO, CiA 402 enable) is SDO traffic to an object dictionary the simulator
  does not have: it is reported as not played (a finding), and `run --simulated-drives --reset` drills it.
- stall: after the first cycle that ends at or after T the master's loop sleeps until T2 (no SYNC, no RxPDO).
- bus-off: from T to T2 the master's controller sends nothing (a send raises can.CanOperationError) and hears
  nothing; after the cycle whose sends failed the master holds until the bus is back, restarts supervision's
  clocks (as operate does) and goes on.
After a stall or a bus-off the anchored cycle goes on at the next instant of its grid, and each gap in the SYNCs is
reported with the instants it missed (`sync_gaps`, as run's JSON).
- sdo-abort is refused (netcfg.sim.faults): it acts on the set-up, and a simulation starts with every node set up.
"""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING, Any, Protocol, cast

import can

from netcfg.cia301 import NMT_BOOT_UP, NMT_STATE_PRE_OPERATIONAL
from netcfg.links import pycan_frames
from netcfg.protocols.canopen.services import fd_services
from netcfg.runtime.drills import Drill
from netcfg.runtime.supervision import BUS_OFF_TEXT, Event, Supervisor, bus_back, sync_gap
from netcfg.sim.engine import NEVER

if TYPE_CHECKING:
    from netcfg.runtime import Bus
    from netcfg.runtime.canopen_master import CycleRecord, MasterCycle
    from netcfg.sim.can_bus import CanBus
    from netcfg.sim.pybus import SimCanBus, VirtualClock
    from netcfg.sim.run import SimRun


class CanopenMaster(Protocol):
    """What the drills use of netcfg.sim.canopen's master (which imports this module, so it is not imported)."""

    sc: SimRun
    can: CanBus
    bus: Bus
    master: str
    drives: list[str]
    drills: DrillPlayer

    @property
    def live(self) -> bool: ...

NMT_ID = 0x000
NMT_PRE_OPERATIONAL = 0x80  # CiA 301 7.2.8.3.1.1: enter pre-operational
NMT_STOP = 0x02
EMCY_BASE = 0x080
EMCY_REGISTER = 0x01  # CiA 301 7.5.2.2: generic error


def install(sc: SimRun, drill: Drill) -> None:
    """Give the drill to the live CANopen master of the bus it acts on (a node drill: the bus of its node; a master
    drill: every live CANopen master). ValueError when there is none."""
    # the CANopen masters: the drivers with a DrillPlayer (netcfg.sim.canopen imports this module, not the reverse)
    live = [
        cast("CanopenMaster", d)
        for d in sc.protocols.values()
        if isinstance(getattr(d, "drills", None), DrillPlayer) and getattr(d, "live", False)
    ]
    if not live:
        raise ValueError(
            "a drill acts on a CANopen bus simulated with its live master (PDO mode, --canopen pdo, not --mode "
            "unsync)" + ("" if any(b.canopen for b in sc.cfg.buses) else "; this system has no CANopen bus")
        )
    if drill.node is None:
        for m in live:
            m.drills.add(drill)
        return
    on = [m for m in live if drill.node in m.drives]
    if not on:
        drives = sorted({d for m in live for d in m.drives})
        raise ValueError(f"'{drill.node}' is not a drive of a simulated CANopen bus ({', '.join(drives)})")
    on[0].drills.add(drill)


class DrillPlayer:
    """The drills of one CANopen bus and the master's reactions to what they cause (module docstring)."""

    def __init__(self, master: CanopenMaster) -> None:
        self.m = master
        self.drills: list[Drill] = []
        self.stopped: dict[str, int] = {}  # drive -> when its PDOs stopped (NMT pre-operational or stop reached it)
        self.played: list[dict[str, Any]] = []  # {"time_s", "text"}: the drills as they happened
        self.sync_gaps: list[dict[str, object]] = []
        self.bus_offs: list[dict[str, object]] = []
        self.findings: list[str] = []
        self.ended_by: str | None = None
        self._stalls: list[Drill] = []
        self._bus_back: tuple[float, float] | None = None
        self._last_sync: float | None = None
        self._seen = 0  # supervisor events reacted to
        self._cycle: MasterCycle | None = None
        self._pybus: SimCanBus | None = None
        self._clock: VirtualClock | None = None
        self._supervisor: Supervisor | None = None
        self._listening = False

    def __bool__(self) -> bool:
        return bool(self.drills)

    @property
    def _fd(self) -> bool:
        """The services the drills add (EMCY, boot-up, NMT) go as the bus's SYNC and heartbeats do."""
        return fd_services(self.m.bus)

    def add(self, drill: Drill) -> None:
        sc, can_bus = self.m.sc, self.m.can
        fd = self._fd
        self.drills.append(drill)
        if not self._listening:  # the drives hear the master's NMT commands
            can_bus.monitor(self._heard)
            self._listening = True
        if drill.kind == "emcy":
            node = sc.cfg.node(str(drill.node))
            assert node.node_id is not None
            src = can_bus.add_source(f"{node.name}_emcy", EMCY_BASE + node.node_id, False, 8, node.name, fd=fd, brs=fd)
            payload = drill.code.to_bytes(2, "little") + bytes([EMCY_REGISTER]) + bytes(5)
            sc.sim.at(drill.at_ns, self._emcy, (drill, src, payload))
        elif drill.kind == "reset":
            msgs = sc.cfg.messages_on(self.m.bus.name)
            beat = next((m for m in msgs if m.implicit == "heartbeat" and m.producer == drill.node), None)
            node = sc.cfg.node(str(drill.node))
            assert node.node_id is not None
            src = sc.msg_source[beat.name][1] if beat is not None else can_bus.add_source(
                f"{node.name}_boot_up", 0x700 + node.node_id, False, 1, node.name, fd=fd, brs=fd
            )
            period = beat.interval_ns or 0 if beat is not None else 0
            sc.sim.at(drill.at_ns, self._note, drill)
            sc.sim.at(drill.until_ns, self._boot, (src, period))
        elif drill.kind == "stall":
            self._stalls.append(drill)
            self._stalls.sort(key=lambda d: d.at_ns)
        elif drill.kind in ("bus-off", "kill"):
            sc.sim.at(drill.at_ns, self._note, drill)

    # -- the drives' side, in simulated time ------------------------------------------------------------
    def _note(self, drill: Drill) -> None:
        self.played.append({"time_s": round(self.m.sc.sim.now / 1e9, 6), "text": drill.description()})

    def _emcy(self, arg: tuple[Drill, int, bytes]) -> None:
        drill, src, payload = arg
        self._note(drill)
        if self.m.sc.alive(str(drill.node)):
            self.m.can.submit(src, payload)

    def _boot(self, arg: tuple[int, int]) -> None:
        """The boot-up message, sent past the node's silence (its TPDOs stay off: PRE-OPERATIONAL), then its
        heartbeat, PRE-OPERATIONAL (0x7F), at its configured period: the 0x1017 default of the device file netcfg
        writes, which is what the node boots with (as the simulated drives of `run` do)."""
        src, period = arg
        self.m.can.submit(src, bytes([NMT_BOOT_UP]))
        if period > 0:
            self.m.sc.sim.at(self.m.sc.sim.now + period, self._beat, arg)

    def _beat(self, arg: tuple[int, int]) -> None:
        src, period = arg
        self.m.can.submit(src, bytes([NMT_STATE_PRE_OPERATIONAL]))
        self.m.sc.sim.at(self.m.sc.sim.now + period, self._beat, arg)

    def _heard(self, end: int, src: int, _release: int, data: bytes | None) -> None:
        """An NMT command reaching the drives: enter pre-operational or stop ends their PDOs."""
        if self.m.can.sources[src].can_id != NMT_ID or not data or len(data) < 2:
            return
        if data[0] not in (NMT_PRE_OPERATIONAL, NMT_STOP):
            return
        for drive in self.m.drives:
            if data[1] in (0, self.m.sc.cfg.node(drive).node_id):
                self.stopped[drive] = min(self.stopped.get(drive, NEVER), end)

    def quiet_from(self, drive: str) -> int:
        """When the drive stopped sending PDOs (NEVER: it did not)."""
        return min(self.m.sc.crash_at.get(drive, NEVER), self.stopped.get(drive, NEVER))

    # -- the master's side: called from its cycle ---------------------------------------------------------
    def bind(self, cycle: MasterCycle, pybus: SimCanBus, clock: VirtualClock, supervisor: Supervisor) -> None:
        self._cycle, self._pybus, self._clock, self._supervisor = cycle, pybus, clock, supervisor
        pybus.off = sorted((d.at_ns, d.until_ns) for d in self.drills if d.kind == "bus-off")

    def after_cycle(self, record: CycleRecord) -> bool:
        """What operate does after a cycle, for the drills: SYNC gaps and bus-offs reported, a stall or a bus-off
        held, the supervisor's new events reacted to. -> whether the cycle goes on."""
        cycle, pybus, clock, supervisor = self._cycle, self._pybus, self._clock, self._supervisor
        assert cycle is not None and pybus is not None and clock is not None and supervisor is not None
        self._gaps(record, cycle.period_s)
        now = clock.now()
        while self._stalls and self._stalls[0].at_s <= now:
            stall = self._stalls.pop(0)
            self.played.append({"time_s": round(now, 6), "text": stall.description()})
            clock.sleep_until(stall.until_s)
        if pybus.state is can.BusState.ERROR:
            detected = clock.now()
            back = min((hi for lo, hi in pybus.off if lo <= round(detected * 1e9) < hi), default=round(detected * 1e9))
            supervisor.events.append(Event(detected, self.m.master, "bus-off", "hold", BUS_OFF_TEXT))
            clock.sleep_until(back / 1e9)
            supervisor.resume(clock.now())
            self._bus_back = (detected, clock.now())
        return self.ended_by is None

    def react(self, record: CycleRecord) -> bool:
        """After supervision's check: the node's on_loss, on_emcy, on_reboot. -> whether the cycle goes on."""
        supervisor, cycle = self._supervisor, self._cycle
        assert supervisor is not None and cycle is not None
        while self._seen < len(supervisor.events):
            event = supervisor.events[self._seen]
            self._seen += 1
            if event.node not in self.m.drives:
                continue  # the master's own (missed SYNCs, bus-off): reported
            if event.kind == "boot-up":
                cycle.muted.add(event.node)  # its RxPDOs would land in an unconfigured dictionary
                supervisor.quiet.add(event.node)
                if event.action == "recover":
                    self.findings.append(
                        f"{event.node} rebooted at {event.time:.3f} s and its on_reboot is recover: setting it up "
                        "again is SDO traffic to an object dictionary the simulator does not have, so it stays "
                        "PRE-OPERATIONAL here; netcfg run --simulated-drives --reset drills the recovery"
                    )
            elif event.kind in ("lost", "emcy") and event.action == "stop_node":
                cycle.muted.add(event.node)
                supervisor.quiet.add(event.node)
                node_id = self.m.sc.cfg.node(event.node).node_id or 0
                self._nmt(node_id)
            if event.action == "stop_all" and self.ended_by is None:
                self.ended_by = f"stop_all: {event.text}"
        if self.ended_by is not None:
            ids = sorted(self.m.sc.cfg.node(drive).node_id or 0 for drive in self.m.drives)
            for node_id in ids:  # the safe stop's NMT part, node by node as operate sends it
                self._nmt(node_id)
        return self.ended_by is None

    def _nmt(self, node_id: int) -> None:
        assert self._pybus is not None
        frame = pycan_frames.message(NMT_ID, False, bytes([NMT_PRE_OPERATIONAL, node_id]), fd=self._fd, brs=self._fd)
        with contextlib.suppress(can.CanError):  # bus-off: the node keeps its PDOs until its own timeouts
            self._pybus.send(frame)

    def _gaps(self, record: CycleRecord, period_s: float) -> None:
        assert self._supervisor is not None
        if self._bus_back is not None:
            (detected, back), self._bus_back = self._bus_back, None
            found, text = bus_back(detected, back, record.sync_sent, 0.0)
            self.bus_offs.append(found)
            self._supervisor.events.append(Event(record.sync_sent, self.m.master, "bus-on", "continue", text))
        if not record.sync_ok:
            return
        last, self._last_sync = self._last_sync, record.sync_sent
        if last is None:
            return
        gap = sync_gap(last, record.sync_sent, period_s, 0.0)
        if gap is not None:
            self.sync_gaps.append(gap[0])
            self._supervisor.events.append(Event(record.sync_sent, self.m.master, "missed-sync", "continue", gap[1]))

    def report(self, out: dict[str, object]) -> None:
        if not self.drills:
            return
        out["drills"] = sorted(self.played, key=lambda d: d["time_s"])
        out["sync_gaps"] = self.sync_gaps
        out["bus_offs"] = self.bus_offs
        out["ended_by"] = self.ended_by
