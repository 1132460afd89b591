"""From a configured object dictionary (dcf_objects) to the view templates/canopen_dcf.j2 renders: the
file's header values (FileView), the object lists and every object's sections as `keyword=value` text (CiA 306
4.6), written once per distinct contents and shared between files; names, number formats and INI-safe text.
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Collection, Iterable
from dataclasses import dataclass
from functools import lru_cache

from netcfg import cia301
from netcfg.devices import DATA_TYPES
from netcfg.model import Bus, Node
from netcfg.protocols.canopen.dcf_objects import ARRAY, NAMES, RECORD, U8, Dictionary, Obj, Var

MANDATORY = (0x1000, 0x1001, 0x1018)  # CiA 306 4.6.2: the mandatory objects of every device
MANUFACTURER = range(0x2000, 0x6000)  # CiA 301 table 43: manufacturer-specific profile area
STANDARD_RATES = (10, 20, 50, 125, 250, 500, 800, 1000)  # kbit/s with a BaudRate_ keyword (CiA 306 4.6.1)
_RPDO_COMM, _TPDO_COMM = cia301.pdo_comm_indices("rpdo"), cia301.pdo_comm_indices("tpdo")

Known = dict[int, tuple[Obj, str]]  # objects whose sections are written already (the same in EDS and DCF)
# a configured object's contents -> its sections in the EDS and in the DCF: most come out the same for every node
# (the SYNC objects, PDO mappings, $NODEID-relative defaults), so 126 drives write each once
Texts = dict[tuple[object, ...], tuple[str, str]]


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
class Identity:
    """Who made the device and what it is: the file's [DeviceInfo] (its 0x1018 identity, CiA 306 4.6.2.1)."""

    product_name: str
    vendor_name: str = ""
    vendor_number: int = 0
    product_number: int = 0
    revision_number: int = 0


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


def shared_text(index: int, obj: Obj) -> str:
    """The sections of an object no node configures: nothing in them is a ParameterValue, so EDS and DCF agree."""
    sections = _sections(index, obj)
    assert all(s.value is None for s in sections), f"0x{index:04X} has a configured value"
    return "".join(section_text(s, dcf=True) for s in sections)


def file_view(
    od: Dictionary,
    node: Node,
    bus: Bus,
    *,
    description: str,
    identity: Identity,
    master: bool,
    comments: list[str],
    texts: Texts,
    dummies: Collection[int] = (),  # the dummy-mapping types the device offers (0x0001-0x0007)
    known: Known | None = None,
) -> FileView:
    """The file of `node` on `bus` that `od` describes, as its sections. `known`: objects whose texts are already
    written (a profile's own), reused as they are."""
    assert node.node_id is not None
    kbit = bus.bitrate // 1000
    lists: dict[str, list[str]] = {"MandatoryObjects": [], "OptionalObjects": [], "ManufacturerObjects": []}
    sections: list[str | tuple[str, str]] = []
    for index in sorted(od):
        group = "MandatoryObjects" if index in MANDATORY else "OptionalObjects"
        lists["ManufacturerObjects" if index in MANUFACTURER else group].append(f"0x{index:04X}")
        cached = known.get(index) if known else None
        if cached is not None and cached[0] is od[index]:
            sections.append(cached[1])
        else:
            sections.append(_object_texts(index, od[index], texts))
    groups = tuple((name, tuple(indices)) for name, indices in lists.items())
    return FileView(
        description=ini_text(description),
        vendor_name=ini_text(identity.vendor_name),
        vendor_number=f"0x{identity.vendor_number:08X}",
        product_name=ini_text(identity.product_name),
        product_number=f"0x{identity.product_number:08X}",
        revision_number=f"0x{identity.revision_number:08X}",
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


def _object_texts(index: int, obj: Obj, texts: Texts) -> tuple[str, str]:
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


def _sections(index: int, obj: Obj) -> list[Section]:
    section = f"{index:04X}"
    subs = obj.subs
    if obj.object_type is None and list(subs) == [0]:
        return [_var_section(section, subs[0], _hex(index, 0))]
    if 0 not in subs:  # CiA 301: sub 0 of a record or array holds its highest sub-index
        subs = {0: Var("Highest sub-index supported", U8, "ro", default=max(subs)), **subs}
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


def _array_or_record(subs: dict[int, Var]) -> int:
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


def _var_section(section: str, var: Var, hex_: bool) -> Section:
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
