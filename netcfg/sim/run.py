"""What a protocol driver (the FTT-CAN master, the CANopen master, an Ethernet network) and a fault need from a
simulation run, and no more: the engine and its random numbers, the configuration and options, node clocks, the
CAN buses with the source of every message, crashes, and the task and flow hooks. `Scenario` is the one run;
the drivers are written against this interface, so none of them imports the scenario, and this module imports
none of them: the scenario builds the drivers and stands above them (RunOptions says which of its options they
read, ScriptedFault and MessageOwner what they ask of a fault and of an Ethernet network).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from netcfg.runtime import RuntimeConfig, Task
from netcfg.sim.can_bus import CanBus
from netcfg.sim.engine import NodeClock, Simulator
from netcfg.sim.flows import FlowTracker


@dataclass(frozen=True)
class MasterTiming:
    """The SDO-polling master's processing times in ns (the earlier approach seed 000 compares with; the PDO master is
    the live one, timed by the spec). Per confirmed SDO transfer, from a joint read of three transfers (Table 4:
    2.9486 ms), and per command write to the joints (Table 3: 32.1848 ms)."""

    sdo_read_ns: int = 2_948_600 // 3
    sdo_write_ns: int = 32_184_800


class ScriptedFault(Protocol):
    """A fault of the run's options as a driver sees it (netcfg.sim.faults.Fault)."""

    @property
    def kind(self) -> str: ...

    @property
    def target(self) -> str | None: ...


class RunOptions(Protocol):
    """The options the drivers, faults and whole-run computations read (netcfg.sim.scenario.SimOptions)."""

    @property
    def duration_ns(self) -> int: ...

    @property
    def stuffing(self) -> str: ...

    @property
    def canopen(self) -> str: ...

    @property
    def faults(self) -> Sequence[ScriptedFault]: ...

    @property
    def master(self) -> MasterTiming: ...

    @property
    def drive_delay_ns(self) -> int | None: ...

    @property
    def eth_queue_frames(self) -> int | None: ...

    @property
    def eth_processing_ns(self) -> Mapping[str, tuple[int, int]] | None: ...


class MessageOwner(Protocol):
    """An Ethernet network as a fault sees the messages it carries (netcfg.sim.ethernet.EthernetNetwork)."""

    def lose_at(self, name: str, at_ns: int) -> None: ...


class SimRun(Protocol):
    cfg: RuntimeConfig
    sim: Simulator
    rng: np.random.Generator
    clock: dict[str, NodeClock]  # node -> its clock
    can: dict[str, CanBus]  # bus -> its CAN model
    msg_source: dict[str, tuple[CanBus, int]]  # CAN message -> (its bus, its source there)
    protocols: dict[str, object]  # bus -> its protocol driver
    crash_at: dict[str, int]  # node -> when it crashes
    sends: dict[str, list[str]]  # task -> messages it sends as it finishes

    @property
    def opts(self) -> RunOptions: ...

    @property
    def eth_owner(self) -> Mapping[str, MessageOwner]:
        """Ethernet message -> its network."""
        ...

    @property
    def synchronised(self) -> bool:
        """The buses run their protocol (mode "auto"), not as free-running CAN ("unsync")."""
        ...

    def alive(self, node: str) -> bool: ...

    def random(self, source: str) -> np.random.Generator:
        """The generator of one random source, seeded from the run's seed and the source's name (Simulator.random)."""
        ...

    def submit(self, message: str, data: bytes | None = None) -> None:
        """A reactive sender queues a frame now."""

    def listen(self, message: str, fn: Callable[[int, int, int, bytes | None], None]) -> None: ...

    def run_task(self, task: Task, start: int | None = None) -> None:
        """Activate a task now (or at `start`)."""

    def exec_ns(self, task: Task) -> int:
        """An execution time of the task, drawn between its BCET and WCET from the task's own generator."""
        ...

    def task_ran(self, task: Task, start: int, end: int) -> None:
        """A task that code outside the simulator ran (the live CANopen master's computation), for its flows."""

    def tasks_on_trigger(self, trigger: str) -> list[Task]: ...

    def tasks_on_sync(self, bus: str) -> list[Task]: ...

    def tasks_on_message(self, message: str) -> list[Task]:
        """The tasks the message's delivery activates (those a flow follows)."""
        ...

    def trackers_of(self, ref: str) -> list[FlowTracker]:
        """The flows that follow a message or a task (node.task)."""
        ...
