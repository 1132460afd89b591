"""The state of one operation of a CANopen network (netcfg.runtime.operate) and what every phase of it uses: SDO
access to the drives outside the cycle, NMT commands, and the routing of the frames the cycle does not take (to a
rebooted drive's set-up again, else to supervision)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import can
import canopen

from netcfg.runtime import RuntimeConfig
from netcfg.runtime.canopen_master import MasterCycle, canopen_bus, canopen_slaves
from netcfg.runtime.cia402 import CONTROLWORD, STATUSWORD, PdoEnabler
from netcfg.runtime.clock import Clock
from netcfg.runtime.operate_outcome import NodeOutcome, Outcome, Plan
from netcfg.runtime.supervision import Supervisor

CAN_ERR_BUSOFF, CAN_ERR_RESTARTED = 0x40, 0x100  # SocketCAN error frame classes (linux/can/error.h)


@dataclass
class Recovery:
    """A drive that rebooted being set up again beside the cycle, on a worker thread; the cycle hands its SDO answers
    to `network` (see Operation._on_frame). `done` is the clock time it ended, `error` why it failed."""

    node: str
    booted: float  # clock time of the boot-up message
    network: canopen.Network
    thread: threading.Thread | None = None
    done: float | None = None
    error: str | None = None
    path: list[str] = field(default_factory=list)


class Operation:
    """One run: its configuration, bus, plan and outcome, and the state the phases share."""

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
        self.recovering: dict[str, Recovery] = {}
        self.sdo_routes: dict[int, Recovery] = {}  # SDO response COB-ID -> the recovery awaiting it
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

    # --- the frames the cycle does not take --------------------------------------------------------------------

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


def sdo_io(remote: canopen.RemoteNode) -> tuple[Callable[[], int], Callable[[int], None]]:
    """Read the statusword, write the controlword of one drive over SDO."""

    def read() -> int:
        return int.from_bytes(remote.sdo.upload(STATUSWORD, 0)[:2], "little")

    def write(controlword: int) -> None:
        remote.sdo.download(CONTROLWORD, 0, controlword.to_bytes(2, "little"))

    return read, write
