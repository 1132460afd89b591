"""CAN FD frame lengths (ISO 11898-1:2015), checked against hand counts field by field.

Base format, worst case, by hand (s = padded data bytes):
  nominal rate: arbitration SOF..BRS 17 + its worst dynamic stuff bits floor((17 - 1) / 4) = 4 + CRC delimiter 1
                + ACK slot, ACK delimiter, EOF 7, intermission 3 = 12                               -> 34 bits
  data rate:    ESI + DLC 5 + 8s + stuff count 4 + CRC 17|21 + fixed stuff bits 6|7
                + the remaining dynamic stuff bits floor((22 + 8s - 1) / 4) - 4
  e.g. s = 8:   5 + 64 + 4 + 17 + 6 + (floor(85 / 4) - 4 = 17)                                     -> 113 bits
       s = 64:  5 + 512 + 4 + 21 + 7 + (floor(533 / 4) - 4 = 129)                                  -> 678 bits
Extended format: arbitration 36 bits with floor(35 / 4) = 8 stuff bits, so 36 + 8 + 1 + 12 = 57 nominal bits, and
the dynamic stuffing region grows by 19 bits (41 + 8s).
Best case: no dynamic stuff bits; the BRS bit and the CRC delimiter at the data rate: 16 + 12 = 28 nominal bits and
1 + 5 + 8s + 4 + CRC + fixed stuff + 1 data bits.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from netcfg.timing.frames import (
    CANFD_LENGTHS,
    FdFrameBits,
    can_frame_bits,
    canfd_dlc,
    canfd_frame_bits,
    canfd_frame_bits_exact,
    canfd_frame_bits_exact_batch,
    canfd_padded_size,
)

# (padded length, worst-case data-phase bits base format, extended format, best-case data-phase bits), by hand
# from the docstring's sums.
HAND = [
    (0, 5 + 0 + 27 + (5 - 4), 5 + 0 + 27 + (10 - 8), 1 + 5 + 0 + 27 + 1),
    (1, 5 + 8 + 27 + (7 - 4), 5 + 8 + 27 + (12 - 8), 1 + 5 + 8 + 27 + 1),
    (2, 5 + 16 + 27 + (9 - 4), 5 + 16 + 27 + (14 - 8), 1 + 5 + 16 + 27 + 1),
    (3, 5 + 24 + 27 + (11 - 4), 5 + 24 + 27 + (16 - 8), 1 + 5 + 24 + 27 + 1),
    (4, 5 + 32 + 27 + (13 - 4), 5 + 32 + 27 + (18 - 8), 1 + 5 + 32 + 27 + 1),
    (5, 5 + 40 + 27 + (15 - 4), 5 + 40 + 27 + (20 - 8), 1 + 5 + 40 + 27 + 1),
    (6, 5 + 48 + 27 + (17 - 4), 5 + 48 + 27 + (22 - 8), 1 + 5 + 48 + 27 + 1),
    (7, 5 + 56 + 27 + (19 - 4), 5 + 56 + 27 + (24 - 8), 1 + 5 + 56 + 27 + 1),
    (8, 5 + 64 + 27 + (21 - 4), 5 + 64 + 27 + (26 - 8), 1 + 5 + 64 + 27 + 1),
    (12, 5 + 96 + 27 + (29 - 4), 5 + 96 + 27 + (34 - 8), 1 + 5 + 96 + 27 + 1),
    (16, 5 + 128 + 27 + (37 - 4), 5 + 128 + 27 + (42 - 8), 1 + 5 + 128 + 27 + 1),
    (20, 5 + 160 + 32 + (45 - 4), 5 + 160 + 32 + (50 - 8), 1 + 5 + 160 + 32 + 1),
    (24, 5 + 192 + 32 + (53 - 4), 5 + 192 + 32 + (58 - 8), 1 + 5 + 192 + 32 + 1),
    (32, 5 + 256 + 32 + (69 - 4), 5 + 256 + 32 + (74 - 8), 1 + 5 + 256 + 32 + 1),
    (48, 5 + 384 + 32 + (101 - 4), 5 + 384 + 32 + (106 - 8), 1 + 5 + 384 + 32 + 1),
    (64, 5 + 512 + 32 + (133 - 4), 5 + 512 + 32 + (138 - 8), 1 + 5 + 512 + 32 + 1),
]
# 27 = stuff count 4 + CRC-17 + 6 fixed stuff bits; 32 = 4 + CRC-21 + 7. The stuff totals in brackets are
# floor((22 + 8s - 1) / 4) (base) and floor((41 + 8s - 1) / 4) (extended), worked out per row.


@pytest.mark.parametrize(("size", "worst_base", "worst_ext", "best"), HAND)
def test_fd_frame_bits_match_hand_counts(size: int, worst_base: int, worst_ext: int, best: int) -> None:
    assert canfd_frame_bits(size) == FdFrameBits(34, worst_base)
    assert canfd_frame_bits(size, extended=True) == FdFrameBits(57, worst_ext)
    assert canfd_frame_bits(size, stuffing="nominal") == FdFrameBits(28, best)
    assert canfd_frame_bits(size, extended=True, stuffing="nominal") == FdFrameBits(28 + 19, best)


@pytest.mark.parametrize(("size", "worst_base", "worst_ext", "best"), HAND)
def test_fd_frame_without_brs_is_all_nominal(size: int, worst_base: int, worst_ext: int, best: int) -> None:
    """Without bit-rate switch the same bits all go at the nominal rate."""
    assert canfd_frame_bits(size, brs=False) == FdFrameBits(34 + worst_base, 0)
    assert canfd_frame_bits(size, extended=True, brs=False) == FdFrameBits(57 + worst_ext, 0)
    assert canfd_frame_bits(size, brs=False, stuffing="nominal") == FdFrameBits(28 + best, 0)


def test_dlc_lengths_and_padding() -> None:
    """ISO 11898-1:2015 Table 5: DLC 9..15 carry 12, 16, 20, 24, 32, 48, 64 bytes."""
    assert [canfd_dlc(n) for n in CANFD_LENGTHS] == list(range(16))
    assert canfd_padded_size(9) == 12
    assert canfd_padded_size(17) == 20
    assert canfd_padded_size(33) == 48
    assert canfd_frame_bits(9) == canfd_frame_bits(12)
    for bad in (-1, 65):
        with pytest.raises(ValueError):
            canfd_padded_size(bad)


def test_fd_best_case_never_exceeds_worst_case_at_any_rate_pair() -> None:
    for size in CANFD_LENGTHS:
        for extended in (False, True):
            for bitrate, data_bitrate in ((500_000, 2_000_000), (1_000_000, 5_000_000), (1_000_000, 1_000_000)):
                best = canfd_frame_bits(size, extended, stuffing="nominal").ns(bitrate, data_bitrate)
                worst = canfd_frame_bits(size, extended).ns(bitrate, data_bitrate)
                assert best <= worst


def test_arm_loads_from_issue_hand_figures() -> None:
    """The CAN FD issue's hand figures for a 9-joint arm at 1 kHz (1 Mbit/s arbitration, 5 Mbit/s data):
    per-joint 8-byte command and feedback frames need about 243 % of classical CAN, about 102 % of CAN FD (eight
    joints: about 91 %), and one 64-byte command frame plus nine 8-byte feedback frames about 68 %."""
    period_ns = 1_000_000
    classical = 18 * can_frame_bits(8) * 1000  # 135 bits at 1 us each
    assert round(100 * classical / period_ns) == 243
    fd8 = canfd_frame_bits(8).ns(1_000_000, 5_000_000)  # 34 us + 113 bits x 200 ns = 56.6 us
    assert fd8 == 56_600
    assert round(100 * 18 * fd8 / period_ns) == 102
    assert round(100 * 16 * fd8 / period_ns) == 91
    fd64 = canfd_frame_bits(64).ns(1_000_000, 5_000_000)  # 34 us + 678 x 200 ns = 169.6 us
    assert fd64 == 169_600
    assert round(100 * (fd64 + 9 * fd8) / period_ns) == 68


def test_exact_fd_frame_by_hand() -> None:
    """Identifier 0, base format, BRS, eight zero bytes, counted bit by bit:
    SOF, 11 identifier bits, RRS, IDE are 14 dominant bits: stuff bits after the 5th and the 10th (the stuff bit
    after the 5th starts a new run), 4 zeros left; FDF 1, res 0, BRS 1: 2 stuff bits in the 17 arbitration bits,
    nominal 17 + 2 + CRC delimiter 1 + 12 = 32. Data phase: ESI 0, DLC 1000 (three zeros), then 64 zero data bits:
    a stuff bit after the 2nd data bit, then one per 5 zeros in the remaining 62: 12; 13 in all.
    5 + 64 + stuff count 4 + CRC-17 + 6 fixed stuff bits + 13 = 109."""
    exact = canfd_frame_bits_exact(0, False, bytes(8))
    assert exact == FdFrameBits(32, 109)
    nominal, data = canfd_frame_bits_exact_batch(0, False, True, np.zeros((3, 8), dtype=np.uint8))
    assert nominal.tolist() == [32] * 3 and data.tolist() == [109] * 3
    assert canfd_frame_bits_exact(0, False, bytes(8), brs=False) == FdFrameBits(32 + 109, 0)


@settings(max_examples=60, deadline=None)
@given(
    can_id=st.integers(0, 0x1FFFFFFF),
    extended=st.booleans(),
    brs=st.booleans(),
    data=st.binary(min_size=0, max_size=64),
)
def test_exact_fd_frame_within_worst_and_best_case(can_id: int, extended: bool, brs: bool, data: bytes) -> None:
    """best <= exact <= worst at several rate pairs (the module docstring's bounds), and the batch path agrees."""
    if not extended:
        can_id &= 0x7FF
    exact = canfd_frame_bits_exact(can_id, extended, data, brs)
    worst = canfd_frame_bits(len(data), extended, brs, "worst")
    best = canfd_frame_bits(len(data), extended, brs, "nominal")
    for rates in ((1_000_000, 5_000_000), (500_000, 2_000_000), (1_000_000, 1_000_000), (125_000, 8_000_000)):
        assert best.ns(*rates) <= exact.ns(*rates) <= worst.ns(*rates)
    nominal, data_bits = canfd_frame_bits_exact_batch(
        can_id, extended, brs, np.frombuffer(data, dtype=np.uint8).reshape(1, len(data))
    )
    assert (int(nominal[0]), int(data_bits[0])) == (exact.nominal, exact.data)
