"""Lely's concise DCF (`canopen/<node>.bin`): the SDO writes that bring a slave from its own defaults to the
configuration in its DCF, as ros2_canopen / Lely's master loads them (what Lely's dcfgen writes per slave).

Format (CiA 302-3's concise DCF, as Lely reads it): UNSIGNED32 number of entries, then per entry index (UNSIGNED16),
sub-index (UNSIGNED8), size in bytes (UNSIGNED32) and the value, all little-endian. The writes follow CiA 301's
order for changing a PDO (7.5.2.35-38): invalidate the COB-ID, set the parameters, clear the mapping count, write
the entries, set the count, validate the COB-ID. Unused PDO slots of the device are invalidated, so that no
traffic the analysis did not see leaves the drive. The values are the DCF's ParameterValues (a test checks that).
"""

from __future__ import annotations

import struct
from typing import Any

from netcfg import cia301
from netcfg.devices import DeviceProfile
from netcfg.model import Bus, Message, Model, Node
from netcfg.protocols.canopen.dcf import KINDS, SYNC_PRODUCER, PdoKind, file_names

Write = tuple[int, int, int, int]  # index, sub-index, size in bytes, value


def emit(model: Model, report: dict[str, Any]) -> dict[str, bytes]:
    files: dict[str, bytes] = {}
    for (bus_name, name), paths in file_names(model).items():
        node = model.nodes[name]
        if node.device is None or node.role == "master" or "dcf" not in paths:
            continue  # a master configures the others; it gets no concise DCF of its own
        writes = slave_writes(model.buses[bus_name], node, node.device)
        files[paths["dcf"].removesuffix(".dcf") + ".bin"] = encode(writes)
    return files


def encode(writes: list[Write]) -> bytes:
    out = [struct.pack("<I", len(writes))]
    for index, sub, size, value in writes:
        out.append(struct.pack("<HBI", index, sub, size) + value.to_bytes(size, "little"))
    return b"".join(out)


def slave_writes(bus: Bus, node: Node, dev: DeviceProfile) -> list[Write]:
    assert bus.canopen is not None and node.node_id is not None
    writes: list[Write] = []
    co = bus.canopen
    sync = co.sync_id | (SYNC_PRODUCER if co.sync_producer == node.name else 0)
    window = co.sync_window_ns // 1000 if co.sync_window_ns is not None else None
    for index, value in ((0x1005, sync), (0x1006, co.sync_period_ns // 1000), (0x1007, window)):
        entry = dev.lookup(index, 0)
        if entry is not None and entry.writable and value is not None:  # as the DCF: what the device lets us write
            writes.append((index, 0, entry.bits // 8, value))
    if node.heartbeat_ns is not None:
        writes.append((0x1017, 0, 2, node.heartbeat_ns // 1_000_000))
    slots: dict[tuple[str, int], Message] = {}
    for m in bus.messages:
        p = m.pdo
        if p is not None and (m.producer == node.name if p.kind == "tpdo" else node.name in m.consumers):
            slots.setdefault((p.kind, p.number), m)
    counts = {"rpdo": dev.rpdo_count, "tpdo": dev.tpdo_count}
    for kind in KINDS:
        last = max([counts[kind], *(n for k, n in slots if k == kind)])
        for n in range(1, last + 1):
            writes += _pdo_writes(dev, node.node_id, kind, n, slots.get((kind, n)))
    return writes


def _pdo_writes(dev: DeviceProfile, nid: int, kind: PdoKind, n: int, m: Message | None) -> list[Write]:
    comm = cia301.pdo_comm_index(kind, n)
    p = m.pdo if m is not None else None
    if m is None or p is None:
        default_id = cia301.default_pdo_cob_id(kind, n, nid) or 0
        return [(comm, 1, 4, cia301.pdo_cob_id(kind, default_id, valid=False))]
    cob = cia301.pdo_cob_id(kind, m.id, m.extended)
    writes: list[Write] = [(comm, 1, 4, cob | cia301.PDO_INVALID), (comm, 2, 1, p.transmission)]
    if kind == "tpdo":
        # the same parameters as the DCF: inhibit time and event timer where the device has them (0 when the spec
        # gives none, as the analysis assumed), SYNC start value only when the spec sets it
        has = {
            3: _has_sub(dev, comm, 3, dev.tpdo_inhibit_time),
            5: _has_sub(dev, comm, 5, dev.tpdo_event_timer),
        }
        for sub, size, value in ((3, 2, p.inhibit_100us), (5, 2, p.event_timer_ms), (6, 1, p.sync_start)):
            if (sub != 6 and (has[sub] or value is not None)) or (sub == 6 and value is not None):
                writes.append((comm, sub, size, value or 0))
    mapping = cia301.pdo_map_index(kind, n)
    writes.append((mapping, 0, 1, 0))
    for k, e in enumerate(p.entries, start=1):
        writes.append((mapping, k, 4, e.index << 16 | e.sub << 8 | e.bits))
    writes += [(mapping, 0, 1, len(p.entries)), (comm, 1, 4, cob)]
    return writes


def _has_sub(dev: DeviceProfile, index: int, sub: int, flag: bool) -> bool:
    """Whether the device's PDO parameter has this sub-index: from its dictionary when it lists the object, else
    from the profile's flag (the built-in profiles describe the PDO parameters by flags)."""
    return dev.lookup(index, sub) is not None if dev.has_index(index) else flag
