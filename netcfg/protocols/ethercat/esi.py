"""The EtherCAT Slave Information file (ETG.2000): what a slave's vendor says of it, read with a hardened parser.

ESI files come from vendors' websites, so they are untrusted input: defusedxml refuses DTDs, entity declarations
and external references (no billion laughs, no file or network reads), and the size guard of netcfg.inputs bounds
the file before the parser sees it. Every problem names the file and line (EsiError).

What netcfg reads of a `<Device>`: its identity (vendor id, product code, revision), sync managers, the RxPdo and
TxPdo sets with `Fixed`, `Mandatory`, `Sm` and `Exclude`, their entries, the CoE object dictionary (each
sub-index's bit size, access and PDO mapping flag) and the distributed-clock modes (`<Dc><OpMode>` with
`AssignActivate`, `CycleTimeSync0` and `ShiftTimeSync0`).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

from defusedxml import DefusedXmlException
from defusedxml.ElementTree import DefusedXMLParser

from netcfg.inputs import InputError, read_input_bytes
from netcfg.runtime.pdos import MappedObject

WHAT = "ESI"


class EsiError(ValueError):
    def __init__(self, file: str, line: int | None, message: str) -> None:
        super().__init__(f"{file}:{line}: {message}" if line else f"{file}: {message}")
        self.file, self.line, self.message = file, line, message


@dataclass(frozen=True)
class SyncManager:
    number: int
    kind: str  # MBoxOut, MBoxIn, Outputs, Inputs
    start: int
    default_size: int | None
    control: int
    enable: bool


@dataclass(frozen=True)
class PdoEntry(MappedObject):
    """A PDO's mapped CoE object; its data type by ETG.2000's name (BOOL, INT, UDINT...), not a CiA 301 code."""

    data_type: str
    line: int

    @property
    def padding(self) -> bool:
        return self.index == 0  # a gap in the PDO (ETG.2000: entry index 0)


@dataclass(frozen=True)
class Pdo:
    index: int
    name: str
    direction: str  # "rx": master -> slave (outputs, 0x16xx); "tx": slave -> master (inputs, 0x1Axx)
    sm: int | None
    fixed: bool
    mandatory: bool
    excludes: tuple[int, ...]
    entries: tuple[PdoEntry, ...]
    line: int

    @property
    def bits(self) -> int:
        return sum(e.bits for e in self.entries)


@dataclass(frozen=True)
class OpMode:
    name: str
    description: str
    assign_activate: int
    cycle_time_sync0: int  # ns; 0: the master's cycle
    cycle_factor_sync0: int  # ETG.2000: SYNC0 cycle = factor x the bus cycle when the time is 0
    shift_time_sync0: int  # ns after the DC cycle start


@dataclass(frozen=True)
class OdEntry:
    index: int
    sub: int
    name: str
    bits: int
    access: str  # ro, rw, wo (ETG.2000 Flags/Access)
    pdo_mapping: str  # "R" (RxPDO), "T" (TxPDO), "RT", "" (not mappable)


@dataclass
class EsiDevice:
    file: str
    type_name: str
    name: str
    vendor_id: int
    product_code: int
    revision: int
    line: int
    sync_managers: list[SyncManager] = field(default_factory=list)
    rx_pdos: list[Pdo] = field(default_factory=list)
    tx_pdos: list[Pdo] = field(default_factory=list)
    op_modes: list[OpMode] = field(default_factory=list)
    objects: dict[tuple[int, int], OdEntry] = field(default_factory=dict)
    pdo_assign: bool = False  # <Mailbox><CoE PdoAssign="true">: the master may write 0x1C12/0x1C13
    physics: str = ""  # <Device Physics>: its ports' physical layers, a letter each (Y 100BASE-TX, K E-bus)

    def pdo(self, index: int) -> Pdo | None:
        return next((p for p in (*self.rx_pdos, *self.tx_pdos) if p.index == index), None)


class _LineBuilder(ET.TreeBuilder):
    """A tree builder that keeps each element's line, which ElementTree drops."""

    def __init__(self) -> None:
        super().__init__()
        self.parser: DefusedXMLParser | None = None
        self.lines: dict[int, int] = {}

    def start(self, tag: str, attrs: dict[str, str]) -> ET.Element:
        element = super().start(tag, attrs)
        assert self.parser is not None
        self.lines[id(element)] = self.parser.parser.CurrentLineNumber
        return element


class _Reader:
    def __init__(self, file: str, text: bytes) -> None:
        self.file = file
        builder = _LineBuilder()
        parser = DefusedXMLParser(target=builder, forbid_dtd=True, forbid_entities=True, forbid_external=True)
        builder.parser = parser
        try:
            parser.feed(text)
            self.root = parser.close()
        except ET.ParseError as exc:
            raise EsiError(file, exc.position[0], f"not well-formed XML: {exc}") from exc
        except DefusedXmlException as exc:
            line = parser.parser.CurrentLineNumber
            raise EsiError(file, line, f"refused: {exc} (an ESI file needs no DTD or entities)") from exc
        self.lines = builder.lines
        self.keep = builder  # the ids in `lines` stay valid while the elements live

    def line(self, e: ET.Element) -> int:
        return self.lines.get(id(e), 0)

    def fail(self, e: ET.Element, message: str) -> EsiError:
        return EsiError(self.file, self.line(e), message)

    def number(self, e: ET.Element, text: str | None, what: str) -> int:
        """ETG.2000's HexDecValue: '#x1A00' or decimal."""
        value = (text or "").strip()
        try:
            return int(value[2:], 16) if value[:2].lower() == "#x" else int(value)
        except ValueError:
            raise self.fail(e, f"{what} {value!r} is not a number (decimal, or hex as #x1A00)") from None

    def child_number(self, e: ET.Element, tag: str, what: str, default: int | None = None) -> int:
        child = e.find(tag)
        if child is None:
            if default is not None:
                return default
            raise self.fail(e, f"<{e.tag}> has no <{tag}> ({what})")
        return self.number(child, child.text, what)

    def text(self, e: ET.Element, tag: str) -> str:
        child = e.find(tag)
        return (child.text or "").strip() if child is not None else ""


def _flag(value: str | None) -> bool:
    return (value or "").strip().lower() in ("1", "true")


def read_esi(path: str | os.PathLike[str]) -> list[EsiDevice]:
    """Every device an ESI file describes; EsiError (file:line) for a file netcfg cannot use."""
    file = os.fspath(path)
    try:
        data = read_input_bytes(file, WHAT)
        stat = os.stat(file)
    except InputError as exc:
        raise EsiError(file, None, exc.message) from exc
    return list(_devices(file, stat.st_mtime_ns, data))


@cache
def _devices(file: str, mtime_ns: int, data: bytes) -> tuple[EsiDevice, ...]:
    r = _Reader(file, data)
    if r.root.tag != "EtherCATInfo":
        raise r.fail(r.root, f"the root element is <{r.root.tag}>; an ESI file's is <EtherCATInfo> (ETG.2000)")
    vendor = r.root.find("Vendor")
    if vendor is None:
        raise r.fail(r.root, "no <Vendor> element: the vendor id is unknown")
    vendor_id = r.child_number(vendor, "Id", "the vendor id")
    devices = r.root.findall("Descriptions/Devices/Device")
    if not devices:
        raise r.fail(r.root, "no <Descriptions><Devices><Device>: the file describes no slave")
    return tuple(_device(r, d, vendor_id) for d in devices)


def _device(r: _Reader, d: ET.Element, vendor_id: int) -> EsiDevice:
    kind = d.find("Type")
    if kind is None:
        raise r.fail(d, "<Device> has no <Type> (its product code and revision)")
    dev = EsiDevice(
        file=r.file,
        type_name=(kind.text or "").strip(),
        name=r.text(d, "Name"),
        vendor_id=vendor_id,
        product_code=r.number(kind, kind.get("ProductCode"), "ProductCode"),
        revision=r.number(kind, kind.get("RevisionNo", "0"), "RevisionNo"),
        line=r.line(d),
        physics=d.get("Physics", ""),
    )
    for n, sm in enumerate(d.findall("Sm")):
        size = sm.get("DefaultSize")
        dev.sync_managers.append(
            SyncManager(
                n,
                (sm.text or "").strip(),
                r.number(sm, sm.get("StartAddress", "0"), "StartAddress"),
                None if size is None else r.number(sm, size, "DefaultSize"),
                r.number(sm, sm.get("ControlByte", "0"), "ControlByte"),
                _flag(sm.get("Enable", "1")),
            )
        )
    dev.rx_pdos = [_pdo(r, p, "rx", len(dev.sync_managers)) for p in d.findall("RxPdo")]
    dev.tx_pdos = [_pdo(r, p, "tx", len(dev.sync_managers)) for p in d.findall("TxPdo")]
    seen: dict[int, Pdo] = {}
    for p in (*dev.rx_pdos, *dev.tx_pdos):
        if p.index in seen:
            raise EsiError(
                r.file, p.line, f"PDO 0x{p.index:04X} is described twice (first at line {seen[p.index].line})"
            )
        seen[p.index] = p
    for p in seen.values():
        for x in p.excludes:
            if x not in seen:
                raise EsiError(
                    r.file, p.line, f"PDO 0x{p.index:04X} excludes 0x{x:04X}, which the device does not have"
                )
    for mode in d.findall("Dc/OpMode"):
        cycle = mode.find("CycleTimeSync0")
        dev.op_modes.append(
            OpMode(
                r.text(mode, "Name"),
                r.text(mode, "Desc"),
                r.child_number(mode, "AssignActivate", "AssignActivate (register 0x0980)"),
                r.child_number(mode, "CycleTimeSync0", "CycleTimeSync0", 0),
                r.number(cycle, cycle.get("Factor", "1"), "Factor") if cycle is not None else 1,
                r.child_number(mode, "ShiftTimeSync0", "ShiftTimeSync0", 0),
            )
        )
    dev.objects = _dictionary(r, d)
    coe = d.find("Mailbox/CoE")
    dev.pdo_assign = coe is not None and _flag(coe.get("PdoAssign"))
    return dev


def _pdo(r: _Reader, p: ET.Element, direction: str, sms: int) -> Pdo:
    index_el = p.find("Index")
    if index_el is None:
        raise r.fail(p, f"<{p.tag}> has no <Index>")
    index = r.number(index_el, index_el.text, "PDO index")
    lo, hi = (0x1600, 0x17FF) if direction == "rx" else (0x1A00, 0x1BFF)
    if not lo <= index <= hi:
        raise r.fail(index_el, f"{p.tag} index 0x{index:04X} is outside 0x{lo:04X}..0x{hi:04X} (ETG.1000.6)")
    sm_text = p.get("Sm")
    sm = None if sm_text is None else r.number(p, sm_text, "Sm")
    if sm is not None and sm >= max(sms, 1):
        raise r.fail(p, f"PDO 0x{index:04X} belongs to sync manager {sm}, but the device has {sms}")
    entries = []
    for e in p.findall("Entry"):
        entries.append(
            PdoEntry(
                r.child_number(e, "Index", "entry index"),
                r.child_number(e, "SubIndex", "entry sub-index", 0),
                r.child_number(e, "BitLen", "entry bit length"),
                r.text(e, "Name"),
                r.text(e, "DataType"),
                r.line(e),
            )
        )
    excludes = tuple(r.number(x, x.text, "Exclude") for x in p.findall("Exclude"))
    return Pdo(
        index,
        r.text(p, "Name"),
        direction,
        sm,
        _flag(p.get("Fixed")),
        _flag(p.get("Mandatory")),
        excludes,
        tuple(entries),
        r.line(p),
    )


def _dictionary(r: _Reader, d: ET.Element) -> dict[tuple[int, int], OdEntry]:
    """Each sub-index of the CoE dictionary: an object of a plain type is sub-index 0; one of a structured type
    (a <DataType> with <SubItem>s) has the sub-indices its type lists, an array's from its <ArrayInfo>."""
    types = {r.text(t, "Name"): t for t in d.findall("Profile/Dictionary/DataTypes/DataType")}
    out: dict[tuple[int, int], OdEntry] = {}
    for obj in d.findall("Profile/Dictionary/Objects/Object"):
        index = r.child_number(obj, "Index", "object index")
        name, type_name = r.text(obj, "Name"), r.text(obj, "Type")
        access, mapping = r.text(obj, "Flags/Access"), r.text(obj, "Flags/PdoMapping")
        dt = types.get(type_name)
        items = dt.findall("SubItem") if dt is not None else []
        if not items:
            bits = r.child_number(obj, "BitSize", "object bit size", 0)
            out[(index, 0)] = OdEntry(index, 0, name, bits, access, mapping.upper())
            continue
        for item in items:
            item_type = types.get(r.text(item, "Type"))
            sub_access = r.text(item, "Flags/Access") or access
            sub_mapping = (r.text(item, "Flags/PdoMapping") or mapping).upper()
            if item.find("SubIdx") is None and item_type is not None and item_type.find("ArrayInfo") is not None:
                lbound = r.child_number(item_type, "ArrayInfo/LBound", "array lower bound", 1)
                count = r.child_number(item_type, "ArrayInfo/Elements", "array elements", 0)
                base = types.get(r.text(item_type, "BaseType"))
                element_bits = (
                    r.child_number(item_type, "BitSize", "array bit size", 0) // max(count, 1)
                    if base is None
                    else r.child_number(base, "BitSize", "bit size", 0)
                )
                for sub in range(lbound, lbound + count):
                    out[(index, sub)] = OdEntry(index, sub, f"{name} {sub}", element_bits, sub_access, sub_mapping)
                continue
            sub = r.child_number(item, "SubIdx", "sub-index", 0)
            bits = r.child_number(item, "BitSize", "sub-item bit size", 0)
            out[(index, sub)] = OdEntry(index, sub, r.text(item, "Name"), bits, sub_access, sub_mapping)
    return out


def select(devices: list[EsiDevice], which: str | int | None, file: str) -> EsiDevice:
    """The device the spec names: by its <Type> text or product code; the only one when the file has one."""
    if which is None:
        if len(devices) == 1:
            return devices[0]
        raise EsiError(file, None, f"describes {len(devices)} devices ({_listed(devices)}): say which with 'device:'")
    for dev in devices:
        if dev.type_name == which or dev.product_code == which:
            return dev
    raise EsiError(file, None, f"has no device {which!r}; it describes {_listed(devices)}")


def _listed(devices: list[EsiDevice]) -> str:
    return ", ".join(f"{d.type_name} (product code 0x{d.product_code:X})" for d in devices)


def resolve_path(base: Path, relative: str) -> Path:
    return (base / relative) if not Path(relative).is_absolute() else Path(relative)
