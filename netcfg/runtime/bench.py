"""What the simulated benches share (netcfg.runtime.drives.DriveBench, netcfg.runtime.simulated_actuator's
ActuatorBench): one python-can connection whose notifier thread hands every frame to each simulated device, one
ResponseScheduler for their delayed answers, and the order they stop in."""

from __future__ import annotations

from typing import Any, Generic, Protocol, TypeVar

import can

from netcfg.runtime.drive_responses import ResponseScheduler


class _Device(Protocol):
    def on_frame(self, msg: can.Message) -> Any: ...


D = TypeVar("D", bound=_Device)
B = TypeVar("B", bound="Bench[Any]")


class Bench(Generic[D]):
    def __init__(self, channel: str, interface: str, devices: dict[str, D]) -> None:
        self.channel, self.interface = channel, interface
        self.devices = devices  # by node name
        self._notifier: can.Notifier | None = None
        self.scheduler: ResponseScheduler | None = None

    def start(self: B) -> B:
        raise NotImplementedError

    def stop(self) -> None:
        raise NotImplementedError

    def _serve(self, bus: can.BusABC) -> None:
        """Hand every frame on `bus` to each device, from one thread."""
        self._notifier = can.Notifier(bus, [self._dispatch], timeout=0.05)

    def _dispatch(self, msg: can.Message) -> None:
        for device in self.devices.values():
            device.on_frame(msg)

    def _stop_serving(self) -> None:
        """Stop handing frames on, then the scheduler: before the buses close, so no delayed answer goes out on a
        closed bus."""
        if self._notifier is not None:
            self._notifier.stop(timeout=2.0)
            self._notifier = None
        if self.scheduler is not None:
            self.scheduler.close()
            self.scheduler = None

    def __enter__(self: B) -> B:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def __getitem__(self, name: str) -> D:
        return self.devices[name]
