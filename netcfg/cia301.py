"""CiA 301 as a table: identifiers, object indices, PDO parameter layouts, data types and transmission types.

It imports nothing, so the compiler and the live runtime (netcfg.runtime, which must not load the compiler) both take
the standard's numbers from here instead of writing them again.
"""

from __future__ import annotations

from typing import Literal

# Pre-defined connection set (CiA 301 v4.2, table 73): function code base + node id.
TPDO_BASE = {1: 0x180, 2: 0x280, 3: 0x380, 4: 0x480}
RPDO_BASE = {1: 0x200, 2: 0x300, 3: 0x400, 4: 0x500}
NMT_ID = 0x000
SYNC_ID = 0x080
EMCY_BASE = 0x080
TIME_ID = 0x100
SDO_TX_BASE = 0x580  # server -> client
SDO_RX_BASE = 0x600  # client -> server
HEARTBEAT_BASE = 0x700
NMT_STATE_OPERATIONAL = 0x05  # a heartbeat's one byte, CiA 301 7.2.8.3.2.4 (0x00 boot-up, 0x04 stopped, 0x7F pre-op)
NMT_STATE_PRE_OPERATIONAL = 0x7F
NMT_BOOT_UP = 0x00  # the boot-up message, CiA 301 7.2.8.3.2.1
HEARTBEAT_TIME = 0x1017  # producer heartbeat time in ms (CiA 301 7.5.2.19)
LSS_IDS = (0x7E4, 0x7E5)

# Restricted COB-IDs (CiA 301 v4.2, table 74): never to be used for PDOs, whatever nodes exist.
RESTRICTED = (
    (0x000, 0x000),
    (0x001, 0x07F),
    (0x101, 0x180),
    (0x581, 0x5FF),
    (0x601, 0x67F),
    (0x6E0, 0x6FF),
    (0x701, 0x77F),
    (0x780, 0x7FF),
)


NODE_IDS = range(1, 128)  # CiA 301 7.2.1: node ids 1..127 (0 addresses all nodes in NMT, it is no node's id)

# PDO parameter objects (CiA 301 7.5.2.35-38): one per PDO, up to 512 per direction
RPDO_COMM, RPDO_MAP, TPDO_COMM, TPDO_MAP = 0x1400, 0x1600, 0x1800, 0x1A00
MAX_PDOS = 512
MAP_OFFSET = 0x200  # a PDO's mapping parameter lies this far above its communication parameter
PDO_PARAMETERS = range(RPDO_COMM, TPDO_MAP + MAX_PDOS)  # 0x1400-0x1BFF

# PDO COB-ID (0x14xx/0x18xx sub 1, CiA 301 7.5.2.35/37): flag bits above the CAN identifier
PDO_INVALID = 1 << 31  # the PDO does not exist / is not valid
PDO_NO_RTR = 1 << 30  # no remote transmission request allowed on this PDO
PDO_EXTENDED = 1 << 29  # a 29-bit identifier; bits 0-10 (11-bit) or 0-28 (29-bit) hold it
COB_ID_MASK = (1 << 29) - 1

# Dummy mapping entries: index 0x0001-0x0007 sub 0 maps the data type of that index (BOOLEAN, INTEGER8/16/32,
# UNSIGNED8/16/32, table 44) to fill a PDO's bits with nothing (CiA 301 7.4.7.1). CiA 306 4.6.6 lists exactly these
# seven as Dummy0001-Dummy0007 in an EDS's [DummyUsage], the canopen package reads and writes those seven, and
# maxon's EPOS4 EDS lists all seven (each 0: unsupported). BOOLEAN included: it is a dummy object like the others.
DUMMY_INDICES = range(0x0001, 0x0008)

# Static data types (CiA 301 table 44): code -> (name, size in bits, kind). Strings and domains have no fixed size.
DATA_TYPES: dict[int, tuple[str, int, str]] = {
    0x01: ("BOOLEAN", 1, "unsigned"),
    0x02: ("INTEGER8", 8, "signed"),
    0x03: ("INTEGER16", 16, "signed"),
    0x04: ("INTEGER32", 32, "signed"),
    0x05: ("UNSIGNED8", 8, "unsigned"),
    0x06: ("UNSIGNED16", 16, "unsigned"),
    0x07: ("UNSIGNED32", 32, "unsigned"),
    0x08: ("REAL32", 32, "float"),
    0x09: ("VISIBLE_STRING", 0, "string"),
    0x0A: ("OCTET_STRING", 0, "string"),
    0x0B: ("UNICODE_STRING", 0, "string"),
    0x0C: ("TIME_OF_DAY", 48, "unsigned"),
    0x0D: ("TIME_DIFFERENCE", 48, "unsigned"),
    0x0F: ("DOMAIN", 0, "string"),
    0x10: ("INTEGER24", 24, "signed"),
    0x11: ("REAL64", 64, "float"),
    0x12: ("INTEGER40", 40, "signed"),
    0x13: ("INTEGER48", 48, "signed"),
    0x14: ("INTEGER56", 56, "signed"),
    0x15: ("INTEGER64", 64, "signed"),
    0x16: ("UNSIGNED24", 24, "unsigned"),
    0x18: ("UNSIGNED40", 40, "unsigned"),
    0x19: ("UNSIGNED48", 48, "unsigned"),
    0x1A: ("UNSIGNED56", 56, "unsigned"),
    0x1B: ("UNSIGNED64", 64, "unsigned"),
}


def pdo_comm_index(kind: str, number: int) -> int:
    """Object index of PDO n's communication parameter: RPDO 0x1400 + n - 1, TPDO 0x1800 + n - 1."""
    return (RPDO_COMM if kind == "rpdo" else TPDO_COMM) + number - 1


def pdo_map_index(kind: str, number: int) -> int:
    """Object index of PDO n's mapping parameter: RPDO 0x1600 + n - 1, TPDO 0x1A00 + n - 1."""
    return pdo_comm_index(kind, number) + MAP_OFFSET


def pdo_comm_indices(kind: str) -> range:
    """Every communication parameter index a device may have for this direction (0x1400-0x15FF / 0x1800-0x19FF)."""
    start = pdo_comm_index(kind, 1)
    return range(start, start + MAX_PDOS)


def pdo_cob_id(kind: str, can_id: int, extended: bool = False, valid: bool = True) -> int:
    """The value of a PDO's COB-ID as netcfg writes it, seen from the node whose RPDO/TPDO slot it is: bit 31 set when
    not valid, bit 30 ('no RTR') on TPDOs as the vendors' EDS have it (CiA AN 802 discourages RTR), bit 29 for a
    29-bit identifier. The DCFs, runtime.json and the live master all write this value."""
    flags = PDO_NO_RTR if kind == "tpdo" else 0
    return (0 if valid else PDO_INVALID) | flags | (PDO_EXTENDED if extended else 0) | can_id


def pdo_can_id(cob_id: int) -> tuple[int, bool]:
    """(CAN identifier, extended) of a PDO COB-ID value, flag bits dropped: bits 0-28 for a 29-bit identifier,
    bits 0-10 for an 11-bit one (bits 11-28 are then 0 by CiA 301 and ignored here, as a device does)."""
    extended = bool(cob_id & PDO_EXTENDED)
    return cob_id & (COB_ID_MASK if extended else 0x7FF), extended


def pack_mapping(index: int, sub: int, bits: int) -> int:
    """A PDO mapping entry (0x16xx/0x1Axx sub 1..n, CiA 301 7.5.2.36): index << 16 | sub-index << 8 | length in
    bits."""
    return index << 16 | sub << 8 | bits


def unpack_mapping(value: int) -> tuple[int, int, int]:
    """(index, sub-index, length in bits) of a PDO mapping entry."""
    return (value >> 16) & 0xFFFF, (value >> 8) & 0xFF, value & 0xFF


def is_dummy(index: int, sub: int) -> bool:
    """Whether a mapping entry is a dummy (padding) entry rather than an object."""
    return index in DUMMY_INDICES and sub == 0


def configured_from_bus(index: int) -> bool:
    """Objects netcfg writes from the bus configuration for every node: SYNC (0x1005-0x1007), the heartbeat producer
    time (0x1017) and the PDO parameters (0x1400-0x1BFF). The DCF emitter configures them per node; a bus.yml SDO
    writing one of them would change what the timing analysis proved."""
    return index in (0x1005, 0x1006, 0x1007, 0x1017) or index in PDO_PARAMETERS


def sync_every(transmission: int) -> int | None:
    """Every how many SYNCs a TPDO of this transmission type answers (CiA 301 7.5.2.35, 0x1800 sub 2), or None when
    SYNC does not drive it (types 241-255: RTR-only, event-driven, reserved).

    1..240 -> n: on every n-th SYNC, counted from 1 (the first SYNC after the node became OPERATIONAL is number 1,
    so type n first answers the n-th), as devices and the live master count. 0 (acyclic synchronous) -> 1: it
    answers a SYNC only when its data changed since it last went out, which may be any SYNC, so bounds and
    simulations treat it as answering every SYNC. For RPDOs the same types say whether the received data take effect
    at the next SYNC (not None) or at once."""
    if 1 <= transmission <= 240:
        return transmission
    return 1 if transmission == 0 else None


def tpdo_timing(
    transmission: int,
    sync_ns: int,
    event_timer_ms: int | None,
    inhibit_100us: int | None,
    kind: Literal["periodic", "sporadic", "on-demand"] | None = None,
    period_ns: int | None = None,
    mit_ns: int | None = None,
    jitter_ns: int = 0,
) -> tuple[Literal["periodic", "sporadic", "on-demand"] | None, int | None, int | None]:
    """When a TPDO goes out (0x1800: sub 2 transmission type, sub 3 inhibit time, sub 5 event timer) ->
    (kind, period_ns, minimum inter-arrival ns); kind stays None when nothing but the inhibit time bounds it, and an
    event-timer TPDO that nothing bounds comes back sporadic with no minimum inter-arrival.

    Types 1-240 send on every n-th SYNC, whatever period was given; type 0 (acyclic synchronous) at most once per
    SYNC. Types 254/255 send on every application event, which the spec's period or minimum inter-arrival describes;
    the inhibit time is a floor under the gap between two sends, whatever caused them. The event timer (CiA 301
    7.3.3, 0x1800 sub 5) is one more event, due when the TPDO has been silent that long: it adds sends and never
    bounds them. So with an event timer:
    - application events only outside the steady state (on-demand): the timer alone sends, every event timer;
    - application events every period, which even a late one (period + release jitter) keeps shorter than the event
      timer: the timer, restarted by every send, never runs out, and the period stands;
    - otherwise the timer may run out just before an application event, and only the inhibit time spaces the two:
      sporadic at the inhibit time (the spec's minimum inter-arrival, about the application alone, cannot)."""
    timer_ns = (event_timer_ms or 0) * 1_000_000
    inhibit_ns = (inhibit_100us or 0) * 100_000
    if 1 <= transmission <= 240:
        period_ns, kind = transmission * sync_ns, kind or "periodic"
    elif transmission == 0 and period_ns is None and mit_ns is None:
        mit_ns, kind = sync_ns, kind or "sporadic"
    elif transmission >= 254 and timer_ns:
        if kind == "on-demand":
            return "periodic", timer_ns, None
        if period_ns is not None and kind != "sporadic" and period_ns + jitter_ns < timer_ns:
            return "periodic", period_ns, None
        return "sporadic", None, inhibit_ns or None
    if inhibit_100us and kind != "periodic":
        mit_ns = max(mit_ns or 0, inhibit_ns)
    return kind, period_ns, mit_ns


def default_pdo_cob_id(kind: str, number: int, node_id: int) -> int | None:
    """Default COB-ID of TPDO/RPDO 1-4; PDOs 5-512 have no default and need an explicit id."""
    base = (TPDO_BASE if kind == "tpdo" else RPDO_BASE).get(number)
    return None if base is None else base + node_id


def restricted(cob_id: int) -> bool:
    return any(lo <= cob_id <= hi for lo, hi in RESTRICTED)


def node_services(node_id: int) -> dict[str, int]:
    """Identifiers a CANopen node uses for its services, whatever its PDOs."""
    return {
        "EMCY": EMCY_BASE + node_id,
        "SDO server->client": SDO_TX_BASE + node_id,
        "SDO client->server": SDO_RX_BASE + node_id,
        "heartbeat/NMT error control": HEARTBEAT_BASE + node_id,
    }


# SDO abort codes (CiA 301 v4.2, 7.2.4.3.17, table 22) and their meaning, in the standard's words
SDO_ABORTS = {
    0x05030000: "toggle bit not alternated",
    0x05040000: "SDO protocol timed out",
    0x05040001: "client/server command specifier not valid or unknown",
    0x05040002: "invalid block size (block mode only)",
    0x05040003: "invalid sequence number (block mode only)",
    0x05040004: "CRC error (block mode only)",
    0x05040005: "out of memory",
    0x06010000: "unsupported access to an object",
    0x06010001: "attempt to read a write only object",
    0x06010002: "attempt to write a read only object",
    0x06020000: "object does not exist in the object dictionary",
    0x06040041: "object cannot be mapped to the PDO",
    0x06040042: "the number and length of the objects to be mapped would exceed PDO length",
    0x06040043: "general parameter incompatibility reason",
    0x06040047: "general internal incompatibility in the device",
    0x06060000: "access failed due to a hardware error",
    0x06070010: "data type does not match, length of service parameter does not match",
    0x06070012: "data type does not match, length of service parameter too high",
    0x06070013: "data type does not match, length of service parameter too low",
    0x06090011: "sub-index does not exist",
    0x06090030: "invalid value for parameter (download only)",
    0x06090031: "value of parameter written too high (download only)",
    0x06090032: "value of parameter written too low (download only)",
    0x06090036: "maximum value is less than minimum value",
    0x060A0023: "resource not available: SDO connection",
    0x08000000: "general error",
    0x08000020: "data cannot be transferred or stored to the application",
    0x08000021: "data cannot be transferred or stored to the application because of local control",
    0x08000022: "data cannot be transferred or stored to the application because of the present device state",
    0x08000023: "object dictionary dynamic generation fails or no object dictionary is present",
    0x08000024: "no data available",
}
SDO_TIMED_OUT = 0x05040000  # what a client sends when the server's answer did not come


def sdo_abort_text(code: int) -> str:
    """The standard's meaning of an SDO abort code, or a note that CiA 301 does not define it (a vendor's code)."""
    return SDO_ABORTS.get(code, "not a CiA 301 abort code: see the device manual")
