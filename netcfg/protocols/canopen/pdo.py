"""CANopen PDO maps (CiA 301 0x1600/0x1A00, dummy entries per CiA 306): object references, the mapped objects
checked against every holder's object dictionary, the PDO's communication parameters, and the signals the map
lays out."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Literal

from netcfg import cia301, links, model
from netcfg.devices import DATA_TYPES
from netcfg.runtime.pdos import PdoEntry
from netcfg.spec import schema
from netcfg.spec.source import Path
from netcfg.timing.frames import CAN_MAX_PAYLOAD, CANFD_MAX_PAYLOAD

if TYPE_CHECKING:
    from netcfg.rules import Resolution

_OBJECT_REF = re.compile(r"^\s*(0x[0-9A-Fa-f]{1,4}|[0-9]{1,5})\s*(?:(?::|sub)\s*(0x[0-9A-Fa-f]{1,2}|[0-9]{1,3}))?\s*$")


def snake(text: str) -> str:
    """'Position actual value' -> 'position_actual_value', the signal name of a mapped device object; a name
    check_name refuses gets 'obj_' in front ('1st' -> 'obj_1st') or '_obj' behind ('Switch' -> 'switch_obj')."""
    return schema.safe_name(re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_").lower(), "obj", "_obj")


def parse_object_ref(r: Resolution, ref: int | str, path: Path) -> tuple[int, int] | None:
    if isinstance(ref, bool):
        ref = str(ref)
    if isinstance(ref, int):
        index, sub = ref, 0
    else:
        mm = _OBJECT_REF.match(ref)
        if not mm:
            r.err("object-ref", f"cannot read object {ref!r}; write 0x6064 or '0x30D1:2' (index:sub-index)", path)
            return None
        index = int(mm.group(1), 0)
        sub = int(mm.group(2), 0) if mm.group(2) else 0
    if not (0 <= index <= 0xFFFF and 0 <= sub <= 0xFF):
        r.err(
            "object-ref",
            f"object 0x{index:X}:{sub} is outside the object dictionary (index <= 0xFFFF, sub-index <= 0xFF)",
            path,
        )
        return None
    return index, sub


def max_pdo_bytes(bus: model.Bus) -> int:
    """A PDO's largest payload on the bus: 8 bytes (CiA 301) on classical CAN, 64 (CANopen FD, CiA 1301) on CAN FD,
    the link's largest frame either way."""
    return CANFD_MAX_PAYLOAD if links.of(bus).data_phase else CAN_MAX_PAYLOAD


def resolve_pdo(
    r: Resolution, m: schema.Message, sbus: schema.Bus, bus: model.Bus, path: Path
) -> tuple[model.Pdo, tuple[model.Signal, ...]] | None:
    p = m.pdo
    assert p is not None
    ppath = (*path, "pdo")
    kind: Literal["tpdo", "rpdo"] = "tpdo" if p.tpdo is not None else "rpdo"
    number = p.tpdo if p.tpdo is not None else p.rpdo
    assert number is not None
    if kind == "tpdo":
        holders = [m.producer]
    else:
        holders = list(m.consumers)
        if len(holders) > 1 and m.id is None:
            r.err("id-missing", "an RPDO received by several nodes has no single default COB-ID; give 'id'", ppath)
    device_node = holders[0]
    devices = [(h, r.model.nodes[h].device) for h in holders if h in r.model.nodes]
    for h, dev in devices:
        if dev is None:
            if r.spec_nodes[h].device is not None:
                continue  # it names a device that could not be loaded: reported where it is named
            role = "produces" if kind == "tpdo" else "receives"
            r.err(
                "no-device",
                f"'{h}' {role} this {kind.upper()} but has no device profile to check the map "
                "against; give it 'device: <profile>' or 'device: {eds: file.eds}'",
                ppath,
            )
            continue
        count = dev.tpdo_count if kind == "tpdo" else dev.rpdo_count
        if number > count:
            r.err(
                "pdo-number",
                f"device {dev.name} of '{h}' ({dev.source}) has {count} {kind.upper()}s; {kind.upper()} {number} "
                "does not exist",
                (*ppath, kind),
            )
        if kind == "tpdo" and p.event_timer is not None and not dev.tpdo_event_timer:
            r.err(
                "event-timer",
                f"device {dev.name} has no TPDO event timer (0x18xx sub-index 5); use a SYNC transmission type instead",
                (*ppath, "event_timer"),
            )
        if kind == "tpdo" and p.inhibit is not None and not dev.tpdo_inhibit_time:
            r.err("inhibit", f"device {dev.name} has no TPDO inhibit time (0x18xx sub-index 3)", (*ppath, "inhibit"))
        if len(p.map) > dev.max_mapped_objects:
            r.err(
                "pdo-length",
                f"device {dev.name} maps at most {dev.max_mapped_objects} objects per PDO; this map has {len(p.map)}",
                (*ppath, "map"),
            )
    tt = p.transmission
    if 241 <= tt <= 251:
        r.err(
            "transmission",
            f"transmission type {tt} is reserved (CiA 301); use 0-240, 254 or 255",
            (*ppath, "transmission"),
        )
    elif kind == "rpdo" and tt in (252, 253):
        r.err("transmission", "transmission types 252/253 (RTR) exist only for TPDOs", (*ppath, "transmission"))
    if p.sync_start is not None and (kind != "tpdo" or not 1 <= tt <= 240):
        r.err(
            "sync-start",
            "a SYNC start value (0x18xx sub-index 6) applies to synchronous TPDOs (transmission type 1-240) only",
            (*ppath, "sync_start"),
        )
    inhibit = r.ns(p.inhibit, (*ppath, "inhibit"), None)
    inhibit_100us = None
    if inhibit is not None:
        if kind == "rpdo":
            r.err("inhibit", "inhibit times limit transmitters: set it on TPDOs", (*ppath, "inhibit"))
        if inhibit % 100_000 or inhibit > 65_535 * 100_000:
            r.err("inhibit", "the inhibit time is stored in units of 100 us (at most 6.5535 s)", (*ppath, "inhibit"))
        inhibit_100us = inhibit // 100_000
    timer = r.ns(p.event_timer, (*ppath, "event_timer"), None)
    timer_ms = None
    if timer is not None:
        if timer % 1_000_000 or timer > 65_535 * 1_000_000 or timer == 0:
            r.err("event-timer", "the event timer is whole milliseconds, 1..65535 ms", (*ppath, "event_timer"))
        timer_ms = timer // 1_000_000
        if tt < 254:
            r.warn(
                "event-timer",
                f"the event timer only acts with transmission type 254/255, not {tt}",
                (*ppath, "event_timer"),
            )
    entries: list[PdoEntry] = []
    names: dict[str, int] = {}
    for k, item in enumerate(p.map):
        epath = (*ppath, "map", k)
        ref = item.object if isinstance(item, schema.PdoEntry) else item
        parsed = parse_object_ref(r, ref, epath)
        if parsed is None:
            continue
        index, sub = parsed
        if cia301.is_dummy(index, sub):
            if kind == "tpdo":
                r.err("pdo-dummy", "dummy entries (0x0001-0x0007) only pad RPDOs", epath)
            bits = DATA_TYPES[index][1]
            name = f"pad{k}"
            entries.append(PdoEntry(index, sub, bits, name, index))
            continue
        obj = None
        for h, dev in devices:
            if dev is None:
                continue
            found = dev.lookup(index, sub)
            where = f"device {dev.name} of '{h}' ({dev.source})"
            # the hint scans the whole dictionary: only for an object that is refused
            refused = found is None or not found.pdo_mappable
            has_subs = refused and sub == 0 and any(i == index and k > 0 for i, k in dev.objects)
            hint = f" (it has sub-indices: give '0x{index:04X}:1')" if has_subs else ""
            if found is None:
                r.err("unknown-object", f"object 0x{index:04X}:{sub} does not exist in {where}{hint}", epath)
                continue
            if not found.pdo_mappable:
                r.err(
                    "not-mappable",
                    f"object 0x{index:04X}:{sub} '{found.name}' of {where} is not PDO-mappable{hint}",
                    epath,
                )
            elif kind == "rpdo" and not found.writable:
                r.err(
                    "pdo-direction",
                    f"object 0x{index:04X}:{sub} '{found.name}' of {where} is read-only "
                    f"({found.access}) and cannot be written by an RPDO; map it in a TPDO",
                    epath,
                )
            elif kind == "tpdo" and not found.readable:
                r.err(
                    "pdo-direction",
                    f"object 0x{index:04X}:{sub} '{found.name}' of {where} is write-only "
                    f"({found.access}) and cannot be sent in a TPDO",
                    epath,
                )
            if found.bits == 0:
                r.err("not-mappable", f"object 0x{index:04X}:{sub} has no fixed size ({found.type_name})", epath)
            obj = obj or found
        if obj is None:
            continue
        name = item.name if isinstance(item, schema.PdoEntry) and item.name else snake(obj.name)
        if name in names:
            r.err(
                "duplicate-name",
                f"signal name '{name}' appears twice in this PDO; name one with '{{object: ..., name: ...}}'",
                epath,
            )
        names[name] = k
        entries.append(PdoEntry(index, sub, obj.bits, name, obj.data_type))
    total = sum(e.bits for e in entries)
    limit = 8 * max_pdo_bytes(bus)
    if total > limit:
        frame = "CAN FD frame (CANopen FD, CiA 1301)" if limit > 64 else "CAN frame"
        r.err("pdo-length", f"the PDO map holds {total} bits; a {frame} carries at most {limit}", (*ppath, "map"))
    if not entries and not p.map:
        r.err("pdo-length", "a PDO needs at least one mapped object", (*ppath, "map"))
    if len(entries) != len(p.map):
        return None
    pdo = model.Pdo(
        kind=kind,
        number=number,
        node=device_node,
        transmission=tt,
        inhibit_100us=inhibit_100us,
        event_timer_ms=timer_ms,
        sync_start=p.sync_start,
        entries=tuple(entries),
    )
    signals, start = [], 0
    for e in entries:
        kind_name = DATA_TYPES.get(e.data_type, ("", 0, "unsigned"))[2]
        signals.append(model.Signal(e.name, start, e.bits, kind_name == "signed", kind_name == "float"))
        start += e.bits
    return pdo, tuple(signals)
