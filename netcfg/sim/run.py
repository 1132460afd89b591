"""What a protocol driver (the FTT-CAN master, the CANopen master, an Ethernet network) and a fault need from a
simulation run, and no more: the engine and its random numbers, the configuration and options, node clocks, the
CAN buses with the source of every message, crashes, and the task and flow hooks. `Scenario` is the one run;
the drivers are written against this interface, so none of them imports the scenario.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from netcfg.runtime import RuntimeConfig, Task
from netcfg.sim.can_bus import CanBus
from netcfg.sim.engine import NodeClock, Simulator
from netcfg.sim.flows import FlowTracker

if TYPE_CHECKING:
    from netcfg.sim.ethernet import EthernetNetwork
    from netcfg.sim.scenario import SimOptions


class SimRun(Protocol):
    cfg: RuntimeConfig
    opts: SimOptions
    sim: Simulator
    rng: np.random.Generator
    clock: dict[str, NodeClock]  # node -> its clock
    can: dict[str, CanBus]  # bus -> its CAN model
    msg_source: dict[str, tuple[CanBus, int]]  # CAN message -> (its bus, its source there)
    eth_owner: dict[str, EthernetNetwork]  # Ethernet message -> its network
    protocols: dict[str, object]  # bus -> its protocol driver
    crash_at: dict[str, int]  # node -> when it crashes
    sends: dict[str, list[str]]  # task -> messages it sends as it finishes

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
