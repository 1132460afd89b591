"""Frame lengths and transmission times.

Classical CAN (Davis, Burns, Bril, Lukkien 2007, "Controller Area Network (CAN) schedulability analysis:
refuted, revisited and revised", Real-Time Systems 35, eq. 1): a frame of s data bytes takes, with the worst
case of bit stuffing and including the 3-bit inter-frame space,
    C = (g + 8s + 13 + floor((g + 8s - 1) / 4)) bit times,   g = 34 (11-bit ids) or 54 (29-bit ids)
which is 55 + 10s bits (standard) and 80 + 10s bits (extended). Without stuffing: g + 8s + 13 = 47 + 8s / 67 + 8s.

Switched Ethernet (seed 001, eq. 6.4): Tframe = (Ndata + Novhd + Npad) * 8 * Tbit, with the 84-byte minimum
on the wire (preamble 7, SFD 1, addresses 12, EtherType 2, data >= 46, FCS 4, inter-packet gap 12).
"""

from __future__ import annotations

from typing import Literal

Stuffing = Literal["worst", "nominal"]

CAN_MAX_PAYLOAD = 8


def can_frame_bits(size: int, extended: bool = False, stuffing: Stuffing = "worst") -> int:
    """Bits on the bus for one classical CAN data frame of `size` bytes, inter-frame space included."""
    g = 54 if extended else 34
    bits = g + 8 * size + 13
    if stuffing == "worst":
        bits += (g + 8 * size - 1) // 4
    return bits


def bit_time_ns(bitrate: int) -> float:
    return 1e9 / bitrate


def bits_to_ns(bits: int, bitrate: int) -> int:
    """Exact when bitrate divides 1e9 (every standard CAN and Ethernet rate); rounded up otherwise."""
    return -(-bits * 1_000_000_000 // bitrate)


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


def udp_frame_bytes(payload: int) -> int:
    """Bytes on the wire for one UDP datagram of `payload` bytes: Ndata + Novhd + Npad (84..1538)."""
    pad = max(0, ETH_MIN_DATA - (IPV4_HEADER + UDP_HEADER + payload))
    return payload + UDP_OVERHEAD + pad


def udp_frame_ns(payload: int, bitrate: int) -> int:
    return bits_to_ns(8 * udp_frame_bytes(payload), bitrate)
