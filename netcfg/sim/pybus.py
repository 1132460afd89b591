"""Run a real program against the simulator: a python-can bus and a clock in virtual time.

    sc = Scenario(cfg, SimOptions(canopen="external"))   # the drives, without the simulator's own master
    sc.start()
    bus, clock = SimCanBus(sc, "can0", node="master"), VirtualClock(sc)
    ... the live master's code, unchanged, with bus and clock ...

Nothing runs in the background: the simulation advances only while the program waits, in `recv()` or in
`clock.sleep_until()`, so a program that takes no time in virtual time finishes a 8 s cycle in milliseconds.
Frames the program sends are matched to the configuration's messages by identifier (unknown identifiers become
sources of their own) and arbitrate like any other frame.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import can

from netcfg.sim.scenario import Scenario


class VirtualClock:
    """The netcfg.runtime.clock.Clock protocol, in simulated seconds."""

    def __init__(self, sc: Scenario) -> None:
        self.sc = sc

    def now(self) -> float:
        return self.sc.sim.now / 1e9

    def sleep_until(self, t: float) -> None:
        target = round(t * 1e9)
        if target > self.sc.sim.now:
            self.sc.sim.run_until(target)


class SimCanBus(can.BusABC):
    """A python-can bus on one of the simulator's CAN buses, as node `node`: receives every frame others send."""

    def __init__(self, sc: Scenario, channel: str, node: str, **kwargs: Any) -> None:
        if channel not in sc.can:
            raise ValueError(f"no CAN bus named '{channel}' in the simulation; there are: {', '.join(sc.can)}")
        self.sc = sc
        self.node = node
        self.sim_bus = sc.can[channel]
        self.channel_info = f"netcfg simulator bus {channel}"
        self._rx: deque[can.Message] = deque()
        self._by_id = {(s.can_id, s.extended): s.index for s in self.sim_bus.sources}
        self._own: set[int] = set()
        self.sim_bus.monitors.append(self._heard)
        super().__init__(channel=channel, **kwargs)

    def _heard(self, end: int, src: int, _release: int, data: bytes | None) -> None:
        if src in self._own:
            return  # like python-can's buses: no echo of one's own frames
        s = self.sim_bus.sources[src]
        payload = data if data is not None else bytes(s.size)
        self._rx.append(
            can.Message(
                timestamp=end / 1e9, arbitration_id=s.can_id, is_extended_id=s.extended, data=payload,
                channel=self.sim_bus.name,
            )
        )

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        key = (msg.arbitration_id, msg.is_extended_id)
        src = self._by_id.get(key)
        if src is None:
            name = f"{self.node}_0x{msg.arbitration_id:x}"
            src = self.sim_bus.add_source(name, msg.arbitration_id, msg.is_extended_id, msg.dlc, self.node)
            self._by_id[key] = src
        self._own.add(src)
        if not self.sc.alive(self.node):
            self.sim_bus.drop(src)  # a crashed node sends nothing
            return
        self.sim_bus.submit(src, bytes(msg.data))

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """The next frame, waiting at most `timeout` simulated seconds (None: until the simulation runs dry)."""
        if not self._rx:
            sim = self.sc.sim
            # at least 1 ns: a timeout left over from float arithmetic must still let time move on
            until = (1 << 62) if timeout is None else sim.now + (max(1, math.ceil(timeout * 1e9)) if timeout > 0 else 0)
            sim.run_until(until, stop=lambda: bool(self._rx))
        return self._rx.popleft() if self._rx else None

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        msg = self.recv(timeout)
        return msg, False

    def shutdown(self) -> None:
        if self._heard in self.sim_bus.monitors:
            self.sim_bus.monitors.remove(self._heard)
        super().shutdown()
