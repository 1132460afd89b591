"""CANopen device description (EDS) and device configuration (DCF) files, CiA 306 v1.3, for every CANopen bus.

For every node with a device profile: canopen/<node>.eds, the device's object dictionary with its PDO configuration,
heartbeat and SYNC settings as default values, and canopen/<node>.dcf, the same plus a ParameterValue for every
configured entry and a [DeviceComissioning] section. For the SYNC producer or master without a profile:
canopen/<node>.dcf describing a CANopen master whose RPDOs mirror the slave TPDOs it consumes and whose TPDOs mirror
the slave RPDOs it produces. A node on several CANopen buses gets one folder per bus: canopen/<bus>/<node>.*.

The files are rendered from one jinja2 template (templates/canopen_dcf.j2; `dcf` switches the DCF-only parts on)
up to the object lists and sections, which are plain `keyword=value` lines written by dcf_sections
(object_lists_text, section_text): a device's objects that no node configures are written once per profile and
the text is shared by every node with it (126 drives with one vendor EDS write each such section once). The files
are made rather than with canopen.objectdictionary.export_eds: that exporter stamps the current date and time into
[FileInfo] (ModificationDate/Time always, CreationDate/Time for a dictionary built in memory), so two builds differ;
it writes Granularity as a boolean (1, not 8), has no NodeName, NetworkName or CANopenManager in
[DeviceComissioning], and writes names unchecked. The canopen package stays the consumer that checks us: the tests
load every file with import_od.

Choices a reader may wonder about:
- Values not known from the profile (e.g. the measured values of a drive, strings an EDS import drops) get no
  DefaultValue line, as in the vendors' own EDS; CiA 306 makes the keyword optional.
- COB-IDs that follow the pre-defined connection set are written $NODEID+0x... in DefaultValue (CiA 306 4.6.3.2),
  as vendors do, so the EDS stays right after an LSS node-id change; ParameterValue is always absolute.
- DeviceProfile carries no parent names and object types of records/arrays, nor vendor name, bit rates or LSS support;
  CiA 301 names them for the communication area, elsewhere the common start of the sub-entry names is used, and an
  object is an ARRAY when all its sub-entries share one data type (CiA 301 7.4.3), else a RECORD.

This module configures each node's dictionary (a slave's from its device profile, the master's from the PDOs it
mirrors); the dictionary and the CiA 301 objects are netcfg.protocols.canopen.dcf_objects'.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import PurePath
from typing import Any

from netcfg import cia301
from netcfg.devices import WRITABLE, DeviceProfile
from netcfg.model import Bus, Message, Model, Node
from netcfg.protocols.canopen.dcf_objects import (
    ARRAY,
    COMM_SUBS,
    NAMES,
    NODE_RELATIVE,
    RECORD,
    U8,
    U16,
    U32,
    Dictionary,
    Obj,
    PdoKind,
    Var,
    comm_record,
    copy_object,
    fix_sub0,
    map_entries,
    map_record,
    object_var,
    pdo_comment,
    sub_var,
)
from netcfg.protocols.canopen.dcf_sections import (
    MANUFACTURER,
    FileView,
    Identity,
    Known,
    Texts,
    file_view,
    ini_text,
    object_lists_text,
    shared_text,
)
from netcfg.templating import render

__all__ = ["KINDS", "SYNC_PRODUCER", "PdoKind", "emit", "file_names", "ini_text"]

TEMPLATE = "canopen_dcf.j2"
SYNC_PRODUCER = 1 << 30  # 0x1005 bit 30: this node generates SYNC (CiA 301 7.5.2.5)
KINDS: tuple[PdoKind, PdoKind] = ("rpdo", "tpdo")
Cache = dict[tuple[int, int | None, int | None, int | None], "_Base"]


@dataclass
class _Base:
    """A profile's dictionary with the fixes that do not depend on the node, and the sections of its objects: shared
    by every node with this profile (126 drives with one vendor EDS make each section once). A node copies the objects
    it configures before changing them."""

    objects: object  # the profile's objects, kept alive: the cache key holds their id
    od: Dictionary
    dummies: frozenset[int]
    known: Known


def emit(model: Model, report: dict[str, Any]) -> dict[str, bytes]:
    files: dict[str, bytes] = {}
    cache: Cache = {}
    texts: Texts = {}
    pdos = {bus.name: device_pdos(bus) for bus in model.buses.values() if bus.canopen is not None}
    for (bus_name, name), paths in file_names(model).items():
        bus, node = model.buses[bus_name], model.nodes[name]
        if node.device is not None:
            view = _device_view(model, bus, node, node.device, cache, pdos[bus_name].get(name, []), texts)
        else:
            view = _master_view(model, bus, node, texts)
        for ext, path in paths.items():
            files[path] = _render(view, PurePath(path).name, ext == "dcf")
    return files


def file_names(model: Model) -> dict[tuple[str, str], dict[str, str]]:
    """(bus, node) -> {"eds": path, "dcf": path} of the files emit() writes, relative to the output folder: both for
    a node with a device profile, a DCF only for the master or SYNC producer without one. runtime.json names the
    same files from here."""
    out: dict[tuple[str, str], dict[str, str]] = {}
    buses = [b for b in model.buses.values() if b.canopen is not None]
    for bus in buses:
        masters = model.canopen_masters(bus)
        for name in bus.nodes:
            node = model.nodes[name]
            if node.node_id is None:  # resolve refuses this on CANopen; nothing to describe
                continue
            on = sum(1 for b in buses if name in b.nodes)
            folder = "canopen" if on == 1 else f"canopen/{bus.name}"
            if node.device is not None:
                out[(bus.name, name)] = {ext: f"{folder}/{name}.{ext}" for ext in ("eds", "dcf")}
            elif name in masters:
                out[(bus.name, name)] = {"dcf": f"{folder}/{name}.dcf"}
    return out


def _render(view: FileView, file_name: str, dcf: bool) -> bytes:
    text = "".join(s if isinstance(s, str) else s[dcf] for s in view.sections)
    lists = object_lists_text(view.groups)
    return render(TEMPLATE, f=view, file_name=file_name, dcf=dcf, object_lists=lists, sections=text)


# -- slaves with a device profile ----------------------------------------------------------------------------------
def _base(dev: DeviceProfile, cache: Cache) -> _Base:
    key = (id(dev.objects), dev.vendor_id, dev.product_code, dev.revision)
    base = cache.get(key)
    if base is not None:
        return base
    od: Dictionary = {}
    dummies: set[int] = set()
    for (index, sub), e in sorted(dev.objects.items()):
        if index < 0x1000:  # data type definitions; the ones a device maps as dummies go to [DummyUsage]
            if cia301.is_dummy(index, sub):
                dummies.add(index)
            continue
        od.setdefault(index, Obj()).subs[sub] = Var(e.name, e.data_type, e.access, e.pdo_mappable, e.default)
    for (index, sub), offset in NODE_RELATIVE.items():
        var = od[index].subs.get(sub) if index in od else None
        if var is not None and var.default is None:
            var.default, var.relative = offset, True
    _mandatory(od, dev)
    # the objects _device_view may change for one node are copied and rendered per node; the others are shared
    known = {i: (obj, shared_text(i, obj)) for i, obj in od.items() if not cia301.configured_from_bus(i)}
    base = cache[key] = _Base(dev.objects, od, frozenset(dummies), known)
    return base


def device_pdos(bus: Bus) -> dict[str, list[Message]]:
    """node -> the bus's PDOs whose device side it is (the producer of a TPDO, a consumer of an RPDO), in the bus's
    order: one pass over the bus instead of one per node."""
    out: dict[str, list[Message]] = {}
    for m in bus.messages:
        p = m.pdo
        if p is not None:
            for name in [m.producer] if p.kind == "tpdo" else dict.fromkeys(m.consumers):
                out.setdefault(name, []).append(m)
    return out


def _device_view(
    model: Model, bus: Bus, node: Node, dev: DeviceProfile, cache: Cache, pdos: list[Message], texts: Texts
) -> FileView:
    """pdos: the node's PDOs on the bus (device_pdos)."""
    assert bus.canopen is not None and node.node_id is not None
    nid = node.node_id
    base = _base(dev, cache)
    od = {index: copy_object(obj) if cia301.configured_from_bus(index) else obj for index, obj in base.od.items()}
    dummies = set(base.dummies)
    # SYNC (CiA 301 7.5.2.5-7): configure what the device lets the bus write; a const 0x1005 stays as it is
    co = bus.canopen
    sync = co.sync_id | (SYNC_PRODUCER if co.sync_producer == node.name else 0)
    window = co.sync_window_ns // 1000 if co.sync_window_ns is not None else None
    overflow = co.sync_overflow or None
    for index, value in ((0x1005, sync), (0x1006, co.sync_period_ns // 1000), (0x1007, window), (0x1019, overflow)):
        var = od[index].subs.get(0) if index in od else None
        if var is not None and value is not None and var.access in WRITABLE:
            var.configure(value)
    if node.heartbeat_ns is not None:
        object_var(od, 0x1017, NAMES[0x1017], U16, "rw", 0).configure(node.heartbeat_ns // 1_000_000)
    # PDOs: every slot the device has, the configured ones from the spec's messages, the others disabled
    slots: dict[tuple[str, int], Message] = {}
    for m in pdos:
        p = m.pdo
        if p is not None:
            slots.setdefault((p.kind, p.number), m)
            dummies.update(e.index for e in p.entries if cia301.is_dummy(e.index, e.sub))
    comments = [f"netcfg configuration of node {node.name} (node id {nid}) on bus {bus.name}, system {model.system}"]
    comments.append(f"device profile {dev.name} ({PurePath(dev.source).name})")
    counts = {"rpdo": dev.rpdo_count, "tpdo": dev.tpdo_count}
    for kind in KINDS:
        last = max([counts[kind], *(n for k, n in slots if k == kind)])
        for n in range(1, last + 1):
            slot = slots.get((kind, n))
            _device_pdo(od, dev, nid, kind, n, slot)
            if slot is not None:
                comments.append(pdo_comment(kind, n, slot))
    return file_view(
        od, node, bus,
        description=f"{node.name}: {dev.name} on CANopen bus {bus.name} of {model.system}, configured by netcfg",
        identity=Identity(
            dev.product_name or dev.name, dev.vendor_name, dev.vendor_id or 0, dev.product_code or 0, dev.revision or 0
        ),
        master=node.role == "master",
        dummies=dummies,
        comments=comments,
        known=base.known,
        texts=texts,
    )


def _mandatory(od: Dictionary, dev: DeviceProfile) -> None:
    """0x1000, 0x1001 and 0x1018 sub 1 exist in every CANopen device (CiA 301 7.5.2.1/2/23); a profile may omit them."""
    object_var(od, 0x1000, NAMES[0x1000], U32, "ro", None)
    object_var(od, 0x1001, NAMES[0x1001], U8, "ro", 0)
    identity = od.setdefault(0x1018, Obj())
    # the vendor's identity is what a master checks before configuring the drive (CiA 301 7.5.2.23): keep it
    stated = (
        (1, "Vendor-ID", dev.vendor_id),
        (2, "Product code", dev.product_code),
        (3, "Revision number", dev.revision),
    )
    for sub, name, value in stated:
        if sub == 3 and sub not in identity.subs and value is None:
            continue  # sub 3 is optional: only where the device has it or its revision is known
        var = identity.subs.setdefault(sub, Var(name, U32, "ro"))
        if var.default is None:
            var.default = value


def _device_pdo(od: Dictionary, dev: DeviceProfile, nid: int, kind: PdoKind, n: int, m: Message | None) -> None:
    """Communication and mapping parameter of one PDO slot of a device (CiA 301 7.5.2.35-38)."""
    comm_index = cia301.pdo_comm_index(kind, n)
    p = m.pdo if m is not None else None
    tpdo = kind == "tpdo"
    comm = od.get(comm_index)
    if comm is None:  # the profile lacks it (e.g. the built-in epos4): build it from CiA 301 and the profile's flags
        comm = od[comm_index] = comm_record(
            kind,
            tpdo and dev.tpdo_inhibit_time,
            tpdo and dev.tpdo_event_timer,
            p is not None and p.sync_start is not None,
        )
    default_id = cia301.default_pdo_cob_id(kind, n, nid)
    if m is None or p is None:
        cob = cia301.pdo_cob_id(kind, default_id or 0, valid=False)
    else:
        cob = cia301.pdo_cob_id(kind, m.id, m.extended)
    relative = default_id is not None and (m is None or (m.id == default_id and not m.extended))
    sub_var(comm, 1, f"COB-ID used by {kind.upper()}", U32).configure(cob, nid if relative else None)
    map_index = cia301.pdo_map_index(kind, n)
    mapping = od.get(map_index)
    if mapping is None:
        mapping = od[map_index] = map_record(dev.max_mapped_objects)
    if p is None:  # unused: disabled, nothing mapped; the other parameters keep the device's defaults
        sub_var(mapping, 0, "Number of mapped application objects in PDO", U8).configure(0)
        for sub in range(1, max(mapping.subs) + 1):
            if sub in mapping.subs:
                mapping.subs[sub].default = 0
        return
    sub_var(comm, 2, "Transmission type", U8).configure(p.transmission)
    if tpdo:
        # the timing analysis assumed the spec's inhibit time and event timer, none when not given: write them all
        for sub, value in ((3, p.inhibit_100us), (5, p.event_timer_ms), (6, p.sync_start)):
            if sub in comm.subs and (value is not None or sub != 6):
                comm.subs[sub].configure(value or 0)
            elif value is not None:  # the spec sets a parameter this profile does not list: keep the setting
                sub_var(comm, sub, COMM_SUBS[sub][0], COMM_SUBS[sub][1]).configure(value)
        fix_sub0(comm)
    map_entries(mapping, [(e.index, e.sub, e.bits) for e in p.entries])


# -- the master ----------------------------------------------------------------------------------------------------
def _master_view(model: Model, bus: Bus, node: Node, texts: Texts) -> FileView:
    assert bus.canopen is not None and node.node_id is not None
    co = bus.canopen
    od: Dictionary = {}
    object_var(od, 0x1000, NAMES[0x1000], U32, "ro", 0)  # 0: no standardised device profile (CiA 301 7.5.2.1)
    object_var(od, 0x1001, NAMES[0x1001], U8, "ro", 0)
    producer = node.name == co.sync_producer
    object_var(od, 0x1005, NAMES[0x1005], U32, "rw", 0).configure(co.sync_id | (SYNC_PRODUCER if producer else 0))
    object_var(od, 0x1006, NAMES[0x1006], U32, "rw", 0).configure(co.sync_period_ns // 1000)
    window = object_var(od, 0x1007, NAMES[0x1007], U32, "rw", 0)  # 0: no window (CiA 301 7.5.2.7)
    if co.sync_window_ns is not None:
        window.configure(co.sync_window_ns // 1000)
    heartbeat = object_var(od, 0x1017, NAMES[0x1017], U16, "rw", 0)
    if node.heartbeat_ns is not None:
        heartbeat.configure(node.heartbeat_ns // 1_000_000)
    # consumer heartbeat times (CiA 301 7.5.2.18): one entry per heartbeat the model makes this node consume, node
    # id in bits 16-23, ms below
    supervised = [
        model.nodes[msg.producer]
        for msg in bus.messages
        if msg.implicit == "heartbeat" and node.name in msg.consumers
    ]
    if supervised:
        consumer = od[0x1016] = Obj(name=NAMES[0x1016], object_type=ARRAY)
        consumer.subs[0] = Var("Highest sub-index supported", U8, "const", default=len(supervised))
        for sub, slave in enumerate(sorted(supervised, key=lambda n: n.node_id or 0), 1):
            assert slave.node_id is not None and slave.heartbeat_timeout_ns is not None
            entry = consumer.subs[sub] = Var(f"Consumer heartbeat time {sub}", U32, "rw", default=0)
            entry.configure(slave.node_id << 16 | slave.heartbeat_timeout_ns // 1_000_000)
    if co.sync_overflow:
        object_var(od, 0x1019, NAMES[0x1019], U8, "rw", 0).configure(co.sync_overflow)
    identity = od[0x1018] = Obj(name=NAMES[0x1018], object_type=RECORD)
    identity.subs[0] = Var("Highest sub-index supported", U8, "ro", default=4)
    for sub, name in enumerate(("Vendor-ID", "Product code", "Revision number", "Serial number"), 1):
        identity.subs[sub] = Var(name, U32, "ro", default=0)  # netcfg's own configuration: no registered vendor
    rx = [m for m in bus.messages if m.pdo and m.pdo.kind == "tpdo" and node.name in m.consumers]
    tx = [m for m in bus.messages if m.pdo and m.pdo.kind == "rpdo" and m.producer == node.name]
    if len(rx) > cia301.MAX_PDOS or len(tx) > cia301.MAX_PDOS:
        raise ValueError(f"master {node.name} on {bus.name} would need more than {cia301.MAX_PDOS} RPDOs or TPDOs")
    comments = [f"netcfg CANopen master {node.name} (node id {node.node_id}) of bus {bus.name}, system {model.system}"]
    comments.append("RPDOs mirror the slave TPDOs it consumes, TPDOs the slave RPDOs it produces")
    next_index = MANUFACTURER.start
    for kind, msgs in zip(KINDS, (rx, tx)):
        for n, m in enumerate(msgs, 1):
            assert m.pdo is not None
            comm_index = cia301.pdo_comm_index(kind, n)
            # a master TPDO is sent by the master's application (its runtime configuration times it): inhibit time
            # and event timer exist, set to 0 (off)
            comm = od[comm_index] = comm_record(kind, kind == "tpdo", kind == "tpdo", False)
            sub_var(comm, 1, "", U32).configure(cia301.pdo_cob_id(kind, m.id, m.extended))
            # RPDO types 252/253 do not exist: a mirrored RTR-only TPDO is received as an event (255)
            synchronous = cia301.sync_every(m.pdo.transmission) is not None
            tt = m.pdo.transmission if kind == "tpdo" or synchronous else 255
            sub_var(comm, 2, "", U8).configure(tt)
            for sub in (3, 5):
                if sub in comm.subs:
                    comm.subs[sub].configure(0)
            mapped = []
            for e in m.pdo.entries:
                if next_index not in MANUFACTURER:
                    raise ValueError(f"master {node.name}: more mapped values than manufacturer objects 0x2000-0x5FFF")
                # received values are written by the bus (rww), sent ones read by it (rwr): CiA 306 4.6.3.2
                access = "rww" if kind == "rpdo" else "rwr"
                object_var(od, next_index, f"{m.name}.{e.name}", e.data_type, access, 0).pdo = True
                mapped.append((next_index, 0, e.bits))
                next_index += 1
            mapping = od[cia301.pdo_map_index(kind, n)] = map_record(len(mapped))
            map_entries(mapping, mapped)
            comments.append(pdo_comment(kind, n, m))
    return file_view(
        od, node, bus,
        description=f"{node.name}: CANopen master of bus {bus.name} of {model.system}, configured by netcfg",
        identity=Identity(f"{node.name} CANopen master"),
        master=True,
        comments=comments,
        texts=texts,
    )
