"""The simulator's building blocks, each against a hand calculation or the standard."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from netcfg.sim.can_bus import CanBus
from netcfg.sim.engine import NEVER, NodeClock, Simulator
from netcfg.sim.streams import PeriodicStreams
from netcfg.timing.frames import arbitration_key


def test_arbitration_follows_the_bits_on_the_wire() -> None:
    """ISO 11898-1: after the 11 base identifier bits a standard frame sends RTR and IDE dominant, an extended one
    SRR and IDE recessive, so with equal base bits the standard frame wins; otherwise the base bits decide, then
    the 18 extension bits."""
    assert arbitration_key(0x123, False) < arbitration_key(0x123 << 18, True)
    assert arbitration_key(0x122 << 18 | 0x3FFFF, True) < arbitration_key(0x123, False)
    assert arbitration_key(0x123 << 18 | 1, True) < arbitration_key(0x123 << 18 | 2, True)
    assert arbitration_key(0x000, False) < arbitration_key(0x001, False)


def test_a_drifting_clock_gains_its_ppm() -> None:
    """+50 ppm: one local second lasts 1 s + 50 us of global time; -20 ppm, 1 s - 20 us; the phase adds."""
    assert NodeClock(0, 50_000).to_global(1_000_000_000) == 1_000_050_000
    assert NodeClock(7, -20_000).to_global(1_000_000_000) == 999_980_007


def test_non_preemptive_fixed_priority_arbitration_by_hand() -> None:
    """1 Mbit/s, three 0-byte frames of 55 bits (worst-case stuffing, Davis et al. 2007) = 55 us each.
    A (0x200) and C (0x300) are queued at 0, B (0x100) at 10 us while A is on the wire. A wins at 0 (0..55 us);
    B, although of higher priority, waits for A to end (no preemption) and wins at 55 us (55..110); C goes last
    (110..165). Responses: A 55 us, B 110 - 10 = 100 us, C 165 us."""
    sim = Simulator()
    bus = CanBus(sim, "can0", 1_000_000)
    a = bus.add_source("A", 0x200, False, 0, "n1")
    b = bus.add_source("B", 0x100, False, 0, "n2")
    c = bus.add_source("C", 0x300, False, 0, "n3")
    bus.start()
    sim.at(0, lambda _: (bus.submit(a), bus.submit(c)))
    sim.at(10_000, lambda _: bus.submit(b))
    sim.run_until(1_000_000)
    got = dict(zip(bus.record.msg, bus.record.response))
    assert bus.record.msg == [a, b, c]
    assert got == {a: 55_000, b: 100_000, c: 165_000}


@pytest.mark.parametrize(("stuffing", "bits"), [("worst", 65), ("none", 55), ("exact", 58)])
def test_the_bus_takes_frame_lengths_from_the_timing_core(stuffing: str, bits: int) -> None:
    """One 1-byte frame, identifier 0x14, data 0x01, alone at 1 Mbit/s (1 us per bit): 55 + 10 bits with the
    worst case of stuffing (Davis et al. 2007), 47 + 8 without, 58 with the stuff bits it actually has
    (frames.can_frame_bits_of, test_bitstream.py)."""
    sim = Simulator()
    bus = CanBus(sim, "can0", 1_000_000, stuffing=stuffing)
    a = bus.add_source("A", 0x14, False, 1, "n1")
    bus.start()
    sim.at(0, lambda _: bus.submit(a, b"\x01"))
    sim.run_until(1_000_000)
    assert bus.record.response == [bits * 1_000]


def test_a_bit_error_retransmits_after_the_error_frame() -> None:
    """One 0-byte frame (55 us at 1 Mbit/s) hit by a bit error 20 us in: error flags, delimiter and intermission
    take 6 + 6 + 8 + 3 = 23 bits (ISO 11898-1, longest active error frame), then the frame is sent again whole:
    response = 20 + 23 + 55 = 98 us, one retransmission."""
    sim = Simulator()
    bus = CanBus(sim, "can0", 1_000_000)
    a = bus.add_source("A", 0x10, False, 0, "n1")
    bus.error_times = [20_000]
    bus.start()
    sim.at(0, lambda _: bus.submit(a))
    sim.run_until(1_000_000)
    assert bus.record.response == [98_000]
    assert bus.retries == {a: 1}
    assert bus.error_frames == 1


@settings(max_examples=40, derandomize=True, deadline=None)
@given(
    period=st.integers(100_000, 50_000_000),
    den=st.integers(1, 7),
    offset=st.integers(0, 10_000_000),
    phase=st.integers(0, 20_000_000),
    drift=st.integers(-100_000, 100_000),
    cut=st.integers(1, 300_000_000),
)
def test_release_streams_do_not_depend_on_where_chunks_are_cut(
    period: int, den: int, offset: int, phase: int, drift: int, cut: int
) -> None:
    """The releases in [0, T) are the same whether expanded in one chunk or in two cut anywhere, and they are
    exactly phase + L + L * drift (L = offset + floor(k * period), the clock's mapping), for a period of whole
    nanoseconds or a fraction of them (an exact rate in hertz); a stream of several sources gives each the same
    releases as a stream of its own."""
    exact = Fraction(period, den)
    make = lambda: PeriodicStreams([0], [exact], [offset], [phase], [drift], [0], [NEVER], np.random.default_rng(0))  # noqa: E731
    end = 400_000_000
    whole = make()(0, end)[0]
    s = make()
    parts = np.concatenate([s(0, cut)[0], s(cut, end)[0]])
    assert whole.tolist() == parts.tolist()
    clock = NodeClock(phase, drift)
    local = [offset + k * exact.numerator // exact.denominator for k in range(end // int(exact) + 2)]
    expected = [t for t in map(clock.to_global, local) if t < end]
    assert whole.tolist() == expected
    rng = np.random.default_rng(0)
    two = PeriodicStreams([5, 0], [1_000_003, exact], [7, offset], [11, phase], [3, drift], [0, 0], [NEVER, NEVER], rng)
    t, src = two(0, cut)
    t2, src2 = two(cut, end)
    assert np.concatenate([t[src == 0], t2[src2 == 0]]).tolist() == expected


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-(10**12), 10**12), min_size=1, max_size=400), st.sampled_from([1, 1000, 10**9]))
def test_p99_is_numpys_nearest_rank(values: list[int], scale: int) -> None:
    """stats.nearest_rank counts a histogram where np.percentile partitions; numpy's "inverted_cdf" is the
    reference, on wide ranges (partition) and narrow ones (histogram), with many repeated values."""
    from netcfg.sim.stats import nearest_rank

    x = np.asarray(values, dtype=np.int64) // scale
    assert nearest_rank(x, 99) == int(np.percentile(x, 99, method="inverted_cdf"))
