"""Simulated actuators: devices built from their profiles, for `netcfg run --simulated-drives` and for tests.

A SimulatedActuator is one actuator node of runtime.json on a python-can bus. It reads every frame with its
profile's codec and
- answers each host message the profile gives a reply with that reply, after a delay drawn uniformly from the range
  the analysis used: for a command the spec sends at a rate, its reply task's BCET..WCET (the profile's `delay_us`,
  or the spec's measured `reply_delay`); for any other (enable, safe stop), the profile's `delay_us`;
- sends its cyclic messages at the rates runtime.json gives them;
- reports in each frame: the fields a command set under the same name (an MIT reply's position, velocity and torque
  echo the command, clamped to the reply's range), 0 for the rest, and in its state fields the value names the
  profile's `enable:` / `safe_stop:` say the device reports after them;
- for drills: kill() (it stops answering and sending), fault() (from then on every frame it sends reports an error:
  each error field its first flag, or 1; each state field with error values its first one).

The delays run on one netcfg.runtime.drive_responses.ResponseScheduler thread, as the simulated CANopen drives'
answers do, so actuators sharing a bus each answer their own delay after their command. The draws come from a
seeded random.Random: a run is repeatable up to the host's thread timing.
"""

from __future__ import annotations

import random
from collections.abc import Mapping
from typing import Any

import can

from netcfg.links import pycan_frames
from netcfg.runtime.actuators import ActuatorCodec, MessageCodec
from netcfg.runtime.bench import Bench
from netcfg.runtime.config import Node, RuntimeConfig
from netcfg.runtime.drive_responses import ResponseScheduler

__all__ = ["ActuatorBench", "SimulatedActuator"]


class SimulatedActuator:
    def __init__(self, cfg: RuntimeConfig, node: Node, rng: random.Random) -> None:
        assert node.actuator is not None
        self.name = node.name
        self.codec: ActuatorCodec = node.actuator.codec()
        self.profile: Mapping[str, Any] = node.actuator.profile
        self.rng = rng
        self.killed = False
        self.faulted = False
        self.answered = 0
        # the most specific first: a fixed frame (Damiao's enable, FF .. FC) before the command on its identifier
        self._host = sorted((m for m in self.codec.messages.values() if m.sender == "host"),
                            key=lambda m: m.fixed is None)
        self._values: dict[str, float] = {}  # the latest commanded value of each field name
        self._states: dict[str, str] = {}  # state field -> the value name it reports
        # the delay range (s) each host message is answered within: the analysis' where the spec commands it
        self._delay_s: dict[str, tuple[float, float]] = {}
        for m in self._host:
            if m.reply_delay_us is not None:
                self._delay_s[m.name] = (m.reply_delay_us[0] / 1e6, m.reply_delay_us[1] / 1e6)
        for c in node.actuator.commands:
            task = next((t for t in node.tasks if t.on_message == c.message), None)
            if task is not None:
                self._delay_s[c.command] = (task.bcet_ns / 1e9, task.wcet_ns / 1e9)
        self.cyclic = [(pm, cfg.message(m).period_ns) for pm, m in node.actuator.cyclic]
        self._actions = [a for a in (self.profile.get("enable"), self.profile.get("safe_stop")) if a]
        self.bus: can.BusABC | None = None
        self.scheduler: ResponseScheduler | None = None

    # -- drills
    def kill(self) -> None:
        self.killed = True

    def fault(self) -> None:
        self.faulted = True

    # -- the bus
    def attach(self, bus: can.BusABC, scheduler: ResponseScheduler) -> None:
        self.bus, self.scheduler = bus, scheduler
        for pm, period_ns in self.cyclic:
            if period_ns:
                self._every(pm, period_ns / 1e9)

    def _every(self, message: str, period_s: float) -> None:
        assert self.scheduler is not None

        def tick() -> None:
            if self.killed or self.bus is None:
                return
            self._send(message)
            assert self.scheduler is not None
            self.scheduler.call_later(period_s, tick)

        self.scheduler.call_later(period_s, tick)

    def on_frame(self, msg: can.Message) -> None:
        if self.killed or msg.is_error_frame:
            return
        for m in self._host:
            if m.is_remote != bool(msg.is_remote_frame):
                continue
            if m.matches(msg.arbitration_id, msg.is_extended_id, b"" if m.is_remote else bytes(msg.data)):
                self._take(m, bytes(msg.data))
                return

    def _take(self, m: MessageCodec, data: bytes) -> None:
        if not m.is_remote:
            self._values.update(m.decode(0, data, si=False).values)
        for action in self._actions:  # enable and safe stop may be one message with other values (ODrive's)
            if action["message"] == m.name and all(self._values.get(k) == _raw_or_name(m, k, v)
                                                   for k, v in action["values"].items()):
                self._states.update(action["state"])
        if m.reply is None or m.name not in self._delay_s or self.scheduler is None:
            return
        lo, hi = self._delay_s[m.name]
        reply = m.reply
        self.scheduler.call_later(self.rng.uniform(lo, hi), lambda: self._send(reply))

    def _send(self, message: str) -> None:
        if self.killed or self.bus is None:
            return
        mc = self.codec.message(message)
        values: dict[str, float | int | str] = {}
        for name in mc.inputs:
            f = mc.by_name[name]
            if f.role == "state":
                state = self._states.get(name)
                values[name] = state if state is not None else 0
                if self.faulted and f.error_values:
                    values[name] = min(f.error_values)
            elif f.role == "error":
                values[name] = (1 << f.flags[0][0] if f.flags else 1) if self.faulted else 0
            else:
                v = float(self._values.get(name, 0.0))
                values[name] = v if f.lo is None or f.hi is None else min(max(v, f.lo), f.hi)
        frame = mc.encode(values, si=False, clamp=True)
        try:
            self.bus.send(pycan_frames.message(frame.arbitration_id, frame.is_extended, frame.data, fd=frame.fd,
                                               brs=frame.brs))
            self.answered += 1
        except can.CanError:
            pass  # a bus shut down under a late answer


def _raw_or_name(m: MessageCodec, field: str, value: Any) -> Any:
    """An action's value as the decoder (wire units) gives it back: a value name as its raw number."""
    if isinstance(value, str):
        f = m.by_name[field]
        return float(next(raw for raw, name in f.choices.items() if name == value))
    return float(value)


class ActuatorBench(Bench[SimulatedActuator]):
    """The actuator nodes of one bus of a runtime config as SimulatedActuators on python-can `channel`, sharing one
    connection and one answering thread (as netcfg.runtime.drives.DriveBench serves its drives).

        with ActuatorBench(cfg, "leg_can", channel="bench") as bench:
            ...  # a master on can.Bus(interface="virtual", channel="bench"); bench["knee"].kill()
    """

    def __init__(self, cfg: RuntimeConfig, bus_name: str, *, channel: str, interface: str = "virtual",
                 seed: int = 0) -> None:
        rng = random.Random(seed)
        super().__init__(channel, interface, {
            n.name: SimulatedActuator(cfg, n, random.Random(rng.getrandbits(64)))
            for n in cfg.nodes if n.actuator is not None and bus_name in n.buses
        })
        self.actuators = self.devices
        self._bus: can.BusABC | None = None

    def start(self) -> ActuatorBench:
        self.scheduler = ResponseScheduler(name=f"{self.channel}-actuators")
        self._bus = can.Bus(interface=self.interface, channel=self.channel)
        for a in self.actuators.values():
            a.attach(self._bus, self.scheduler)
        self._serve(self._bus)
        return self

    def stop(self) -> None:
        self._stop_serving()
        for a in self.actuators.values():
            a.bus = None
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None

