"""What a simulated CAN bus (netcfg.sim.can_bus) carries: its sources, FIFO transmit queues and record of frames,
and, under exact stuffing, each frame's time from its payload's bits (ExactFrames: free-running frames carry seeded
random payloads, their lengths computed a message at a time).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from netcfg.runtime.codec import Field
from netcfg.runtime.columns import fill_in_range
from netcfg.sim.engine import Simulator
from netcfg.timing.frames import (
    bits_to_ns,
    can_frame_bits_exact_batch,
    can_frame_bits_of,
    canfd_frame_bits_exact,
    canfd_frame_bits_exact_batch,
)

Listener = Callable[[int, int, int, bytes | None], None]  # (end_ns, message index, release_ns, data)
Gate = Callable[[int, int], int]  # (t, duration) -> earliest start >= t at which the frame may go
Pending = tuple[int, int, int, int, bytes | None]  # key, release, seq (FIFO order), msg, data


@dataclass
class CanSource:
    """A message as the bus sees it."""

    index: int
    name: str
    can_id: int
    extended: bool
    size: int
    producer: str
    key: int = 0
    dur_ns: int = 0  # frame time in the bus's stuffing mode (exact mode: computed per frame)
    gated: bool = False  # FTT-CAN asynchronous traffic: only inside the asynchronous window
    fd: bool = False  # CAN FD: arbitration and tail at the bus's bit rate, the data phase (brs) at its data rate
    brs: bool = False
    fields: tuple[Field, ...] = ()  # the payload's layout (netcfg.runtime.codec)
    rest: bytes = b""  # what a frame nobody gives a payload carries: every field at its resting value


@dataclass
class TxFifo:
    """A node's FIFO transmit queue: only its head competes in arbitration; the rest wait behind it in order."""

    depth: int
    drop: bool  # a frame queued into a full FIFO is dropped (counted); otherwise its writer blocks until a slot
    behind: deque[Pending] = field(default_factory=deque)  # queued after the head, in order
    size: int = 0  # frames queued, the head included
    max_size: int = 0  # the largest backlog seen
    overflows: int = 0  # frames that found the queue full (dropped, or their writer blocked)


# Free-running sources, expanded a chunk at a time: (t0, t1) -> (release instants, source indices) of every
# release whose nominal instant falls in [t0, t1); release jitter may put an instant a little after t1.
Stream = Callable[[int, int], tuple[np.ndarray, np.ndarray]]


@dataclass
class Record:
    """Every transmitted frame: in bus order event by event; a whole run (netcfg.sim.ftt_whole_run) appends its
    frames message by message, each message's in order, so readers group by message or sort by end."""

    msg: list[int] = field(default_factory=list)
    response: list[int] = field(default_factory=list)  # end - release
    end: list[int] = field(default_factory=list)  # only when a trace is kept
    data: list[bytes | None] = field(default_factory=list)  # only when a trace is kept



class ExactFrames:
    """Frame times under exact stuffing, remembered per (source, payload) until the frame is sent."""

    def __init__(self, sim: Simulator, sources: list[CanSource], bitrate: int, data_bitrate: int) -> None:
        self.sim, self.sources = sim, sources
        self.bitrate, self.data_bitrate = bitrate, data_bitrate
        self._exact: dict[tuple[int, bytes], int] = {}  # (source, payload) -> frame time

    def random_payloads(self, srcs: np.ndarray, data: list[bytes | None], first_new: int) -> list[bytes | None]:
        """Exact stuffing needs each frame's bits: free-running frames carry seeded random payloads, whose frame
        lengths are computed here in one vectorised pass per message and remembered for the loop."""
        carried = {(s, d) for s, d in zip(srcs[:first_new].tolist(), data[:first_new]) if d is not None}
        self._exact = {k: v for k, v in self._exact.items() if k in carried}  # forget frames already sent
        new = srcs[first_new:]
        for s in np.unique(new).tolist():
            src = self.sources[s]
            rows = np.flatnonzero(new == s)
            payloads = self.payloads(src, len(rows))
            if src.fd:
                nominal, fast = canfd_frame_bits_exact_batch(src.can_id, src.extended, src.brs, payloads)
                durations = [
                    bits_to_ns(n, self.bitrate) + bits_to_ns(f, self.data_bitrate)
                    for n, f in zip(nominal.tolist(), fast.tolist())
                ]
            else:
                bits = can_frame_bits_exact_batch(src.can_id, src.extended, payloads)
                durations = [bits_to_ns(b, self.bitrate) for b in bits.tolist()]
            for r, payload, dur in zip(rows.tolist(), payloads, durations):
                blob = payload.tobytes()
                data[first_new + r] = blob
                self._exact[(s, blob)] = dur
        return data

    def payloads(self, src: CanSource, n: int) -> np.ndarray:
        """n seeded random payloads of the source, each field inside its [minimum, maximum]."""
        payloads = self.sim.rng.integers(0, 256, (n, src.size), dtype=np.uint8)
        fill_in_range(src.fields, payloads, self.sim.rng)
        return payloads

    def duration(self, src: CanSource, data: bytes | None) -> int:
        payload = data if data is not None else src.rest
        known = self._exact.get((src.index, payload))
        if known is not None:
            return known
        if src.fd:
            fd_bits = canfd_frame_bits_exact(src.can_id, src.extended, bytes(payload), src.brs)
            return fd_bits.ns(self.bitrate, self.data_bitrate)
        return bits_to_ns(can_frame_bits_of(src.can_id, src.extended, payload, "exact"), self.bitrate)
