"""Whose clock stamped a log: the wire's, or a host's.

On a CAN bus two frames cannot end closer together than the second one's transmission time: its bits without a
single stuff bit (netcfg.timing.frames.frame_bits, stuffing "nominal"), at the bus's bit rate. A log whose
consecutive frames on one bus come closer than that (by more than its 1 us resolution) was not stamped by the
wire; when that holds for many of them (at least 10, and 1 in 100), its timestamps are a host's (python-can's
virtual bus, where the drives are threads of the master's process and a frame takes no time; software
timestamps taken when a driver or a program got round to it). On such a log a
response measured from the SYNC holds the host's latency as well as the bus's, so a response beyond the analysed
bound is not evidence against the bus: verify then reports it as the host's lateness (`host_late`, a warning with
its measured excess) instead of a `late` violation. A gap or a shortfall of frames in the SYNC cycle (the SYNC,
the master's RxPDOs, the synchronous TPDOs that answer the SYNC) is still a violation, the master's host having
sent late what the analysis assumed on time (its master_jitter), but named so: `host_late`, not `gap` or `rate`. So
is one on an actuator bus: a command the master's host sent late, or the reply that answers it.
Everything else (a drive's own heartbeat, load, sizes) is judged as before.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from netcfg.runtime import Bus, RuntimeConfig
from netcfg.runtime.actuator_plan import reply_commands
from netcfg.timing.frames import frame_bits
from netcfg.verify.frames import ERROR, EXTENDED, FD, REMOTE

if TYPE_CHECKING:
    from netcfg.verify.message_checks import MessageState

RESOLUTION_US = 1  # a log's timestamps are in microseconds (verify's Batch)
HOST_MIN_FRAMES = 10  # at least this many frames, and this share of all, too close: a host stamped the log
HOST_SHARE = 0.01
HostFinding = Callable[[str, "MessageState | None", str], tuple[str, str, bool]]  # -> (kind, detail, a warning)


def host_finding(cfg: RuntimeConfig) -> HostFinding:
    """How the checker names a finding on a log a host stamped (module docstring)."""
    masters = {b.canopen.sync_producer for b in cfg.buses if b.canopen is not None}
    commanders = {cfg.message(command).producer for command in reply_commands(cfg).values()}

    def name(kind: str, st: MessageState | None, detail: str) -> tuple[str, str, bool]:
        if kind == "late":
            return "host_late", f"{detail} (a host's timestamps: its latency is in the response)", True
        if kind in ("gap", "rate") and st is not None and (st.msg.producer in masters or st.response_ref == "sync"):
            return "host_late", f"{detail} (the SYNC cycle: the master's host sent late)", False
        if kind in ("gap", "rate") and st is not None and (
            st.msg.producer in commanders or st.response_ref == "command"
        ):
            return "host_late", f"{detail} (an actuator's command: the master's host sent it late)", False
        return kind, detail, False

    return name


class HostClock:
    """Fed each batch of the log with the bus of each frame; `host` once any two frames came too close."""

    def __init__(self, buses: list[Bus]) -> None:
        self.bitrates = [b.bitrate for b in buses]
        self.last: dict[int, int] = {}  # bus -> its last frame's time
        self.pairs = 0  # consecutive classical frames on one bus
        self.too_close = 0
        self.closest: tuple[int, int] | None = None  # (interval, the frame's shortest transmission), us, the worst
        # per bus: the shortest transmission (us) of a classical frame by (extended, length 0-8): index 9 * ext + len
        self.needed = [
            np.array(
                [frame_bits(n, x, stuffing="nominal").ns(rate) // 1000 for x in (False, True) for n in range(9)],
                np.int64,
            )
            for rate in self.bitrates
        ]

    @property
    def host(self) -> bool:
        """Many frames too close: a host's clock throughout (python-can's virtual bus: about 3 in 4 of them), not a
        frame or two out of place (an edited or merged log), which leaves every other frame judged as the wire's."""
        return self.too_close >= max(HOST_MIN_FRAMES, HOST_SHARE * self.pairs)

    def take(self, t: NDArray[np.int64], bus: NDArray[np.int64], flags: NDArray[np.uint8], length: Any) -> None:
        # classical data frames only: a remote frame has no data field, an FD frame's data phase its own rate
        plain = (flags & (ERROR | REMOTE | FD)) == 0
        for b in range(len(self.bitrates)):
            rows = np.flatnonzero(plain & (bus == b))
            if not len(rows):
                continue
            tb = t[rows]
            prev = np.concatenate([[self.last[b]], tb]) if b in self.last else tb
            self.last[b] = int(tb[-1])
            iv = np.diff(prev)
            if not len(iv):
                continue
            later = rows[-len(iv) :]
            ext = ((flags[later] & EXTENDED) != 0).astype(np.int64)
            needed = self.needed[b][9 * ext + np.minimum(np.asarray(length[later], np.int64), 8)]
            close = iv < needed - RESOLUTION_US
            self.pairs += len(iv)
            if close.any():
                self.too_close += int(close.sum())
                k = int(np.argmin(iv - needed))
                worst = (int(iv[k]), int(needed[k]))
                if self.closest is None or worst[0] - worst[1] < self.closest[0] - self.closest[1]:
                    self.closest = worst

    def report(self) -> dict[str, Any]:
        out: dict[str, Any] = {"clock": "host" if self.host else "wire", "pairs": self.pairs}
        out["too_close"] = self.too_close
        if self.closest is not None:
            out["closest_us"], out["needed_us"] = self.closest
        return out
