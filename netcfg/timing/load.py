"""Bus load: per-message transmission times and per-bus (or per-link) utilisation.

Periodic messages count at their fastest admissible period, sporadic ones at their minimum inter-arrival
time; on-demand messages (start-up, mode changes) are not part of the steady-state load.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING, Protocol

from netcfg.timing.frames import FdFrameBits, bits_to_ns, frame_bits, udp_message_bytes

if TYPE_CHECKING:  # annotations only: the simulator reads runtime messages and needs no spec model
    from netcfg import model


@dataclass(frozen=True)
class FrameTiming:
    bits_worst: int  # CAN FD: both phases together
    bits_nominal: int
    tx_ns: int  # worst case on the wire
    utilization: float  # tx_ns / interval, 0 for on-demand
    nominal_ns: int = 0  # best case on the wire: no stuff bits
    fd_worst: FdFrameBits | None = None  # CAN FD: the worst case's bits at the arbitration and at the data rate


class Framed(Protocol):
    """What a frame's length depends on: a spec's message (netcfg.model) and a runtime one (netcfg.runtime)."""

    @property
    def name(self) -> str: ...
    @property
    def size(self) -> int: ...
    @property
    def extended(self) -> bool: ...
    @property
    def fd(self) -> bool: ...
    @property
    def brs(self) -> bool: ...
    @property
    def interval_ns(self) -> int | None: ...


def frame_timing(msg: Framed, bitrate: int, data_bitrate: int | None = None) -> FrameTiming:
    """One CAN data frame: classical, or CAN FD (msg.fd) with its data phase at data_bitrate when msg.brs. What
    `check` times a message with, and so verify, the simulator and tune (netcfg.timing.frames.frame_bits)."""
    if msg.fd and data_bitrate is None:
        raise ValueError(f"CAN FD message '{msg.name}' needs the bus's data bit rate")
    worst = frame_bits(msg.size, msg.extended, msg.fd, msg.brs, "worst")
    nominal = frame_bits(msg.size, msg.extended, msg.fd, msg.brs, "nominal")
    tx = worst.ns(bitrate, data_bitrate)
    return FrameTiming(
        worst.total,
        nominal.total,
        tx,
        tx / msg.interval_ns if msg.interval_ns else 0.0,
        nominal.ns(bitrate, data_bitrate),
        worst if msg.fd else None,
    )


def udp_timing(msg: model.Message, bitrate: int) -> FrameTiming:
    """One UDP datagram: the 1-byte application message id (seed 001, Table 6.1) + the data."""
    bits = 8 * udp_message_bytes(msg.size)
    tx = bits_to_ns(bits, bitrate)
    return FrameTiming(bits, bits, tx, tx * float(rate_hz(msg)) / 1e9, tx)


class Rated(Protocol):
    """What the rate of a message depends on: a spec's message (netcfg.model) and a runtime one (netcfg.runtime)."""

    @property
    def kind(self) -> str: ...
    @property
    def period_ns(self) -> int | None: ...
    @property
    def interval_ns(self) -> int | None: ...
    @property
    def rate_hz(self) -> Fraction | None: ...


def exact_rate(msg: Rated) -> Fraction | None:
    """The rate the spec gave, when the message is sent at it (not a sporadic minimum inter-arrival time)."""
    return msg.rate_hz if msg.rate_hz is not None and msg.period_ns == msg.interval_ns else None


def rate_hz(msg: Rated) -> float:
    """Transmissions per second at the fastest admissible rate (exact when the spec gave a rate)."""
    if msg.kind == "on-demand" or not msg.interval_ns:
        return 0.0
    exact = exact_rate(msg)
    if exact is not None:
        return float(exact)
    return 1e9 / msg.interval_ns


EXACT_MARGIN = 1e-9  # float utilisations closer than this to 1 are decided again with fractions


def compare_to_capacity(approx: float, loads: Iterable[tuple[int, int]]) -> int:
    """Sign of (sum of C / T) - 1 over (C, T) pairs in integer time, decided exactly: the float sum `approx`
    settles it unless it lies within EXACT_MARGIN of 1, where floats depend on the order of the terms."""
    if approx < 1 - EXACT_MARGIN:
        return -1
    if approx > 1 + EXACT_MARGIN:
        return 1
    total = sum((Fraction(c, t) for c, t in loads), Fraction(0))
    return (total > 1) - (total < 1)


def can_bus_load(bus: model.Bus) -> tuple[dict[str, FrameTiming], float, float]:
    """-> (timing per message, worst-case utilisation, utilisation without stuff bits)."""
    timings = {m.name: frame_timing(m, bus.bitrate, bus.data_bitrate) for m in bus.messages}
    worst = sum(t.utilization for t in timings.values())
    nominal = sum(
        t.nominal_ns / m.interval_ns
        for m, t in zip(bus.messages, timings.values())
        if m.interval_ns and m.kind != "on-demand"
    )
    return timings, worst, nominal


def can_bus_overloaded(
    bus: model.Bus, timings: dict[str, FrameTiming], approx: float, extra: tuple[int, int] | None = None
) -> bool:
    """True when the worst-case load (plus an extra C / T such as FTT-CAN's trigger message) is above 100 %,
    decided exactly (a load of exactly 1 fits)."""
    loads = [(timings[m.name].tx_ns, m.interval_ns) for m in bus.messages if m.interval_ns and m.kind != "on-demand"]
    return compare_to_capacity(approx, [*loads, *([extra] if extra else [])]) > 0
