"""CANopen device description (EDS) and device configuration (DCF) files, CiA 306 v1.3, for every CANopen bus.

For every node with a device profile: canopen/<node>.eds, the device's object dictionary with its PDO configuration,
heartbeat and SYNC settings as default values, and canopen/<node>.dcf, the same plus a ParameterValue for every
configured entry and a [DeviceComissioning] section. For the SYNC producer or master without a profile:
canopen/<node>.dcf describing a CANopen master whose RPDOs mirror the slave TPDOs it consumes and whose TPDOs mirror
the slave RPDOs it produces. A node on several CANopen buses gets one folder per bus: canopen/<bus>/<node>.*.

The files are rendered from one jinja2 template (templates/canopen_dcf.j2; `dcf` switches the DCF-only parts on)
up to the object lists and sections, which are plain `keyword=value` lines written here (object_lists_text,
section_text): a device's objects that no node configures are written once per profile and the text is shared by
every node with it (126 drives with one vendor EDS write each such section once). The files are made rather than
with canopen.objectdictionary.export_eds: that exporter stamps the current date and time into [FileInfo]
(ModificationDate/Time always, CreationDate/Time for a dictionary built in memory), so two builds differ; it writes
Granularity as a boolean (1, not 8), has no NodeName, NetworkName or CANopenManager in [DeviceComissioning], and
writes names unchecked. The canopen package stays the consumer that checks us: the tests load every file with
import_od.

Choices a reader may wonder about:
- Values not known from the profile (e.g. the measured values of a drive, strings an EDS import drops) get no
  DefaultValue line, as in the vendors' own EDS; CiA 306 makes the keyword optional.
- COB-IDs that follow the pre-defined connection set are written $NODEID+0x... in DefaultValue (CiA 306 4.6.3.2),
  as vendors do, so the EDS stays right after an LSS node-id change; ParameterValue is always absolute.
- DeviceProfile carries no parent names and object types of records/arrays, nor vendor name, bit rates or LSS support;
  CiA 301 names them for the communication area, elsewhere the common start of the sub-entry names is used, and an
  object is an ARRAY when all its sub-entries share one data type (CiA 301 7.4.3), else a RECORD.
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import PurePath
from typing import Any, Literal

from netcfg import cia301
from netcfg.devices import DATA_TYPES, WRITABLE, DeviceProfile
from netcfg.model import Bus, Message, Model, Node
from netcfg.templating import render

TEMPLATE = "canopen_dcf.j2"

U8, U16, U32 = 0x05, 0x06, 0x07  # CiA 301 table 44 data type codes
VAR, ARRAY, RECORD = 0x7, 0x8, 0x9  # CiA 301 table 42 object codes
SYNC_PRODUCER = 1 << 30  # 0x1005 bit 30: this node generates SYNC (CiA 301 7.5.2.5)
MANDATORY = (0x1000, 0x1001, 0x1018)  # CiA 306 4.6.2: the mandatory objects of every device
MANUFACTURER = range(0x2000, 0x6000)  # CiA 301 table 43: manufacturer-specific profile area
STANDARD_RATES = (10, 20, 50, 125, 250, 500, 800, 1000)  # kbit/s with a BaudRate_ keyword (CiA 306 4.6.1)
PdoKind = Literal["rpdo", "tpdo"]
_RPDO_COMM, _TPDO_COMM = cia301.pdo_comm_indices("rpdo"), cia301.pdo_comm_indices("tpdo")
KINDS: tuple[PdoKind, PdoKind] = ("rpdo", "tpdo")

# CiA 301 v4.2 7.5.2: names of the communication-area objects netcfg may have to name or create itself
NAMES = {
    0x1000: "Device type",
    0x1001: "Error register",
    0x1003: "Pre-defined error field",
    0x1005: "COB-ID SYNC",
    0x1006: "Communication cycle period",
    0x1007: "Synchronous window length",
    0x1010: "Store parameters",
    0x1011: "Restore default parameters",
    0x1014: "COB-ID EMCY",
    0x1016: "Consumer heartbeat time",
    0x1017: "Producer heartbeat time",
    0x1018: "Identity object",
    0x1019: "Synchronous counter overflow value",
    0x1029: "Error behavior object",
}
# CiA 301 7.5.2: default values relative to the node id, which an EDS import through canopen loses ($NODEID+...)
NODE_RELATIVE = {(0x1014, 0): cia301.EMCY_BASE, (0x1200, 1): cia301.SDO_RX_BASE, (0x1200, 2): cia301.SDO_TX_BASE}


# -- the view the template renders: plain, formatted, sanitised ---------------------------------------------------
@dataclass(frozen=True)
class Section:
    """One [XXXX] or [XXXXsubN] section: a variable, or the head of a record or array (sub_number set)."""

    section: str  # "6064", "1A00", "1A00sub1"
    name: str
    object_type: str
    sub_number: int | None = None  # heads only
    data_type: str = ""  # variables only, from here on
    access: str = ""
    pdo: int = 0
    default: str | None = None
    value: str | None = None  # ParameterValue, DCF only


@dataclass(frozen=True)
class Commissioning:
    node_id: int
    node_name: str
    baudrate: int  # kbit/s (CiA 306 4.7.1)
    network_name: str
    manager: int


@dataclass(frozen=True)
class FileView:
    description: str
    vendor_name: str
    vendor_number: str
    product_name: str
    product_number: str
    revision_number: str
    baudrates: tuple[tuple[int, int], ...]
    boot_master: int
    boot_slave: int
    nr_rx: int
    nr_tx: int
    lss: int
    dummies: tuple[tuple[int, int], ...]
    comments: tuple[str, ...]
    groups: tuple[tuple[str, tuple[str, ...]], ...]  # the three object lists of CiA 306 4.6.2: name, indices
    sections: tuple[str | tuple[str, str], ...]  # every object's sections as text, by index: (EDS, DCF) or shared
    commissioning: Commissioning


# -- a node's object dictionary while it is being configured -------------------------------------------------------
@dataclass
class _Var:
    name: str
    data_type: int
    access: str
    pdo: bool = False
    default: int | None = None
    relative: bool = False  # default is an offset to the node id ($NODEID+default)
    value: int | None = None  # ParameterValue: written by the configuration tool

    def configure(self, value: int, node_id: int | None = None) -> None:
        """`value` becomes the default (EDS) and, where the object is writable, the DCF's ParameterValue; with
        node_id, the default is written relative to it."""
        self.default = value if node_id is None else value - node_id
        self.relative = node_id is not None
        if self.access in WRITABLE:
            self.value = value


@dataclass
class _Obj:
    subs: dict[int, _Var] = field(default_factory=dict)
    name: str | None = None
    object_type: int | None = None  # None: decided from the entries (see module docstring)


Dictionary = dict[int, _Obj]
Known = dict[int, tuple[_Obj, str]]  # objects whose sections are written already (the same in EDS and DCF)
# a configured object's contents -> its sections in the EDS and in the DCF: most come out the same for every node
# (the SYNC objects, PDO mappings, $NODEID-relative defaults), so 126 drives write each once
Texts = dict[tuple[object, ...], tuple[str, str]]
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


def _copy(obj: _Obj) -> _Obj:
    # the constructor, not dataclasses.replace: a third of the time, for 134 entries per drive
    subs = {k: _Var(v.name, v.data_type, v.access, v.pdo, v.default, v.relative, v.value) for k, v in obj.subs.items()}
    return _Obj(subs, obj.name, obj.object_type)


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


@lru_cache(maxsize=64)
def object_lists_text(groups: tuple[tuple[str, tuple[str, ...]], ...]) -> str:
    """[MandatoryObjects], [OptionalObjects], [ManufacturerObjects] (CiA 306 4.6.2), each followed by a blank line:
    the same for every node with one profile, so written once for them all."""
    parts = []
    for group, indices in groups:
        parts.append(f"[{group}]\nSupportedObjects={len(indices)}\n")
        parts.extend(f"{k}={index}\n" for k, index in enumerate(indices, 1))
        parts.append("\n")
    return "".join(parts)


def section_text(s: Section, dcf: bool) -> str:
    """One object section (CiA 306 4.6.3): the keywords in the order of the standard's examples, then a blank line."""
    lines = [f"[{s.section}]", f"ParameterName={s.name}", f"ObjectType={s.object_type}"]
    if s.sub_number is not None:
        lines.append(f"SubNumber={s.sub_number}")
    else:
        lines += [f"DataType={s.data_type}", f"AccessType={s.access}"]
        if s.default is not None:
            lines.append(f"DefaultValue={s.default}")
        lines.append(f"PDOMapping={s.pdo}")
        if dcf and s.value is not None:
            lines.append(f"ParameterValue={s.value}")
    return "\n".join(lines) + "\n\n"


def _shared_text(index: int, obj: _Obj) -> str:
    """The sections of an object no node configures: nothing in them is a ParameterValue, so EDS and DCF agree."""
    sections = _sections(index, obj)
    assert all(s.value is None for s in sections), f"0x{index:04X} has a configured value"
    return "".join(section_text(s, dcf=True) for s in sections)


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
        od.setdefault(index, _Obj()).subs[sub] = _Var(e.name, e.data_type, e.access, e.pdo_mappable, e.default)
    for (index, sub), offset in NODE_RELATIVE.items():
        var = od[index].subs.get(sub) if index in od else None
        if var is not None and var.default is None:
            var.default, var.relative = offset, True
    _mandatory(od, dev)
    # the objects _device_view may change for one node are copied and rendered per node; the others are shared
    known = {i: (obj, _shared_text(i, obj)) for i, obj in od.items() if not cia301.configured_from_bus(i)}
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
    od = {index: _copy(obj) if cia301.configured_from_bus(index) else obj for index, obj in base.od.items()}
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
        _var(od, 0x1017, NAMES[0x1017], U16, "rw", 0).configure(node.heartbeat_ns // 1_000_000)
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
                comments.append(_pdo_comment(kind, n, slot))
    return _file_view(
        od,
        node=node,
        bus=bus,
        description=f"{node.name}: {dev.name} on CANopen bus {bus.name} of {model.system}, configured by netcfg",
        vendor_name=dev.vendor_name,
        vendor_number=dev.vendor_id or 0,
        product_name=dev.product_name or dev.name,
        product_number=dev.product_code or 0,
        revision_number=dev.revision or 0,
        master=node.role == "master",
        dummies=dummies,
        comments=comments,
        known=base.known,
        texts=texts,
    )


def _mandatory(od: Dictionary, dev: DeviceProfile) -> None:
    """0x1000, 0x1001 and 0x1018 sub 1 exist in every CANopen device (CiA 301 7.5.2.1/2/23); a profile may omit them."""
    _var(od, 0x1000, NAMES[0x1000], U32, "ro", None)
    _var(od, 0x1001, NAMES[0x1001], U8, "ro", 0)
    identity = od.setdefault(0x1018, _Obj())
    # the vendor's identity is what a master checks before configuring the drive (CiA 301 7.5.2.23): keep it
    stated = (
        (1, "Vendor-ID", dev.vendor_id),
        (2, "Product code", dev.product_code),
        (3, "Revision number", dev.revision),
    )
    for sub, name, value in stated:
        if sub == 3 and sub not in identity.subs and value is None:
            continue  # sub 3 is optional: only where the device has it or its revision is known
        var = identity.subs.setdefault(sub, _Var(name, U32, "ro"))
        if var.default is None:
            var.default = value


def _device_pdo(od: Dictionary, dev: DeviceProfile, nid: int, kind: PdoKind, n: int, m: Message | None) -> None:
    """Communication and mapping parameter of one PDO slot of a device (CiA 301 7.5.2.35-38)."""
    comm_index = cia301.pdo_comm_index(kind, n)
    p = m.pdo if m is not None else None
    tpdo = kind == "tpdo"
    comm = od.get(comm_index)
    if comm is None:  # the profile lacks it (e.g. the built-in epos4): build it from CiA 301 and the profile's flags
        comm = od[comm_index] = _comm_record(
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
    _sub(comm, 1, f"COB-ID used by {kind.upper()}", U32).configure(cob, nid if relative else None)
    map_index = cia301.pdo_map_index(kind, n)
    mapping = od.get(map_index)
    if mapping is None:
        mapping = od[map_index] = _map_record(dev.max_mapped_objects)
    if p is None:  # unused: disabled, nothing mapped; the other parameters keep the device's defaults
        _sub(mapping, 0, "Number of mapped application objects in PDO", U8).configure(0)
        for sub in range(1, max(mapping.subs) + 1):
            if sub in mapping.subs:
                mapping.subs[sub].default = 0
        return
    _sub(comm, 2, "Transmission type", U8).configure(p.transmission)
    if tpdo:
        # the timing analysis assumed the spec's inhibit time and event timer, none when not given: write them all
        for sub, value in ((3, p.inhibit_100us), (5, p.event_timer_ms), (6, p.sync_start)):
            if sub in comm.subs and (value is not None or sub != 6):
                comm.subs[sub].configure(value or 0)
            elif value is not None:  # the spec sets a parameter this profile does not list: keep the setting
                _sub(comm, sub, _COMM_SUBS[sub][0], _COMM_SUBS[sub][1]).configure(value)
        _fix_sub0(comm)
    _map(mapping, [(e.index, e.sub, e.bits) for e in p.entries])


# -- the master ----------------------------------------------------------------------------------------------------
def _master_view(model: Model, bus: Bus, node: Node, texts: Texts) -> FileView:
    assert bus.canopen is not None and node.node_id is not None
    co = bus.canopen
    od: Dictionary = {}
    _var(od, 0x1000, NAMES[0x1000], U32, "ro", 0)  # 0: no standardised device profile (CiA 301 7.5.2.1)
    _var(od, 0x1001, NAMES[0x1001], U8, "ro", 0)
    producer = node.name == co.sync_producer
    _var(od, 0x1005, NAMES[0x1005], U32, "rw", 0).configure(co.sync_id | (SYNC_PRODUCER if producer else 0))
    _var(od, 0x1006, NAMES[0x1006], U32, "rw", 0).configure(co.sync_period_ns // 1000)
    window = _var(od, 0x1007, NAMES[0x1007], U32, "rw", 0)  # 0: no window (CiA 301 7.5.2.7)
    if co.sync_window_ns is not None:
        window.configure(co.sync_window_ns // 1000)
    heartbeat = _var(od, 0x1017, NAMES[0x1017], U16, "rw", 0)
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
        consumer = od[0x1016] = _Obj(name=NAMES[0x1016], object_type=ARRAY)
        consumer.subs[0] = _Var("Highest sub-index supported", U8, "const", default=len(supervised))
        for sub, slave in enumerate(sorted(supervised, key=lambda n: n.node_id or 0), 1):
            assert slave.node_id is not None and slave.heartbeat_timeout_ns is not None
            entry = consumer.subs[sub] = _Var(f"Consumer heartbeat time {sub}", U32, "rw", default=0)
            entry.configure(slave.node_id << 16 | slave.heartbeat_timeout_ns // 1_000_000)
    if co.sync_overflow:
        _var(od, 0x1019, NAMES[0x1019], U8, "rw", 0).configure(co.sync_overflow)
    identity = od[0x1018] = _Obj(name=NAMES[0x1018], object_type=RECORD)
    identity.subs[0] = _Var("Highest sub-index supported", U8, "ro", default=4)
    for sub, name in enumerate(("Vendor-ID", "Product code", "Revision number", "Serial number"), 1):
        identity.subs[sub] = _Var(name, U32, "ro", default=0)  # netcfg's own configuration: no registered vendor
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
            comm = od[comm_index] = _comm_record(kind, kind == "tpdo", kind == "tpdo", False)
            _sub(comm, 1, "", U32).configure(cia301.pdo_cob_id(kind, m.id, m.extended))
            # RPDO types 252/253 do not exist: a mirrored RTR-only TPDO is received as an event (255)
            synchronous = cia301.sync_every(m.pdo.transmission) is not None
            tt = m.pdo.transmission if kind == "tpdo" or synchronous else 255
            _sub(comm, 2, "", U8).configure(tt)
            for sub in (3, 5):
                if sub in comm.subs:
                    comm.subs[sub].configure(0)
            mapped = []
            for e in m.pdo.entries:
                if next_index not in MANUFACTURER:
                    raise ValueError(f"master {node.name}: more mapped values than manufacturer objects 0x2000-0x5FFF")
                # received values are written by the bus (rww), sent ones read by it (rwr): CiA 306 4.6.3.2
                access = "rww" if kind == "rpdo" else "rwr"
                _var(od, next_index, f"{m.name}.{e.name}", e.data_type, access, 0).pdo = True
                mapped.append((next_index, 0, e.bits))
                next_index += 1
            mapping = od[cia301.pdo_map_index(kind, n)] = _map_record(len(mapped))
            _map(mapping, mapped)
            comments.append(_pdo_comment(kind, n, m))
    return _file_view(
        od,
        node=node,
        bus=bus,
        description=f"{node.name}: CANopen master of bus {bus.name} of {model.system}, configured by netcfg",
        vendor_number=0,
        product_name=f"{node.name} CANopen master",
        product_number=0,
        master=True,
        dummies=set(),
        comments=comments,
        known={},
        texts=texts,
    )


# -- CiA 301 communication objects -----------------------------------------------------------------------------------
# PDO communication parameter sub-entries (CiA 301 7.5.2.35/37): sub -> (name, data type)
_COMM_SUBS = {
    0: ("Highest sub-index supported", U8),
    1: ("COB-ID used by PDO", U32),
    2: ("Transmission type", U8),
    3: ("Inhibit time", U16),
    5: ("Event timer", U16),
    6: ("SYNC start value", U8),
}


def _comm_record(kind: PdoKind, inhibit: bool, timer: bool, sync_start: bool) -> _Obj:
    name = "RPDO" if kind == "rpdo" else "TPDO"
    obj = _Obj(object_type=RECORD)  # named by _standard_name
    subs = [0, 1, 2] + [3] * inhibit + [5] * timer + [6] * sync_start
    for sub in subs:
        sub_name, dtype = _COMM_SUBS[sub]
        obj.subs[sub] = _Var(sub_name.replace("PDO", name), dtype, "const" if sub == 0 else "rw", default=0)
    obj.subs[2].default = 255  # event-driven, manufacturer-specific: the CiA 301 default
    _fix_sub0(obj)
    return obj


def _map_record(count: int) -> _Obj:
    obj = _Obj(object_type=RECORD)  # named by _standard_name
    obj.subs[0] = _Var("Number of mapped application objects in PDO", U8, "rw", default=0)
    for sub in range(1, count + 1):
        obj.subs[sub] = _Var(f"Application object {sub}", U32, "rw", default=0)
    return obj


def _map(mapping: _Obj, entries: list[tuple[int, int, int]]) -> None:
    """sub 0 = number of mapped objects, sub k = the k-th entry (CiA 301 7.5.2.36)."""
    _sub(mapping, 0, "Number of mapped application objects in PDO", U8).configure(len(entries))
    for k, (index, sub, bits) in enumerate(entries, 1):
        _sub(mapping, k, f"Application object {k}", U32).configure(cia301.pack_mapping(index, sub, bits))
    for k in range(len(entries) + 1, max(mapping.subs) + 1):
        if k in mapping.subs:
            mapping.subs[k].default = 0


def _fix_sub0(obj: _Obj) -> None:
    sub0 = obj.subs.get(0)
    if sub0 is not None:
        sub0.default = max(obj.subs)


def _sub(obj: _Obj, sub: int, name: str, data_type: int) -> _Var:
    return obj.subs.setdefault(sub, _Var(name, data_type, "rw", default=0))


def _var(od: Dictionary, index: int, name: str, data_type: int, access: str, default: int | None) -> _Var:
    obj = od.setdefault(index, _Obj())
    return obj.subs.setdefault(0, _Var(name, data_type, access, default=default))


def _pdo_comment(kind: str, n: int, m: Message) -> str:
    assert m.pdo is not None
    entries = ", ".join(f"0x{e.index:04X}:{e.sub} {e.name}" for e in m.pdo.entries)
    return f"{kind.upper()}{n} = {m.name}: COB-ID 0x{m.id:03X}, type {m.pdo.transmission}, {entries}"


# -- from the dictionary to the template's view ------------------------------------------------------------------
def _file_view(
    od: Dictionary,
    *,
    node: Node,
    bus: Bus,
    description: str,
    vendor_number: int,
    product_name: str,
    product_number: int,
    master: bool,
    vendor_name: str = "",
    revision_number: int = 0,
    dummies: set[int],
    comments: list[str],
    known: Known,
    texts: Texts,
) -> FileView:
    assert node.node_id is not None
    kbit = bus.bitrate // 1000
    lists: dict[str, list[str]] = {"MandatoryObjects": [], "OptionalObjects": [], "ManufacturerObjects": []}
    sections: list[str | tuple[str, str]] = []
    for index in sorted(od):
        group = "MandatoryObjects" if index in MANDATORY else "OptionalObjects"
        lists["ManufacturerObjects" if index in MANUFACTURER else group].append(f"0x{index:04X}")
        cached = known.get(index)
        if cached is not None and cached[0] is od[index]:
            sections.append(cached[1])
        else:
            sections.append(_object_texts(index, od[index], texts))
    groups = tuple((name, tuple(indices)) for name, indices in lists.items())
    return FileView(
        description=ini_text(description),
        vendor_name=ini_text(vendor_name),
        vendor_number=f"0x{vendor_number:08X}",
        product_name=ini_text(product_name),
        product_number=f"0x{product_number:08X}",
        revision_number=f"0x{revision_number:08X}",
        # the device's own rates are not in its profile: the one the bus runs at is the one known to work
        baudrates=tuple((rate, int(rate == kbit)) for rate in STANDARD_RATES),
        boot_master=int(master),
        boot_slave=int(not master),
        nr_rx=sum(1 for i in od if i in _RPDO_COMM),
        nr_tx=sum(1 for i in od if i in _TPDO_COMM),
        lss=0,
        dummies=tuple((k, int(k in dummies)) for k in cia301.DUMMY_INDICES),
        comments=tuple(ini_text(line, 255) for line in comments),
        groups=groups,
        sections=tuple(sections),
        commissioning=Commissioning(node.node_id, ini_text(node.name, 246), kbit, ini_text(bus.name, 243), int(master)),
    )


def _object_texts(index: int, obj: _Obj, texts: Texts) -> tuple[str, str]:
    """The object's sections in the EDS and in the DCF, made once per distinct contents."""
    key = (
        index,
        obj.name,
        obj.object_type,
        *((k, v.name, v.data_type, v.access, v.pdo, v.default, v.relative, v.value) for k, v in obj.subs.items()),
    )
    pair = texts.get(key)
    if pair is None:
        sections = _sections(index, obj)
        pair = texts[key] = (
            "".join(section_text(s, False) for s in sections),
            "".join(section_text(s, True) for s in sections),
        )
    return pair


def _sections(index: int, obj: _Obj) -> list[Section]:
    section = f"{index:04X}"
    subs = obj.subs
    if obj.object_type is None and list(subs) == [0]:
        return [_var_section(section, subs[0], _hex(index, 0))]
    if 0 not in subs:  # CiA 301: sub 0 of a record or array holds its highest sub-index
        subs = {0: _Var("Highest sub-index supported", U8, "ro", default=max(subs)), **subs}
    object_type = obj.object_type
    if object_type is None:
        object_type = RECORD if index == 0x1018 or 0x1200 <= index < 0x1C00 else _array_or_record(subs)
    name = (
        obj.name or _standard_name(index) or _common_name(v.name for k, v in subs.items() if k) or f"Object {section}"
    )
    head = Section(section, ini_text(name), f"0x{object_type:X}", sub_number=len(subs))
    return [head, *(_var_section(f"{section}sub{sub:X}", subs[sub], _hex(index, sub)) for sub in sorted(subs))]


def _standard_name(index: int) -> str | None:
    """CiA 301 7.5.2 names of the communication area's objects."""
    for start, end, name in _RANGES:
        if start <= index < end:
            return f"{name[:4]}{index - start + 1}{name[4:]}" if "PDO" in name else name
    return NAMES.get(index)


_RANGES = (
    (0x1200, 0x1280, "SDO server parameter"),
    (0x1280, 0x1300, "SDO client parameter"),
    (cia301.RPDO_COMM, cia301.RPDO_MAP, "RPDO communication parameter"),
    (cia301.RPDO_MAP, cia301.TPDO_COMM, "RPDO mapping parameter"),
    (cia301.TPDO_COMM, cia301.TPDO_MAP, "TPDO communication parameter"),
    (cia301.TPDO_MAP, cia301.PDO_PARAMETERS.stop, "TPDO mapping parameter"),
)


def _array_or_record(subs: dict[int, _Var]) -> int:
    return ARRAY if len({v.data_type for k, v in subs.items() if k}) == 1 else RECORD


def _common_name(names: Iterable[str]) -> str:
    """The words all sub-entry names start with: 'Current actual value' for 'Current actual value (averaged)'."""
    words = [n.split() for n in names]
    common: list[str] = []
    for column in zip(*words):
        if len(set(column)) != 1:
            break
        common.append(column[0])
    return " ".join(common)


def _hex(index: int, sub: int) -> bool:
    """Bit fields are written in hex, as vendors do: device type, COB-IDs, identity, PDO mapping entries. Counts and
    times (0x1006 in us, heartbeat in ms, transmission types...) in decimal."""
    if index in (0x1000, 0x1005, 0x1012, 0x1014) or (index == 0x1018 and sub > 0):
        return True
    if 0x1200 <= index < 0x1300:  # SDO parameters: two COB-IDs
        return sub in (1, 2)
    if index in _RPDO_COMM or index in _TPDO_COMM:
        return sub == 1
    return index in cia301.PDO_PARAMETERS and sub > 0  # the mapping parameters: the rest of 0x1400-0x1BFF


def _var_section(section: str, var: _Var, hex_: bool) -> Section:
    default = _number(var.default, var.data_type, hex_)
    if default is not None and var.relative:
        default = f"$NODEID+{default}"
    value = _number(var.value, var.data_type, hex_)
    dtype = f"0x{var.data_type:04X}"
    return Section(section, ini_text(var.name), "0x7", None, dtype, var.access, int(var.pdo), default, value)


def _number(value: int | None, data_type: int, hex_: bool) -> str | None:
    if value is None:
        return None
    bits = DATA_TYPES.get(data_type, ("", 0, ""))[1]
    if hex_ and value >= 0 and bits:
        return f"0x{value:0{bits // 4}X}"
    return str(value)


_UNSAFE = re.compile(r"[^\x20-\x7E]")


@lru_cache(maxsize=4096)
def ini_text(text: str, limit: int = 241) -> str:
    """A value that cannot break the INI structure: printable ASCII on one line, no section brackets, no ';' (inline
    comments for canopen's parser); accents dropped rather than lost. 241 characters: CiA 306 ParameterName limit."""
    ascii_text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    ascii_text = _UNSAFE.sub(" ", ascii_text).replace("[", "(").replace("]", ")").replace(";", ",")
    return " ".join(ascii_text.split())[:limit].rstrip()
