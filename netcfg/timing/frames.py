"""Frame lengths and transmission times.

Classical CAN (Davis, Burns, Bril, Lukkien 2007, "Controller Area Network (CAN) schedulability analysis:
refuted, revisited and revised", Real-Time Systems 35, eq. 1): a frame of s data bytes takes, with the worst
case of bit stuffing and including the 3-bit inter-frame space,
    C = (g + 8s + 13 + floor((g + 8s - 1) / 4)) bit times,   g = 34 (11-bit ids) or 54 (29-bit ids)
which is 55 + 10s bits (standard) and 80 + 10s bits (extended). Without stuffing: g + 8s + 13 = 47 + 8s / 67 + 8s.

Switched Ethernet (seed 001, eq. 6.4): Tframe = (Ndata + Novhd + Npad) * 8 * Tbit, with the 84-byte minimum
on the wire (preamble 7, SFD 1, addresses 12, EtherType 2, data >= 46, FCS 4, inter-packet gap 12).

Exact classical CAN frames (ISO 11898-1; Bosch, "CAN Specification 2.0", 1991, part A 3.1.1 and part B 3.1.1): the
stuffed region runs from SOF through the CRC sequence, laid out as SOF, 11-bit identifier, RTR, IDE, r0, DLC, data,
CRC (base format) or SOF, base identifier 11, SRR, IDE, identifier extension 18, RTR, r1, r0, DLC, data, CRC
(extended format); that is g + 8s bits. The CRC-15 (generator 0x4599, register cleared at SOF) covers SOF through
the end of the data field. After five equal bits the transmitter inserts a complementary stuff bit, which itself
starts the next run. The rest of the frame is fixed form: CRC delimiter, ACK slot, ACK delimiter, 7 EOF bits, and
(as above) the 3-bit intermission, 13 bits. The exact count of stuff bits never exceeds floor((g + 8s - 1) / 4),
so can_frame_bits(s, x, "nominal") <= can_frame_bits_exact(...) <= can_frame_bits(s, x, "worst").

CAN FD frames (ISO 11898-1:2015, clause 10.4; the FD base and extended formats), counted field by field:
    arbitration phase, nominal rate:  SOF 1, identifier 11, RRS 1, IDE 1, FDF 1, res 1, BRS 1          = 17 bits
                  (extended format:   SOF 1, base id 11, SRR 1, IDE 1, extension 18, RRS 1, FDF 1, res 1, BRS 1 = 36)
    data phase, data rate:            ESI 1, DLC 4, data 8s, stuff count 4 (3-bit Gray count + parity),
                                      CRC 17 (s <= 16) or 21 (s > 16), fixed stuff bits 6 or 7, CRC delimiter 1
    nominal rate again:               ACK slot 1, ACK delimiter 1, EOF 7, intermission 3                  = 12 bits
Dynamic stuffing covers SOF through the end of the data field (22 + 8s bits, 41 + 8s extended) and, as for classical
frames, inserts at most floor((n - 1) / 4) stuff bits in n bits; at most floor((17 - 1) / 4) = 4 of them (8 of 36
extended) fall before the rate switch. The CRC field is not dynamically stuffed: a fixed stuff bit precedes the stuff
count and one follows every fourth bit of stuff count + CRC, 1 + 5 = 6 bits with CRC-17 (21 bits) and 1 + 6 = 7
with CRC-21 (25 bits). The bit rate switches at the sample point of BRS and back at the sample point of the CRC
delimiter, so those two bits are partly at each rate: the worst case counts both at the nominal rate, the best case
(no dynamic stuff bits) both at the data rate. Without BRS every bit is at the nominal rate. A payload is padded to
the next valid length (0-8, 12, 16, 20, 24, 32, 48, 64 bytes).

Exact CAN FD frames (canfd_frame_bits_exact): the dynamically stuffed region is, base format, SOF 0, identifier,
RRS 0, IDE 0, FDF 1, res 0, BRS, ESI 0 (error active), DLC, data; extended format SOF 0, base identifier, SRR 1,
IDE 1, identifier extension, RRS 0, FDF 1, res 0, BRS, ESI 0, DLC, data. Its stuff bits are counted as on the wire;
those inserted after one of the arbitration bits (SOF .. BRS, fixed by the identifier) are at the nominal rate, the
rest at the data rate. The stuff count and the CRC sequence (CRC-17 or CRC-21 over the stuffed bits) carry fixed
stuff bits only, so their values do not change the length: the frame's length depends on the identifier, BRS and
the data alone. A dynamic stuff bit due right after the last data bit is counted before the fixed stuff bit (at
most one bit more than a controller that lets the fixed stuff bit stand in for it). The sample point of BRS and
of the CRC delimiter is not modelled: both count at the nominal rate, as in the worst case, so exact <= worst holds
at every pair of rates.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache, lru_cache
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:  # numpy is imported by the batch functions only: check, import and build need none of it here
    import numpy as np
    from numpy.typing import NDArray

Stuffing = Literal["worst", "nominal"]
# can_frame_bits sees only a size, so "exact" (which needs the identifier and the data) has its own type and entry
# point, can_frame_bits_of (the simulator's); Stuffing stays as it is so that can_frame_bits cannot be asked for
# what it cannot do.
FrameStuffing = Literal["worst", "nominal", "exact"]

CAN_MAX_PAYLOAD = 8


def can_frame_bits(size: int, extended: bool = False, stuffing: Stuffing = "worst") -> int:
    """Bits on the bus for one classical CAN data frame of `size` bytes, inter-frame space included."""
    g = 54 if extended else 34
    bits = g + 8 * size + 13
    if stuffing == "worst":
        bits += (g + 8 * size - 1) // 4
    return bits


CAN_CRC15_POLY = 0x4599  # x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1, the x^15 term implicit
CAN_FIXED_TAIL_BITS = 13  # CRC delimiter, ACK slot, ACK delimiter, EOF 7, intermission 3: never stuffed
CAN_STUFF_RUN = 5


def can_crc15(bits: Sequence[int]) -> int:
    """CAN CRC-15 over a bit sequence (SOF through the last data bit), register cleared at the start."""
    crc = 0
    for bit in bits:
        feedback = (bit & 1) ^ (crc >> 14)
        crc = (crc << 1) & 0x7FFF
        if feedback:
            crc ^= CAN_CRC15_POLY
    return crc


def _check_frame(can_id: int, extended: bool, size: int) -> None:
    limit = 1 << (29 if extended else 11)
    if not 0 <= can_id < limit:
        raise ValueError(f"CAN identifier {can_id:#x} does not fit {29 if extended else 11} bits")
    if not 0 <= size <= CAN_MAX_PAYLOAD:
        raise ValueError(f"a classical CAN frame carries 0..{CAN_MAX_PAYLOAD} data bytes, not {size}")


def _msb_first(value: int, width: int) -> list[int]:
    return [(value >> i) & 1 for i in range(width - 1, -1, -1)]


def _header_bits(can_id: int, extended: bool, dlc: int, rtr: bool) -> list[int]:
    """SOF through DLC: the part of the stuffed region that depends on neither data nor CRC."""
    if extended:
        return [
            0,  # SOF
            *_msb_first(can_id >> 18, 11),  # base identifier
            1,  # SRR, recessive
            1,  # IDE, recessive: extended format
            *_msb_first(can_id & 0x3FFFF, 18),  # identifier extension
            int(rtr),
            0,  # r1
            0,  # r0
            *_msb_first(dlc, 4),
        ]
    return [0, *_msb_first(can_id, 11), int(rtr), 0, 0, *_msb_first(dlc, 4)]  # SOF, id, RTR, IDE, r0, DLC


def can_frame_fields(can_id: int, extended: bool, data: bytes, rtr: bool = False) -> list[int]:
    """The unstuffed bits of a classical CAN frame from SOF through the CRC sequence (the stuffed region).

    With rtr=True the frame is a remote frame: RTR recessive, DLC = len(data) (the length asked for) and no data
    field on the bus.
    """
    _check_frame(can_id, extended, len(data))
    bits = _header_bits(can_id, extended, len(data), rtr)
    if not rtr:
        for byte in data:
            bits += _msb_first(byte, 8)
    return bits + _msb_first(can_crc15(bits), 15)


def stuff_bits(bits: Sequence[int]) -> list[int]:
    """The bits as transmitted: a complementary bit after every five equal ones, counting toward the next run."""
    out: list[int] = []
    last, run = -1, 0
    for bit in bits:
        out.append(bit)
        if bit == last:
            run += 1
        else:
            last, run = bit, 1
        if run == CAN_STUFF_RUN:
            last, run = 1 - bit, 1
            out.append(last)
    return out


def count_stuff_bits(bits: Sequence[int]) -> int:
    """How many stuff bits stuff_bits() would insert."""
    count = 0
    last, run = -1, 0
    for bit in bits:
        if bit == last:
            run += 1
        else:
            last, run = bit, 1
        if run == CAN_STUFF_RUN:
            count += 1
            last, run = 1 - bit, 1
    return count


@lru_cache(maxsize=1 << 16)
def can_frame_bits_exact(can_id: int, extended: bool, data: bytes) -> int:
    """Bits on the bus for one classical CAN data frame with its actual stuff bits, inter-frame space included.

    Memoised: periodic messages often repeat their payload. `data` must be hashable (bytes, not bytearray).
    """
    fields = can_frame_fields(can_id, extended, data)
    return len(fields) + count_stuff_bits(fields) + CAN_FIXED_TAIL_BITS


def can_frame_bits_of(can_id: int, extended: bool, data: bytes, stuffing: FrameStuffing = "exact") -> int:
    """Bits on the bus for one frame under any stuffing assumption; the simulator's single entry point."""
    if stuffing == "exact":
        return can_frame_bits_exact(can_id, extended, bytes(data))
    _check_frame(can_id, extended, len(data))
    return can_frame_bits(len(data), extended, stuffing)


# Stuffing as a finite-state machine for the vectorised path: state = 4 * last bit + (run length - 1), runs 1..4
# (a fifth equal bit is followed by a stuff bit, which leaves a run of 1 of the other value).
def _stuff_tables() -> tuple[list[int], list[int]]:
    nxt = [0] * 16
    stuffed = [0] * 16
    for state in range(8):
        last, run = state >> 2, (state & 3) + 1
        for bit in (0, 1):
            if bit != last:
                new_last, new_run, stuff = bit, 1, 0
            elif run + 1 == CAN_STUFF_RUN:
                new_last, new_run, stuff = 1 - bit, 1, 1
            else:
                new_last, new_run, stuff = bit, run + 1, 0
            nxt[2 * state + bit] = 4 * new_last + new_run - 1
            stuffed[2 * state + bit] = stuff
    return nxt, stuffed


_STUFF_NEXT, _STUFF_COUNT = _stuff_tables()


@cache
def _stuff_arrays() -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """The stuffing tables as arrays, for indexing with a whole column of states at once."""
    import numpy as np

    return np.array(_STUFF_NEXT, dtype=np.uint8), np.array(_STUFF_COUNT, dtype=np.uint8)


def _stuff_state(bits: Sequence[int]) -> tuple[int, int]:
    """(state, stuff bits so far) after a prefix; the prefix starts with SOF, so there is always a last bit."""
    state, count = 0, 0
    for i, bit in enumerate(bits):
        if i == 0:
            state = 4 * bit
            continue
        k = 2 * state + bit
        count += _STUFF_COUNT[k]
        state = _STUFF_NEXT[k]
    return state, count


@lru_cache(maxsize=CAN_MAX_PAYLOAD + 1)
def _crc_matrix(size: int) -> NDArray[np.float32]:
    """Row j: the CRC-15 bits (MSB first) of a data field whose only 1 is bit j.

    The CRC is linear over GF(2) and starts from 0, so leading zeros change nothing and
    crc(header + data) = crc(header + zeros) ^ crc(data): one matrix product gives every row's data term.
    float32 keeps the product on BLAS and is exact here (sums of at most 64 ones).
    """
    import numpy as np

    nbits = 8 * size
    rows = np.zeros((nbits, 15), dtype=np.float32)
    for j in range(nbits):
        unit = [0] * nbits
        unit[j] = 1
        rows[j] = _msb_first(can_crc15(unit), 15)
    return rows


def can_frame_bits_exact_batch(can_id: int, extended: bool, payloads: NDArray[np.uint8]) -> NDArray[np.int64]:
    """can_frame_bits_exact for n payloads of one identifier at once: payloads (n, size) uint8 -> (n,) int64.

    The header's bits and stuffing state are the same for every row and are computed once; data, CRC and the
    stuffing scan run column by column over all rows (bit arrays of shape (n, nbits)).
    """
    import numpy as np

    stuff_next, stuff_count = _stuff_arrays()
    payloads = np.asarray(payloads)
    if payloads.ndim != 2 or payloads.dtype != np.uint8:
        raise ValueError(f"payloads must be a 2-D uint8 array (n, size), got {payloads.dtype} {payloads.shape}")
    n, size = payloads.shape
    _check_frame(can_id, extended, size)
    header = _header_bits(can_id, extended, size, False)
    fixed = len(header) + 8 * size + 15 + CAN_FIXED_TAIL_BITS
    state0, count0 = _stuff_state(header)
    header_crc = np.array(_msb_first(can_crc15(header + [0] * (8 * size)), 15), dtype=np.uint8)

    data_bits = np.unpackbits(payloads, axis=1)  # MSB first, as on the bus
    crc_bits = (data_bits.astype(np.float32) @ _crc_matrix(size)).astype(np.uint8) & 1
    crc_bits ^= header_crc
    tail = np.ascontiguousarray(np.concatenate([data_bits, crc_bits], axis=1).T)  # one contiguous row per bit

    state = np.full(n, state0, dtype=np.uint8)
    count = np.full(n, count0 + fixed, dtype=np.int64)
    for bits in tail:
        k = 2 * state + bits
        count += stuff_count[k]
        state = stuff_next[k]
    return count


def arbitration_key(can_id: int, extended: bool) -> int:
    """Sort key of CAN arbitration, lower wins, bit by bit as on the wire (ISO 11898-1): the 11 base identifier
    bits, then SRR/IDE (a standard frame beats an extended one with the same base identifier), then the 18
    extension bits."""
    if extended:
        return (can_id >> 18) << 19 | 1 << 18 | (can_id & 0x3FFFF)
    return can_id << 19


def bits_to_ns(bits: int, bitrate: int) -> int:
    """Exact when bitrate divides 1e9 (every standard CAN and Ethernet rate); rounded up otherwise."""
    return -(-bits * 1_000_000_000 // bitrate)



CANFD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)  # data bytes of DLC 0..15
CANFD_MAX_PAYLOAD = CANFD_LENGTHS[-1]
CANFD_ARBITRATION_BITS = 17  # SOF .. BRS, base format
CANFD_ARBITRATION_BITS_EXTENDED = 36
CANFD_CONTROL_DATA_BITS = 5  # ESI, DLC: after the switch, before the data
CANFD_STUFF_COUNT_BITS = 4
CANFD_TAIL_BITS = 12  # ACK slot, ACK delimiter, EOF 7, intermission 3


def canfd_padded_size(size: int) -> int:
    """The data length a CAN FD frame carries for a payload of `size` bytes: the next valid DLC length."""
    for length in CANFD_LENGTHS:
        if size <= length:
            if size < 0:
                break
            return length
    raise ValueError(f"a CAN FD frame carries 0..{CANFD_MAX_PAYLOAD} data bytes, not {size}")


def canfd_dlc(size: int) -> int:
    """The DLC code (0..15) of a CAN FD frame carrying a `size`-byte payload (padded as canfd_padded_size)."""
    return CANFD_LENGTHS.index(canfd_padded_size(size))


def canfd_crc_bits(size: int) -> int:
    """CRC sequence length: CRC-17 up to 16 data bytes, CRC-21 above."""
    return 17 if canfd_padded_size(size) <= 16 else 21


@dataclass(frozen=True)
class FdFrameBits:
    """One CAN FD frame as bit times at each rate; `data` is 0 for a frame sent without bit-rate switch."""

    nominal: int
    data: int

    def ns(self, bitrate: int, data_bitrate: int | None = None) -> int:
        """Transmission time: the nominal bits at the arbitration rate, the data-phase bits at the data rate."""
        if not self.data:
            return bits_to_ns(self.nominal, bitrate)
        if data_bitrate is None:
            raise ValueError("a CAN FD frame with bit-rate switch needs the bus's data bit rate")
        return bits_to_ns(self.nominal, bitrate) + bits_to_ns(self.data, data_bitrate)

    @property
    def total(self) -> int:
        """Bits at both rates together: what a bit error can hit."""
        return self.nominal + self.data


def canfd_frame_bits(size: int, extended: bool = False, brs: bool = True, stuffing: Stuffing = "worst") -> FdFrameBits:
    """Bits of one CAN FD data frame of `size` payload bytes at each rate, intermission included (see the module
    docstring for the field count). "worst": every dynamic stuff bit the rule allows, the BRS bit and the CRC
    delimiter at the nominal rate; "nominal": no dynamic stuff bits, those two bits at the data rate."""
    length = canfd_padded_size(size)
    arbitration = CANFD_ARBITRATION_BITS_EXTENDED if extended else CANFD_ARBITRATION_BITS
    crc = canfd_crc_bits(length)
    fixed_stuff = 1 + (CANFD_STUFF_COUNT_BITS + crc) // 4
    data = CANFD_CONTROL_DATA_BITS + 8 * length + CANFD_STUFF_COUNT_BITS + crc + fixed_stuff
    nominal = arbitration + CANFD_TAIL_BITS
    crc_delimiter = 1
    if stuffing == "worst":
        stuffed = arbitration + CANFD_CONTROL_DATA_BITS + 8 * length
        stuff_total = (stuffed - 1) // 4
        stuff_arbitration = (arbitration - 1) // 4
        nominal += stuff_arbitration + crc_delimiter
        data += stuff_total - stuff_arbitration
    else:  # BRS and the CRC delimiter at the data rate
        nominal -= 1
        data += 1 + crc_delimiter
    if not brs:
        return FdFrameBits(nominal + data, 0)
    return FdFrameBits(nominal, data)


def frame_bits(
    size: int, extended: bool = False, fd: bool = False, brs: bool = False, stuffing: Stuffing = "worst"
) -> FdFrameBits:
    """Bits of one CAN data frame of `size` payload bytes at each rate: the one entry point every command that
    times a frame by its size goes through (check, verify, the simulator, tune, the reports). A classical frame
    (fd False) has all its bits at the nominal rate; a CAN FD frame is padded to its DLC length and, with brs,
    has its data phase at the data rate (canfd_frame_bits)."""
    if fd:
        return canfd_frame_bits(size, extended, brs, stuffing)
    return FdFrameBits(can_frame_bits(size, extended, stuffing), 0)


CANFD_PADDING = 0x00  # what pads a payload to its frame length when netcfg sends one (ISO 11898-1 leaves it open)


def _canfd_header_bits(can_id: int, extended: bool, brs: bool, dlc: int) -> list[int]:
    """SOF through DLC of a CAN FD frame (the exact layout is in the module docstring)."""
    if extended:
        arbitration = [0, *_msb_first(can_id >> 18, 11), 1, 1, *_msb_first(can_id & 0x3FFFF, 18), 0, 1, 0, int(brs)]
    else:
        arbitration = [0, *_msb_first(can_id, 11), 0, 0, 1, 0, int(brs)]
    return [*arbitration, 0, *_msb_first(dlc, 4)]  # ESI, DLC


def _canfd_fixed_bits(length: int, extended: bool) -> FdFrameBits:
    """The bits of a CAN FD frame of `length` data bytes besides its dynamic stuff bits, BRS and the CRC delimiter
    counted at the nominal rate (the split of the worst case)."""
    arbitration = CANFD_ARBITRATION_BITS_EXTENDED if extended else CANFD_ARBITRATION_BITS
    crc = canfd_crc_bits(length)
    fixed_stuff = 1 + (CANFD_STUFF_COUNT_BITS + crc) // 4
    data = CANFD_CONTROL_DATA_BITS + 8 * length + CANFD_STUFF_COUNT_BITS + crc + fixed_stuff
    return FdFrameBits(arbitration + 1 + CANFD_TAIL_BITS, data)  # + 1: the CRC delimiter


def _canfd_split(fixed: FdFrameBits, arbitration_stuff: int, total_stuff: int, brs: bool) -> FdFrameBits:
    nominal, data = fixed.nominal + arbitration_stuff, fixed.data + total_stuff - arbitration_stuff
    return FdFrameBits(nominal, data) if brs else FdFrameBits(nominal + data, 0)


def _canfd_check(can_id: int, extended: bool, size: int) -> int:
    limit = 1 << (29 if extended else 11)
    if not 0 <= can_id < limit:
        raise ValueError(f"CAN identifier {can_id:#x} does not fit {29 if extended else 11} bits")
    return canfd_padded_size(size)


@lru_cache(maxsize=1 << 16)
def canfd_frame_bits_exact(can_id: int, extended: bool, data: bytes, brs: bool = True) -> FdFrameBits:
    """Bits of one CAN FD data frame with its actual stuff bits, at each rate, intermission included. A payload
    shorter than a valid length is padded with CANFD_PADDING, as netcfg sends it. Memoised (data must be bytes)."""
    length = _canfd_check(can_id, extended, len(data))
    header = _canfd_header_bits(can_id, extended, brs, CANFD_LENGTHS.index(length))
    bits = list(header)
    for byte in data + bytes([CANFD_PADDING]) * (length - len(data)):
        bits += _msb_first(byte, 8)
    arbitration = CANFD_ARBITRATION_BITS_EXTENDED if extended else CANFD_ARBITRATION_BITS
    return _canfd_split(
        _canfd_fixed_bits(length, extended), count_stuff_bits(bits[:arbitration]), count_stuff_bits(bits), brs
    )


def canfd_frame_bits_exact_batch(
    can_id: int, extended: bool, brs: bool, payloads: NDArray[np.uint8]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """canfd_frame_bits_exact for n payloads of one identifier: payloads (n, size) uint8 -> ((n,) bits at the
    nominal rate, (n,) bits at the data rate), the fields of FdFrameBits row by row."""
    import numpy as np

    stuff_next, stuff_count = _stuff_arrays()
    payloads = np.asarray(payloads)
    if payloads.ndim != 2 or payloads.dtype != np.uint8:
        raise ValueError(f"payloads must be a 2-D uint8 array (n, size), got {payloads.dtype} {payloads.shape}")
    n, size = payloads.shape
    length = _canfd_check(can_id, extended, size)
    if length > size:
        payloads = np.concatenate([payloads, np.full((n, length - size), CANFD_PADDING, dtype=np.uint8)], axis=1)
    header = _canfd_header_bits(can_id, extended, brs, CANFD_LENGTHS.index(length))
    arbitration = CANFD_ARBITRATION_BITS_EXTENDED if extended else CANFD_ARBITRATION_BITS
    arbitration_stuff = count_stuff_bits(header[:arbitration])
    state0, count0 = _stuff_state(header)
    state = np.full(n, state0, dtype=np.uint8)
    count = np.full(n, count0, dtype=np.int64)
    for bits in np.ascontiguousarray(np.unpackbits(payloads, axis=1).T):
        k = 2 * state + bits
        count += stuff_count[k]
        state = stuff_next[k]
    fixed = _canfd_fixed_bits(length, extended)
    if not brs:
        return fixed.nominal + fixed.data + count, np.zeros(n, dtype=np.int64)
    return np.full(n, fixed.nominal + arbitration_stuff, dtype=np.int64), fixed.data + count - arbitration_stuff


# Ethernet II + IPv4 + UDP, bytes on the wire besides the application data.
ETH_PREAMBLE_SFD = 8
ETH_HEADER = 14  # destination, source, EtherType
ETH_FCS = 4
ETH_IPG = 12
ETH_MIN_DATA = 46  # the data field is padded up to 46 bytes
IPV4_HEADER = 20
UDP_HEADER = 8
ETH_OVERHEAD = ETH_PREAMBLE_SFD + ETH_HEADER + ETH_FCS + ETH_IPG  # 38
UDP_OVERHEAD = ETH_OVERHEAD + IPV4_HEADER + UDP_HEADER  # Novhd = 66
MAX_UDP_PAYLOAD = 1500 - IPV4_HEADER - UDP_HEADER  # 1472 without IP fragmentation


# Frames a NIC's or switch port's transmit queue holds, counting the one being sent, when the spec does not say
# (nodes' nic_queue, switches' and ports' queue); the simulator drops a frame that finds its queue full. An
# assumption, not a datasheet figure: small unmanaged switches share a packet memory of a few tens of kilobytes
# among their ports, and 64 frames per port is of that order for minimum-size frames.
QUEUE_FRAMES = 64


def udp_frame_bytes(payload: int) -> int:
    """Bytes on the wire for one UDP datagram of `payload` bytes: Ndata + Novhd + Npad (84..1538)."""
    pad = max(0, ETH_MIN_DATA - (IPV4_HEADER + UDP_HEADER + payload))
    return payload + UDP_OVERHEAD + pad


def udp_frame_ns(payload: int, bitrate: int) -> int:
    return bits_to_ns(8 * udp_frame_bytes(payload), bitrate)


APP_ID_BYTES = 1  # every application datagram starts with the 1-byte message id (seed 001, Table 6.1)


def udp_message_bytes(size: int) -> int:
    """Bytes on the wire for one application message of `size` data bytes: the message id, then the data."""
    return udp_frame_bytes(APP_ID_BYTES + size)


def udp_message_ns(size: int, bitrate: int) -> int:
    """Transmission time of one application message of `size` data bytes (udp_message_bytes) on one link."""
    return bits_to_ns(8 * udp_message_bytes(size), bitrate)
