"""Drifting node clocks in the CAN analysis (timing.clocks): a sender whose crystal runs fast releases its
periodic messages more often than nominal, and the analysis must count that (the simulator drifts each node
within +-50 ppm; a bus's clock_tolerance, default 100 ppm, bounds it)."""

from __future__ import annotations

from netcfg.timing import can_offsets, can_rta, clocks

US = 1000


def test_clock_conversions_by_hand() -> None:
    """At 100 ppm: 1 s of real time is at most 1 s / (1 - 1e-4) = 1,000,100.010001 us of a fast clock, rounded up
    to whole ns: 1,000,100,011 ns; 10 ms of a clock last between 10 ms - 1 us and 10 ms + 1 us of real time.
    At 0 ppm every conversion is the identity."""
    assert clocks.longest_local(10**9, 100) == 1_000_100_011
    assert clocks.shortest_real(10_000_000, 100) == 9_999_000
    assert clocks.longest_real(10_000_000, 100) == 10_001_000
    assert clocks.longest_local(12_345, 0) == clocks.shortest_real(12_345, 0) == 12_345


def boundary_bus() -> list[can_rta.CanFrame]:
    """k1 (C 500 us, T 1 ms) and k2 (C 499 us, sent once) above m (C 100 us), at 1 Mbit/s (tau 1 us)."""
    return [
        can_rta.CanFrame("k1", 0x10, False, 500 * US, 1000 * US),
        can_rta.CanFrame("k2", 0x20, False, 499 * US, None),
        can_rta.CanFrame("m", 0x30, False, 100 * US, 10_000 * US),
    ]


def test_a_fast_clock_adds_a_release_at_the_boundary() -> None:
    """Davis et al. 2007 eq. 12 for m, q = 0, B = 0: w = 500 + 499 = 999 us; w + tau = 1000 us.
    Nominal clocks: ceil(1000 / 1000) = 1 release of k1, so w = 999 us and R = 999 + 100 = 1099 us.
    A k1 clock 100 ppm fast releases again after 1000 us (1 - 1e-4) = 999.9 us, before m can start at 1000 us:
    ceil(longest_local(1000 us) / 1000 us) = ceil(1000.1 / 1000) = 2, so w = 999 + 500 = 1499 us (w + tau = 1500 us
    of real time holds at most 1500.15 us of k1's clock: still 2 releases) and R = 1599 us."""
    tau = 1 * US
    assert can_rta.analyse(boundary_bus(), tau)["m"].wcrt_ns == 1099 * US
    assert can_rta.analyse(boundary_bus(), tau, tolerance_ppm=100)["m"].wcrt_ns == 1599 * US
    # the offset-aware analysis never goes above the offset-free one and sees the same release without offsets
    assert can_offsets.analyse(boundary_bus(), tau, {}, 100)["m"].wcrt_ns == 1599 * US


def test_exactly_full_with_drifting_clocks_is_unbounded() -> None:
    """Two frames of 1 ms every 2 ms fill the bus exactly: with exact clocks the busy period ends at the
    hyperperiod (2 ms) and m's bound is 2 ms (Davis et al. 2007; can_rta's exact-1 rule); if the senders' clocks
    may run fast, the fastest of them ask for 1 / (1 - 1e-4) of the bus, over its capacity: unbounded."""
    frames = [
        can_rta.CanFrame("k", 0x10, False, 1000 * US, 2000 * US),
        can_rta.CanFrame("m", 0x20, False, 1000 * US, 2000 * US),
    ]
    assert can_rta.analyse(frames, US)["m"].wcrt_ns == 2000 * US
    fast = can_rta.analyse(frames, US, tolerance_ppm=100)["m"]
    assert fast.wcrt_ns is None and fast.limit == "load"


def test_long_windows_do_not_overflow() -> None:
    """A window of 10^15 ns (the longest duration a spec takes) at 10,000 ppm: x * ppm = 10^19 is past int64, so
    the arithmetic must not form it. ceil(10^15 / 0.99) = 1,010,101,010,101,011 ns, the same for a Python integer
    and an int64 array."""
    import numpy as np

    x = 10**15
    assert clocks.longest_local(x, 10_000) == 1_010_101_010_101_011
    assert int(clocks.longest_local(np.array([x], dtype=np.int64), 10_000)[0]) == 1_010_101_010_101_011
    assert clocks.shortest_real(x, 10_000) == 990_000_000_000_000
