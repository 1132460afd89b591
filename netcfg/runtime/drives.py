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

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import can

from netcfg.runtime import RuntimeConfig
from netcfg.runtime.bench import Bench
from netcfg.runtime.canopen_master import canopen_bus, canopen_slaves
from netcfg.runtime.clock import Clock, SystemClock
from netcfg.runtime.drive_responses import ResponseScheduler
from netcfg.runtime.simulated_drive import DriveModel, SimulatedDrive, follow_velocity

__all__ = ["DriveBench", "DriveModel", "ResponseScheduler", "SimulatedDrive", "follow_velocity"]


class DriveBench(Bench[SimulatedDrive]):
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
        super().__init__(channel, interface, {})
        self.drives = self.devices
        self.separate_connections = separate_connections
        self._clock: Clock = drive_options.get("clock") or SystemClock()
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
        self._serve(bus)
        return self

    def stop(self) -> None:
        self._stop_serving()
        for drive in self.drives.values():
            drive.detach(join=False)
        for drive in self.drives.values():
            drive.join_threads()
        for bus in self._buses:
            bus.shutdown()
        self._buses.clear()

