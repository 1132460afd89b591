"""EtherCAT (IEC 61158 type 12) on 100BASE-TX (or 1 Gbit/s): the master's frames pass through every slave in wire
order and come back, each slave reading and writing its process data on the fly. Frames do not arbitrate and
queue nowhere: a segment's timing is its frames' bytes on the wire and the delays along the line.

The frame on the wire (IEEE 802.3 and ETG.1000.4): preamble and SFD 8 bytes, Ethernet header 14, EtherCAT header 2,
each datagram 10 + its data + its working counter 2, FCS 4, then the inter-frame gap of 12; an Ethernet frame below
64 bytes (header to FCS) is padded to 64. One frame carries at most 1,498 bytes of datagrams (the 1,500-byte
payload less the EtherCAT header): 1,486 bytes of data in one datagram, the figure Beckhoff gives for one frame.
"""

from __future__ import annotations

from netcfg.links.base import Link
from netcfg.timing.ethernet import PROPAGATION_M_PER_S

PREAMBLE_SFD = 8
ETHERNET_HEADER = 14
ECAT_HEADER = 2
DATAGRAM_HEADER = 10
WORKING_COUNTER = 2
FCS = 4
INTER_FRAME_GAP = 12
MIN_ETHERNET_FRAME = 64  # header to FCS (IEEE 802.3): shorter ones are padded
MAX_PAYLOAD = 1500  # the Ethernet payload: the EtherCAT header and its datagrams
MAX_DATAGRAM_DATA = MAX_PAYLOAD - ECAT_HEADER - DATAGRAM_HEADER - WORKING_COUNTER  # 1,486 bytes
BIT_RATES = (100_000_000, 1_000_000_000)  # 100BASE-TX; EtherCAT G at 1 Gbit/s

# What a slave adds to the frame's round trip when the spec gives no forwarding_delay, by the physics of the ports
# its line uses (ETG.2000 Device@Physics: a letter a port, Y 100BASE-TX, H 100BASE-TX with fast hot connect, K E-bus):
# - an RJ45 slave, with a PHY at each port: Beckhoff's EK1101 coupler, technical data, "propagation delay 1 us typ.",
#   once on the way out and once back. It bounds what SOEM's slaveinfo measures on RJ45 slaves (its pdelay, one way,
#   steps of 700-760 ns between neighbours in SOEM issues #288, #487 and #618: 1.40-1.52 us a round trip);
# - an E-bus terminal, without PHYs: the largest step in the DC receive times ethercrab keeps of real lines
#   (src/dc.rs, test propagation_delay_calc_fork: EK1100 -> EK1122 145 ns, EK1122 -> EL9560 and EK1914 -> EL1008
#   155 ns one way), twice.
MII_FORWARDING_NS = 2 * 1_000
EBUS_FORWARDING_NS = 2 * 155
# the port types the defaults know; any other letter on ports 0 and 1 counts as RJ45, the slower (' ': unused)
PHYSICS = {"Y": "100BASE-TX", "H": "100BASE-TX with fast hot connect", "K": "E-bus"}


def default_forwarding_ns(physics: str | None) -> int:
    """A slave's forwarding delay from its ESI's Physics: an E-bus one when ports 0 and 1 (the way in and on) are
    E-bus or unused, an RJ45 one otherwise and without an ESI (a CoE drive is an RJ45 slave)."""
    line = (physics or "")[:2].replace(" ", "")
    return EBUS_FORWARDING_NS if line and set(line) == {"K"} else MII_FORWARDING_NS


def unknown_physics(physics: str) -> list[str]:
    """The letters of ports 0 and 1 (the ones that decide the default) that are no port type netcfg knows."""
    return sorted(set(physics[:2]) - set(PHYSICS) - {" "})


def frame_bytes(datagrams: list[int]) -> int:
    """Bytes one frame of datagrams (their data sizes) occupies on the wire, preamble to inter-frame gap."""
    payload = ECAT_HEADER + sum(DATAGRAM_HEADER + d + WORKING_COUNTER for d in datagrams)
    ethernet = max(ETHERNET_HEADER + payload + FCS, MIN_ETHERNET_FRAME)
    return PREAMBLE_SFD + ethernet + INTER_FRAME_GAP


def wire_ns(nbytes: int, bitrate: int) -> int:
    """The bytes' time on the wire: 80 ns a byte at 100 Mbit/s, 8 ns at 1 Gbit/s."""
    return -(-nbytes * 8 * 1_000_000_000 // bitrate)


def propagation_ns(cable_m: float) -> float:
    """One way along a cable, at the velocity factor the Ethernet analysis takes (timing.ethernet)."""
    return cable_m / PROPAGATION_M_PER_S * 1e9


def split_image(total: int) -> list[int]:
    """The process image's bytes in frames of one datagram each, none above MAX_DATAGRAM_DATA."""
    if total <= 0:
        return [0]
    full, rest = divmod(total, MAX_DATAGRAM_DATA)
    return [MAX_DATAGRAM_DATA] * full + ([rest] if rest else [])


class EtherCat(Link):
    name = "ethercat"
    title = "EtherCAT"
    arbitrates = False  # the base Link's rules (BusRules): EtherCAT asks nothing of a bus beyond them

    def offsets_unused(self) -> str | None:
        return "EtherCAT's process data travels in the master's cyclic frame: it has no release offset of its own"

    def identifiers_fixed(self) -> str | None:
        return "EtherCAT's process data has no identifier: its place in the logical image is its address"


ETHERCAT = EtherCat()
