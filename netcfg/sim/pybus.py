"""Run a real program against the simulator: a python-can bus and a clock in virtual time.

    sc = Scenario(cfg, SimOptions(canopen="external"))   # the drives, without the simulator's own master
    sc.start()
    bus, clock = SimCanBus(sc, "can0", node="master"), VirtualClock(sc)
    ... the live master's code, unchanged, with bus and clock ...

Nothing runs in the background: the simulation advances only while the program waits, in `recv()` or in
`clock.sleep_until()`, so a program that takes no time in virtual time finishes a 8 s cycle in milliseconds.
Several programs at once (one live master per CANopen bus) each run in a thread of their own, hosted by a
`Program`: exactly one thread runs at any moment, and a program's wait hands the turn to the simulation until the
instant it waits for or a frame it can take, so the run stays deterministic.
Frames the program sends are matched to the configuration's messages by identifier (unknown identifiers become
sources of their own) and arbitrate like any other frame.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable
from typing import Any

import can

from netcfg.links import pycan_frames
from netcfg.sim.engine import NEVER
from netcfg.sim.run import SimRun
from netcfg.timing.frames import CANFD_PADDING, canfd_padded_size


class Program:
    """One program sharing the simulation with others, in a thread of its own that runs only on its turn."""

    def __init__(self, sc: SimRun, main: Callable[[Program], None]) -> None:
        self.sc = sc
        self.main = main
        self._turn = threading.Semaphore(0)  # the program may run
        self._back = threading.Semaphore(0)  # the simulation may run
        self._token = 0  # a wake-up for an earlier wait is stale
        self._ready: Callable[[], object] | None = None
        self.done = False
        self.error: BaseException | None = None

    def start(self, at_ns: int) -> None:
        threading.Thread(target=self._run, name="netcfg-sim-program", daemon=True).start()
        self.sc.sim.at(at_ns, self._resume, self._token)

    def _run(self) -> None:
        self._turn.acquire()
        try:
            self.main(self)
        except BaseException as exc:  # handed to the simulation's thread, which raises it
            self.error = exc
        finally:
            self.done = True
            self._back.release()

    def _resume(self, token: int) -> None:
        """A simulation event: the program's turn, until it waits again or ends."""
        if token != self._token or self.done:
            return
        self._token += 1
        self._turn.release()
        self._back.acquire()

    def wait(self, until_ns: int, ready: Callable[[], object] | None = None) -> None:
        """In the program's thread: let the simulation run until `until_ns`, or until ready() turns true."""
        sim = self.sc.sim
        if until_ns <= sim.now or (ready is not None and ready()):
            return
        self._ready = ready
        sim.at(until_ns, self._resume, self._token)
        self._back.release()
        self._turn.acquire()
        self._ready = None

    def poke(self) -> None:
        """In the simulation's thread: something the program may wait for happened; wake it if it was that."""
        if self._ready is not None and self._ready():
            self.sc.sim.at(self.sc.sim.now, self._resume, self._token)


def run_programs(sc: SimRun, programs: list[tuple[int, Callable[[Program], None]]], until_ns: int) -> None:
    """Run the simulation to `until_ns` with these programs (start instant, main) in it, then on until every
    program has ended; a program's exception is raised here."""
    hosts = [Program(sc, main) for _, main in programs]
    for host, (at, _) in zip(hosts, programs):
        host.start(at)
    sc.sim.run_until(until_ns)
    if not all(h.done for h in hosts):
        sc.sim.run_until(1 << 62, stop=lambda: all(h.done for h in hosts))
    for host in hosts:
        if host.error is not None:
            raise host.error


class VirtualClock:
    """The netcfg.runtime.clock.Clock protocol, in simulated seconds (`host`: for a program sharing the run)."""

    def __init__(self, sc: SimRun, host: Program | None = None) -> None:
        self.sc = sc
        self.host = host
        self._sim = sc.sim  # read at every now(): a master asks 30 times a cycle

    def now(self) -> float:
        return self._sim.now / 1e9

    def sleep_until(self, t: float) -> None:
        target = round(t * 1e9)
        if target > self.sc.sim.now:
            if self.host is not None:
                self.host.wait(target)
            else:
                self.sc.sim.run_until(target)


class SimCanBus(can.BusABC):
    """A python-can bus on one of the simulator's CAN buses, as node `node`: receives every frame others send."""

    def __init__(self, sc: SimRun, channel: str, node: str, host: Program | None = None, **kwargs: Any) -> None:
        if channel not in sc.can:
            raise ValueError(f"no CAN bus named '{channel}' in the simulation; there are: {', '.join(sc.can)}")
        self.sc = sc
        self.node = node
        self.host = host
        self.sim_bus = sc.can[channel]
        self.channel_info = f"netcfg simulator bus {channel}"
        self._rx: deque[can.Message] = deque()
        self._ready = self._rx.__len__  # recv()'s stop(), checked after every event: a bound built-in, made once
        self._sim = sc.sim
        self._by_id = {(s.can_id, s.extended): s.index for s in self.sim_bus.sources}
        self._own: set[int] = set()  # its sources: it does not hear them
        self._crash = sc.crash_at.get(node, NEVER)  # when its node crashes (sc.alive, asked at every send)
        self._channel = self.sim_bus.name
        self._frames: dict[int, tuple[int, bool, bytes, Callable[[int, bytes | None], can.Message] | None]] = {}
        self.off: list[tuple[int, int]] = []  # [from, until) spans its controller is bus-off (a drill): no send, no rx
        self.sim_bus.monitor(self._heard)
        super().__init__(channel=channel, **kwargs)

    def is_off(self, t: int) -> bool:
        """Its controller is bus-off at t (python-can's BusState.ERROR)."""
        return any(lo <= t < hi for lo, hi in self.off)

    @property
    def state(self) -> can.BusState:
        return can.BusState.ERROR if self.off and self.is_off(self._sim.now) else can.BusState.ACTIVE

    @state.setter
    def state(self, new_state: can.BusState) -> None:
        raise NotImplementedError("the simulator's bus state follows its bus-off drills")

    def _heard(self, end: int, src: int, _release: int, data: bytes | None) -> None:
        # never one of its own frames (the bus does not deliver those): like python-can's buses, no echo
        if self.off and self.is_off(end):
            return  # a controller that is bus-off hears nothing
        frame = self._frames.get(src)
        if frame is None:
            frame = self._frames[src] = self._frame_of(src)
        can_id, extended, zeros, fd = frame
        if fd is not None:
            self._rx.append(fd(end, data))
        else:
            # python-can's Message(timestamp, arbitration_id, is_extended_id, is_remote_frame, is_error_frame,
            # channel, dlc, data), positionally: half the time of keywords, once per frame heard
            payload = zeros if data is None else data
            self._rx.append(can.Message(end / 1e9, can_id, extended, False, False, self._channel, None, payload))
        if self.host is not None:
            self.host.poke()

    def _frame_of(self, src: int) -> tuple[int, bool, bytes, Callable[[int, bytes | None], can.Message] | None]:
        """What every frame of the source looks like here: identifier, extended, the payload of a frame without
        one (its resting payload, as the trace writes it: each field at rest, a started node's heartbeat
        OPERATIONAL), and for CAN FD the frame's maker (a receiver sees an FD frame's padded length)."""
        s = self.sim_bus.sources[src]
        rest = s.rest if len(s.rest) == s.size else bytes(s.size)
        if not s.fd:
            return s.can_id, s.extended, rest, None

        def fd(end: int, data: bytes | None) -> can.Message:
            payload = data if data is not None else rest
            payload += bytes([CANFD_PADDING]) * (canfd_padded_size(len(payload)) - len(payload))
            return pycan_frames.message(
                s.can_id, s.extended, payload, fd=True, brs=s.brs, timestamp=end / 1e9, channel=self._channel
            )

        return s.can_id, s.extended, rest, fd

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        key = (msg.arbitration_id, msg.is_extended_id)
        src = self._by_id.get(key)
        if src is None:
            name = f"{self.node}_0x{msg.arbitration_id:x}"
            fd, brs = pycan_frames.frame_format(msg)
            src = self.sim_bus.add_source(
                name, msg.arbitration_id, msg.is_extended_id, msg.dlc, self.node, fd=fd, brs=brs
            )
            self._by_id[key] = src
        if src not in self._own:
            self._own.add(src)
            self.sim_bus.deafen(self._heard, src)
        if self.sc.sim.now >= self._crash:
            self.sim_bus.drop(src)  # a crashed node sends nothing
            return
        if self.off and self.is_off(self._sim.now):
            raise can.CanOperationError("the CAN controller is bus-off")
        self.sim_bus.submit(src, bytes(msg.data))

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """The next frame, waiting at most `timeout` simulated seconds (None: until the simulation runs dry)."""
        rx = self._rx
        if not rx:
            sim = self._sim
            # at least 1 ns: a timeout left over from float arithmetic must still let time move on
            until = (1 << 62) if timeout is None else sim.now + (max(1, math.ceil(timeout * 1e9)) if timeout > 0 else 0)
            if self.host is not None:
                self.host.wait(until, ready=self._ready)
            else:
                sim.run_until(until, stop=self._ready)
        return rx.popleft() if rx else None

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        msg = self.recv(timeout)
        return msg, False

    def shutdown(self) -> None:
        self.sim_bus.unmonitor(self._heard)
        super().shutdown()
