"""CiA 301 identifier rules: the pre-defined connection set and the restricted COB-IDs."""

from __future__ import annotations

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


def pdo_comm_index(kind: str, number: int) -> int:
    """Object index of PDO n's communication parameter: RPDO 0x1400 + n - 1, TPDO 0x1800 + n - 1. Its mapping
    parameter is 0x200 above it (0x1600 / 0x1A00)."""
    return (0x1400 if kind == "rpdo" else 0x1800) + number - 1


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
