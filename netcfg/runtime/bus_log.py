"""BusLog: the python-can bus a live master runs on, every frame it sends or receives written to a log file, and a
controller bus-off played for drills (netcfg.runtime.operate). Several buses may write one LogFile, each frame under
its bus's name (a run of several actuator buses: netcfg verify reads the log back per bus)."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import can

BUS_POLL_S = 0.001  # how often a master whose controller is bus-off looks whether the bus is back


class LogFile:
    """One log file (can.Logger) that one or several BusLogs write, in time order."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._logger: Any = can.Logger(str(path))
        self._lock = threading.Lock()
        self._last = 0.0  # the log's latest timestamp

    def write(self, msg: can.Message) -> None:
        with self._lock:
            if self._logger is None:
                return
            # in time order, as a log must be (netcfg verify reads it): a reply stamped by its sender can come in
            # before our own frame's stamp is logged; it is logged no earlier than the frame before it
            if msg.timestamp < self._last:
                msg.timestamp = self._last
            self._last = msg.timestamp
            self._logger.on_message_received(msg)

    def close(self) -> None:
        with self._lock:
            if self._logger is not None:
                self._logger.stop()
                self._logger = None


class BusLog(can.BusABC):
    """A python-can bus that writes every frame sent or received through it to a log file (can.Logger).

    It also plays a bus-off of the controller for drills (`bus_off(duration_s)`), which python-can's virtual bus
    cannot: meanwhile `state` is can.BusState.ERROR, send() raises can.CanOperationError and nothing is received
    (what came is dropped, as a controller off the bus never sees it). Otherwise `state` is the interface's."""

    def __init__(self, bus: can.BusABC, path: str | Path | None, *, log: LogFile | None = None,
                 channel: str | None = None) -> None:
        """`path`: the log file this bus writes alone; `log`: one it shares with other buses (closed by whoever made
        it); `channel`: the name the log gives every frame of this bus, sent or received (default: the interface's
        channel for the frames sent, the interface's own for those received)."""
        self.inner = bus
        self._own_log = log is None and path is not None
        self._file: LogFile | None = log if log is not None else LogFile(path) if path is not None else None
        self.path = self._file.path if self._file is not None else None
        self.channel_info = f"logged {bus.channel_info}"
        self._channel = channel
        # the channel name the log gives the frames this side sends (received ones carry the interface's)
        names = (getattr(bus, attr, None) for attr in ("channel_id", "channel"))  # virtual's, socketcan's, ...
        self.channel_name = channel or next((n for n in names if isinstance(n, (str, int))), None)
        self._filters = None
        self._is_shutdown = False
        self._off_until: float | None = None  # time.monotonic() the simulated bus-off ends

    def bus_off(self, duration_s: float) -> None:
        """The controller goes bus-off now and is back on the bus after duration_s (a drill)."""
        self._off_until = time.monotonic() + duration_s

    def _off(self) -> bool:
        if self._off_until is not None and time.monotonic() >= self._off_until:
            self._off_until = None
        return self._off_until is not None

    @property
    def state(self) -> can.BusState:
        if self._off():
            return can.BusState.ERROR
        try:
            return self.inner.state
        except NotImplementedError:
            return can.BusState.ACTIVE

    @state.setter
    def state(self, new_state: can.BusState) -> None:
        self.inner.state = new_state

    def _log(self, msg: can.Message) -> None:
        if self._file is not None:
            if self._channel is not None:
                msg.channel = self._channel
            self._file.write(msg)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self._off():
            raise can.CanOperationError("the CAN controller is bus-off")
        queued = time.time()
        self.inner.send(msg, timeout)
        sent = can.Message(
            timestamp=queued,
            arbitration_id=msg.arbitration_id,
            is_extended_id=msg.is_extended_id,
            is_remote_frame=msg.is_remote_frame,
            dlc=msg.dlc,
            data=msg.data,
            is_rx=False,
            channel=msg.channel or self.channel_name,
        )
        self._log(sent)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        if self._off():
            end = None if timeout is None else time.monotonic() + timeout
            while self._off():  # frames on the bus meanwhile never reach a controller that is off it
                left = None if end is None else end - time.monotonic()
                if left is not None and left <= 0:
                    return None
                self.inner.recv(min(left, BUS_POLL_S) if left is not None else BUS_POLL_S)
            timeout = None if end is None else max(0.0, end - time.monotonic())
        msg = self.inner.recv(timeout)
        if msg is not None:
            self._log(msg)
        return msg

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.recv(timeout), True  # pragma: no cover - recv is overridden

    def shutdown(self) -> None:
        """Flush and close the log, then the bus."""
        if self._is_shutdown:
            return
        self._is_shutdown = True
        if self._file is not None and self._own_log:
            self._file.close()
        self.inner.shutdown()
