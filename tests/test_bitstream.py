"""The exact CAN bit stream: CRC-15, frame layout, bit stuffing, exact frame lengths (scalar and batch)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from crccheck.crc import Crc15Can  # a peer implementation, installed with cantools
from hypothesis import given, settings
from hypothesis import strategies as st

from netcfg.timing.frames import (
    can_crc15,
    can_frame_bits,
    can_frame_bits_exact,
    can_frame_bits_exact_batch,
    can_frame_bits_of,
    can_frame_fields,
    count_stuff_bits,
    stuff_bits,
)

PROPERTY = settings(max_examples=150, deadline=None, derandomize=True)


def bits_of(data: bytes) -> list[int]:
    return [(byte >> i) & 1 for byte in data for i in range(7, -1, -1)]


def peer_crc15(bits: list[int]) -> int:
    """crccheck's CRC-15/CAN works on bytes; the CAN CRC starts from 0, so leading zero bits leave the register at 0
    and padding the front to a whole number of bytes gives the CRC of the bit sequence itself."""
    padded = [0] * (-len(bits) % 8) + bits
    data = bytes(int("".join(map(str, padded[i : i + 8])), 2) for i in range(0, len(padded), 8))
    return int(Crc15Can.calc(data))


def test_crc15_check_value() -> None:
    """CRC catalogue (reveng), CRC-15/CAN: width 15, poly 0x4599, init 0, no reflection, xorout 0,
    check = 0x059E for ASCII "123456789" (fed MSB first)."""
    assert can_crc15(bits_of(b"123456789")) == 0x059E
    assert Crc15Can.calc(b"123456789") == 0x059E  # the peer is the same catalogue algorithm


@PROPERTY
@given(st.lists(st.integers(0, 1), max_size=200))
def test_crc15_matches_crccheck(bits: list[int]) -> None:
    """Peer: crccheck.crc.Crc15Can, over any bit length (front-padded, see peer_crc15)."""
    assert can_crc15(bits) == peer_crc15(bits)


def test_published_frame_bit_for_bit() -> None:
    """commaai/panda, tests/gmbitbang/test_packer.c: the expected bus bits of a base frame with identifier 20 (0x14),
    DLC 1, data 0x01, stuff bits included, followed by CRC delimiter, ACK, ACK delimiter, EOF 7 and 3 bits of
    inter-frame space (all recessive) -- the same 13-bit tail our lengths count."""
    published = "0000010010100000100010000010011110111010100111111111111111"
    fields = can_frame_fields(0x14, False, b"\x01")
    on_bus = "".join(map(str, stuff_bits(fields))) + "1" * 13
    assert on_bus == published
    assert can_frame_bits_exact(0x14, False, b"\x01") == len(published) == 58
    assert count_stuff_bits(fields) == 3
    assert can_crc15(fields[:-15]) == peer_crc15(fields[:-15])


@pytest.mark.parametrize(
    ("can_id", "extended", "data", "crc", "stuff", "total"),
    [
        (0x7FF, False, b"", 0x272F, 3, 50),
        (0x000, False, bytes(8), 0x145B, 16, 127),
        (0x1FFFFFFF, True, b"", 0x1C88, 7, 74),
    ],
)
def test_hand_counted_frames(can_id: int, extended: bool, data: bytes, crc: int, stuff: int, total: int) -> None:
    """CRC values from the peer crccheck Crc15Can (checked below too); stuff bits counted by hand, a stuff bit
    starting the next run (ISO 11898-1), total = stuffed region + stuff + 13:

    id 0x7FF, DLC 0 (34 bits): 0 11111111111 0000000 | CRC 0x272F = 010011100101111.
      SOF 0, then ones 1-5 -> stuff 0 (1); ones 6-10 -> stuff 0 (2); one 11 is a run of 1; RTR, IDE, r0, DLC 0000
      are 7 zeros: zeros 1-5 -> stuff 1 (3); zeros 6-7 and the CRC's leading 0 make 3; the CRC's longest run is
      its final 1111. 3 stuff bits, 34 + 3 + 13 = 50.
    id 0x000, DLC 8, data 00 x 8 (98 bits): 15 zeros (SOF, id, RTR, IDE, r0), DLC 1000, 64 zeros,
      CRC 0x145B = 001010001011011.
      Zeros 1-15 -> stuff 1 after the 5th, 10th, 15th (3); that stuff 1 and DLC's 1 make a run of 2; then
      3 + 64 = 67 zeros -> a stuff after every 5, 13 of them (16), leaving zeros 66-67 to run on into the CRC's
      00: 4, no stuff; the rest of the CRC has no run over 3. 16 stuff bits, 98 + 16 + 13 = 127.
    id 0x1FFFFFFF extended, DLC 0 (54 bits): SOF 0, 11 + SRR + IDE + 18 = 31 ones, RTR r1 r0 DLC = 7 zeros,
      CRC 0x1C88 = 001110010001000.
      31 ones -> a stuff 0 after every 5: 6 stuff bits, the 31st one a run of 1; 7 zeros -> stuff 1 (7) after
      the 5th, zeros 6-7 + CRC 00 = 4; the CRC then runs at most 3. 7 stuff bits, 54 + 7 + 13 = 74.
    """
    fields = can_frame_fields(can_id, extended, data)
    assert len(fields) == (54 if extended else 34) + 8 * len(data)
    assert can_crc15(fields[:-15]) == peer_crc15(fields[:-15]) == crc
    assert int("".join(map(str, fields[-15:])), 2) == crc
    assert count_stuff_bits(fields) == stuff
    assert can_frame_bits_exact(can_id, extended, data) == total


def test_stuff_bit_counts_toward_the_next_run() -> None:
    """ISO 11898-1 stuffing, by hand: 11111 0000 -> 11111 [0] 0000 [1]: the stuff 0 and the four data zeros are
    five equal bits, so a second stuff bit follows (the case behind Davis et al.'s one-in-four worst case)."""
    bits = [1, 1, 1, 1, 1, 0, 0, 0, 0]
    assert stuff_bits(bits) == [1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 1]
    assert count_stuff_bits(bits) == 2
    assert count_stuff_bits([0, 1] * 20) == 0
    assert count_stuff_bits([0] * 4) == 0


@PROPERTY
@given(st.booleans(), st.integers(0, (1 << 29) - 1), st.binary(max_size=8), st.booleans())
def test_field_layout(extended: bool, raw_id: int, data: bytes, rtr: bool) -> None:
    """Bosch CAN 2.0 (1991) part B, 3.1.1, read field by field:
    base:     SOF | id 11 | RTR | IDE=0 | r0=0 | DLC 4 | data 8s | CRC 15
    extended: SOF | id[28:18] 11 | SRR=1 | IDE=1 | id[17:0] 18 | RTR | r1=0 | r0=0 | DLC 4 | data 8s | CRC 15
    (a remote frame has RTR = 1 and no data field)."""
    can_id = raw_id if extended else raw_id & 0x7FF
    bits = can_frame_fields(can_id, extended, data, rtr)

    def take(n: int) -> int:
        nonlocal bits
        value, bits = int("".join(map(str, bits[:n])) or "0", 2), bits[n:]
        return value

    assert take(1) == 0
    if extended:
        base, srr, ide, ext = take(11), take(1), take(1), take(18)
        assert (base << 18 | ext, srr, ide) == (can_id, 1, 1)
        assert take(1) == rtr
        assert take(2) == 0
    else:
        assert (take(11), take(1), take(1), take(1)) == (can_id, rtr, 0, 0)
    assert take(4) == len(data)
    if not rtr:
        assert take(8 * len(data)) == int.from_bytes(data, "big")
    take(15)
    assert bits == []


@PROPERTY
@given(st.booleans(), st.integers(0, (1 << 29) - 1), st.integers(0, 8), st.data())
def test_exact_between_nominal_and_worst_and_batch_equals_scalar(
    extended: bool, raw_id: int, size: int, draw: st.DataObject
) -> None:
    """Davis et al. 2007, eq. 1 (frames.py): no frame has fewer bits than without stuffing, nor more than with
    floor((g + 8s - 1) / 4) stuff bits; the batch path must agree with the scalar one row by row."""
    can_id = raw_id if extended else raw_id & 0x7FF
    rows = draw.draw(st.lists(st.binary(min_size=size, max_size=size), min_size=1, max_size=6))
    # bytes that make long runs, so the worst case is approached, not only random data
    rows += [bytes([b] * size) for b in (0x00, 0xFF, 0x0F, 0xF0, 0x3C, 0xC3)]
    scalar = [can_frame_bits_exact(can_id, extended, row) for row in rows]
    for bits in scalar:
        assert can_frame_bits(size, extended, "nominal") <= bits <= can_frame_bits(size, extended, "worst")
    payloads = np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(len(rows), size)
    batch = can_frame_bits_exact_batch(can_id, extended, payloads)
    assert batch.dtype == np.int64
    assert batch.tolist() == scalar


def test_stuffing_modes() -> None:
    """can_frame_bits_of gives can_frame_bits for worst/nominal and the exact count otherwise (frame above: 58)."""
    assert can_frame_bits_of(0x14, False, b"\x01", "worst") == can_frame_bits(1) == 65
    assert can_frame_bits_of(0x14, False, b"\x01", "nominal") == can_frame_bits(1, stuffing="nominal") == 55
    assert can_frame_bits_of(0x14, False, b"\x01") == 58


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: can_frame_fields(0x800, False, b""), "11 bits"),
        (lambda: can_frame_fields(1 << 29, True, b""), "29 bits"),
        (lambda: can_frame_fields(1, False, bytes(9)), "0..8"),
        (lambda: can_frame_bits_exact_batch(1, False, np.zeros((2, 9), dtype=np.uint8)), "0..8"),
        (lambda: can_frame_bits_exact_batch(1, False, np.zeros((2, 8), dtype=np.int64)), "uint8"),
        (lambda: can_frame_bits_exact_batch(1, False, np.zeros(8, dtype=np.uint8)), "2-D"),
    ],
)
def test_bad_frames_are_refused(call: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        call()  # type: ignore[operator]


def test_batch_throughput() -> None:
    """Prints the batch path's rate on 8-byte frames (no timing assertion); the large batch must still agree with
    the scalar path (itself checked against crccheck above) row for row on a sample."""
    payloads = np.random.default_rng(7).integers(0, 256, size=(200_000, 8), dtype=np.uint8)
    can_frame_bits_exact_batch(0x181, False, payloads[:1000])  # warm up
    start = time.perf_counter()
    bits = can_frame_bits_exact_batch(0x181, False, payloads)
    elapsed = time.perf_counter() - start
    print(f"\ncan_frame_bits_exact_batch: {len(payloads) / elapsed:,.0f} frames/s (8-byte, 11-bit id)")
    assert bits.shape == (200_000,)
    sample = range(0, 200_000, 997)
    assert [int(bits[i]) for i in sample] == [can_frame_bits_exact(0x181, False, payloads[i].tobytes()) for i in sample]
