"""Frame lengths and quantities, checked against the formulas' sources."""

from __future__ import annotations

import pytest

from netcfg.spec.units import Duration, parse_bitrate, parse_duration, parse_frequency
from netcfg.timing.ethernet import max_min_frame_rate, min_frame_ns, propagation_ns
from netcfg.timing.frames import (
    bits_to_ns,
    can_frame_bits,
    udp_frame_bytes,
    udp_frame_ns,
    udp_message_bytes,
    udp_message_ns,
)


@pytest.mark.parametrize("size", range(9))
def test_can_worst_case_frame_bits_follow_davis_2007(size: int) -> None:
    """Davis et al. 2007, eq. 1: C = g + 8s + 13 + floor((g + 8s - 1) / 4), g = 34 (11-bit) or 54 (29-bit),
    which the issue writes as 55 + 10s (standard) and 80 + 10s (extended)."""
    assert can_frame_bits(size, extended=False) == 55 + 10 * size
    assert can_frame_bits(size, extended=True) == 80 + 10 * size


@pytest.mark.parametrize("size", range(9))
def test_can_nominal_frame_bits(size: int) -> None:
    """Without stuff bits: 47 + 8s (standard, 44 bits of frame + 3 of intermission) and 67 + 8s (extended)."""
    assert can_frame_bits(size, stuffing="nominal") == 47 + 8 * size
    assert can_frame_bits(size, extended=True, stuffing="nominal") == 67 + 8 * size


def test_trigger_message_time_matches_cambada() -> None:
    """Seed 002, section 5.2: a 5-byte trigger message at 250 kbit/s takes 420 us (105 bits x 4 us)."""
    assert bits_to_ns(can_frame_bits(5), 250_000) == 420_000


def test_ethernet_frame_sizes_match_seed_001() -> None:
    """Seed 001, section 6.2.2.12: the minimum message on the wire is 84 bytes, 6.72 us at 100 Mbit/s, a maximum
    rate of 148.81 kHz; a full frame is 1538 bytes, 123.04 us; up to 18 data bytes fit the minimum frame."""
    assert udp_frame_bytes(1) == udp_frame_bytes(18) == 84
    assert udp_frame_bytes(19) == 85
    assert udp_frame_ns(5, 100_000_000) == 6_720
    assert round(max_min_frame_rate(100_000_000), 2) == 148_809.52
    assert udp_frame_bytes(1472) == 1538
    assert udp_frame_ns(1472, 100_000_000) == 123_040
    assert min_frame_ns(100_000_000) == 6_720


def test_an_application_message_carries_its_id_byte() -> None:
    """Seed 001, Table 6.1: a datagram is the 1-byte message id, then the data. SAHR's 4-byte encoder is still a
    minimum frame (6.72 us at 100 Mbit/s); 17 data bytes fill the minimum frame, 18 do not; 1471 fill a full one."""
    assert udp_message_ns(4, 100_000_000) == 6_720
    assert udp_message_bytes(17) == 84 and udp_message_bytes(18) == 85
    assert udp_message_bytes(1471) == udp_frame_bytes(1472) == 1538


def test_cable_propagation_at_seven_tenths_of_c() -> None:
    """Seed 001: 0.4-0.7 c in a cable; at 0.7 c, 20 m take 95.3 ns, 50 m 238.3 ns, 10 m 47.7 ns, rounded to the
    nanosecond (the figures test_sim_ethernet's two-switch network checks)."""
    assert [propagation_ns(m) for m in (20, 50, 10, 0)] == [95, 238, 48, 0]


@pytest.mark.parametrize(
    ("text", "ns"),
    [
        ("5 ms", 5_000_000),
        ("250 us", 250_000),
        ("250 µs", 250_000),
        ("1.5 s", 1_500_000_000),
        ("66667 ns", 66_667),
        ("0.1 ms", 100_000),
        (0, 0),
    ],
)
def test_durations(text: str | int, ns: int) -> None:
    assert parse_duration(text) == Duration(ns=ns)


def test_durations_in_elementary_cycles() -> None:
    assert parse_duration("6 EC") == Duration(ec=6)
    assert parse_duration("6 EC").to_ns(5_000_000) == 30_000_000


@pytest.mark.parametrize("bad", ["5", 5, "5 parsec", "0.5 ns", "-1 ms", "1.5 EC", "ms"])
def test_bad_durations_are_refused(bad: object) -> None:
    with pytest.raises(ValueError):
        parse_duration(bad)


def test_rates() -> None:
    assert parse_bitrate("250 kbit/s") == 250_000
    assert parse_bitrate("1 Mbit/s") == 1_000_000
    assert parse_bitrate("100 Mbit/s") == 100_000_000
    assert parse_frequency("15 kHz") == 15_000
    with pytest.raises(ValueError):
        parse_bitrate("250")


def test_ftt_asynchronous_priority_follows_arbitration_not_the_raw_number() -> None:
    """ISO 11898-1 arbitration: an extended frame whose 11 base bits are 0 beats standard 0x7FE and 0x7FF,
    although its 29-bit number is far larger. Three asynchronous frames of 100, 100 and 500 us: in the right
    order the extended one waits only for the longest lower-priority frame (100 + 500 us of demand), 0x7FE also for
    the extended one (100 + 500 + 100 us); sorted by the raw number it would be the other way round."""
    from netcfg.timing.ftt import AsyncFrame, EcSlot, Schedule, async_response_times

    slot = EcSlot(index=0, messages=(), triggers=(), ids=(), sync_ns=0, async_ns=4_000_000)
    sched = Schedule(ec_ns=5_000_000, tm_ns=400_000, lsw_ns=4_600_000, entries=(), slots=(slot,))
    frames = [
        AsyncFrame("ext", 0x0001_2345, 100_000, 100_000_000, extended=True),
        AsyncFrame("std_7fe", 0x7FE, 100_000, 100_000_000),
        AsyncFrame("std_7ff", 0x7FF, 500_000, 100_000_000),
    ]
    r = async_response_times(sched, frames)
    assert r["ext"] is not None and r["std_7fe"] is not None
    assert r["ext"] < r["std_7fe"]
