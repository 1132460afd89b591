"""Import a vendor EDS/DCF (CiA 306) into a DeviceProfile, using the `canopen` package's importer.

The file comes through netcfg's input guard (size limit, byte-order mark, Windows-1252 fallback: vendor files
are often written on Windows) and what canopen reads is then held against CiA 301's ranges, so that a damaged
file is refused here, naming its object, instead of surfacing later as a crash or as a wrong value in a DCF.
"""

from __future__ import annotations

import io
import re
from functools import lru_cache
from pathlib import Path
from typing import Any

from netcfg import cia301
from netcfg.devices import DeviceProfile, ObjectEntry
from netcfg.inputs import InputError, read_input_text

UNSIGNED32_MAX = 0xFFFF_FFFF
MAX_MAPPED_OBJECTS = 64  # CiA 301 7.5.2.36: sub-index 0 of a PDO mapping parameter is 0..64
IDENTITY = 0x1018
_TEXT_TYPES = {0x09, 0x0A, 0x0B, 0x0F}  # VISIBLE_STRING, OCTET_STRING, UNICODE_STRING, DOMAIN: not numbers
_LONG_NUMBER = re.compile(r"[0-9A-Fa-f]{21,}")  # 2^64 has 20 decimal digits, 16 hex ones
IDENTITY_NAMES = {1: "Vendor-ID", 2: "Product code", 3: "Revision number", 4: "Serial number"}


class EdsError(Exception):
    """What is wrong with a device file; line and column when the fault is at one place in it."""

    def __init__(self, message: str, line: int | None = None, column: int | None = None) -> None:
        super().__init__(message)
        self.line = line
        self.column = column


def read_od(path: Path, node_id: int | None = None) -> Any:
    """The canopen ObjectDictionary of an EDS/DCF file, read through the input guard and checked (check_od).
    EdsError names what is wrong (and where, for the range checks)."""
    import canopen

    what = "DCF" if path.suffix.lower() == ".dcf" else "EDS"
    try:
        text = read_input_text(path, what, legacy=True)
    except InputError as exc:
        raise EdsError(str(exc)) from exc
    stream = io.StringIO(text)
    stream.name = str(path)  # canopen picks the format by the name's suffix
    import logging  # with canopen, only when a device file is read: a spec without one loads neither

    logging.getLogger("canopen").setLevel(logging.ERROR)
    try:
        od = canopen.import_od(stream, node_id)
    except Exception as exc:  # canopen raises many kinds for bad files; report them all the same way
        line, column = _value_position(text, str(exc))
        raise EdsError(f"canopen could not read the {what} file: {exc}", line, column) from exc
    check_od(od, text)
    return od


def object_dictionary(path: Path) -> Any:
    """canopen's object dictionary of an EDS/DCF file (read_od), parsed once per file version: a bus of many
    identical drives names one file many times, and the bus.yml importer and resolve both read it. Callers only
    read it. EdsError when the file cannot be read or breaks CiA 301's ranges; OSError from stat propagates."""
    return _parsed(str(path), path.stat().st_mtime_ns)


@lru_cache(maxsize=64)
def _parsed(file: str, mtime_ns: int) -> Any:
    return read_od(Path(file))


def cached_profile(path: Path, display: str) -> DeviceProfile:
    """The profile of an EDS file, built once per file version (named after the file as the spec writes it)."""
    return _profile(str(path), path.stat().st_mtime_ns, Path(display).stem)


@lru_cache(maxsize=64)
def _profile(file: str, mtime_ns: int, name: str) -> DeviceProfile:
    return import_eds(Path(file), name)


def _value_position(text: str, error: str) -> tuple[int | None, int | None]:
    """Where the value canopen's error quotes ("invalid literal ...: '0xZZ'") is written: the first `Key=value` line
    with it. (None, None) when the error quotes none or it is not found."""
    quoted = re.findall(r"'([^'\n]+)'", error)
    for value in reversed(quoted):  # the value comes last in Python's conversion errors
        m = re.search(rf"^([^=\n;\[]+=[ \t]*){re.escape(value)}[ \t]*$", text, re.MULTILINE)
        if m is not None:
            return text.count("\n", 0, m.start()) + 1, len(m.group(1)) + 1
    return None, None


def _section_line(text: str, index: int, sub: int | None) -> int | None:
    name = f"{index:04X}" if sub is None else f"{index:04X}sub{sub:X}"
    m = re.search(rf"^\[{name}\]", text, re.IGNORECASE | re.MULTILINE)
    return None if m is None else text.count("\n", 0, m.start()) + 1


def _where(text: str, index: int, sub: int | None = None) -> str:
    line = _section_line(text, index, sub) or (_section_line(text, index, None) if sub == 0 else None)
    obj = f"0x{index:04X}" if sub is None else f"0x{index:04X}:{sub}"
    return f"object {obj}" + (f" (line {line})" if line else "")


def _shown(value: int, hex_digits: int = 0) -> str:
    """A number for a message: as written when short (a 5,000-digit one cannot even be printed in decimal)."""
    if value.bit_length() > 64:
        return f"a number of {value.bit_length():,} bits"
    return f"0x{value:0{hex_digits}X}" if hex_digits and value >= 0 else str(value)


def _value(var: Any) -> Any:
    value = getattr(var, "value", None)
    return value if value is not None else getattr(var, "default", None)


def check_od(od: Any, text: str) -> None:
    """CiA 301's shape and ranges for what netcfg reads from a device file: the identity object, PDO mapping
    counts. EdsError names the object and its line."""
    import canopen.objectdictionary as cod

    for var in _entries(od):  # CiA 301: 16-bit indices, 8-bit sub-indices, values of at most 64 bits
        index, sub = var.index, var.subindex  # type: ignore[attr-defined]
        if not (0 <= index <= 0xFFFF and 0 <= sub <= 0xFF):
            raise EdsError(f"an object numbered {_shown(index, 4)} sub {_shown(sub, 2)} is outside CiA 301's ranges "
                           "(index 0x0000..0xFFFF, sub-index 0..255); fix the EDS")
        for what in ("default", "value"):
            raw = getattr(var, f"{what}_raw", None)  # canopen keeps the text when it cannot convert it
            numeric = getattr(var, "data_type", None) not in _TEXT_TYPES
            if isinstance(raw, str) and numeric and _LONG_NUMBER.search(raw):
                raise EdsError(f"{_where(text, index, sub)}: its {what} value has a number of more than 20 digits, "
                               "more than any CANopen data type holds (64 bits); fix the EDS")
            value = getattr(var, what, None)
            if isinstance(value, int) and value.bit_length() > 64:
                raise EdsError(f"{_where(text, index, sub)}: its {what} value is {_shown(value)}, more than any "
                               "CANopen data type holds (64 bits); fix the EDS")
    identity = od.get(IDENTITY)
    if identity is not None and isinstance(identity, cod.ODVariable):
        raise EdsError(
            f"{_where(text, IDENTITY)} (Identity) is a VAR; CiA 301 makes it a RECORD (ObjectType=0x9) with "
            "sub 1 Vendor-ID, 2 Product code, 3 Revision number; fix the EDS"
        )
    if identity is not None:
        for sub, what in IDENTITY_NAMES.items():
            if sub in identity:
                value = _value(identity[sub])
                if isinstance(value, int) and not 0 <= value <= UNSIGNED32_MAX:
                    raise EdsError(
                        f"{_where(text, IDENTITY, sub)} ({what}) is {_shown(value)}, outside UNSIGNED32 "
                        "(0..0xFFFFFFFF); "
                        "fix the EDS"
                    )
    info = od.device_information
    for attr, key in (("vendor_number", "VendorNumber"), ("product_number", "ProductNumber"),
                      ("revision_number", "RevisionNumber")):
        value = getattr(info, attr, None)
        if isinstance(value, int) and not 0 <= value <= UNSIGNED32_MAX:
            raise EdsError(f"[DeviceInfo] {key}={_shown(value)} is outside UNSIGNED32 (0..0xFFFFFFFF); fix the EDS")
    for kind in ("rpdo", "tpdo"):
        for number in range(1, cia301.MAX_PDOS + 1):
            index = cia301.pdo_map_index(kind, number)
            obj = od.get(index)
            if obj is None or isinstance(obj, cod.ODVariable) or 0 not in obj:
                continue
            count = _value(obj[0])
            if isinstance(count, int) and not 0 <= count <= MAX_MAPPED_OBJECTS:
                raise EdsError(
                    f"{_where(text, index, 0)}: {_shown(count)} mapped objects; CiA 301 allows 0..{MAX_MAPPED_OBJECTS}"
                )


def _entries(od: object) -> list[object]:
    import canopen.objectdictionary as cod

    out: list[object] = []
    for obj in od.values():  # type: ignore[attr-defined]
        if isinstance(obj, cod.ODVariable):
            out.append(obj)
        else:
            out.extend(obj.values())
    return out


def import_eds(path: Path, name: str) -> DeviceProfile:
    """Read an EDS file; EdsError carries a message for the user if it cannot be read or breaks CiA 301."""
    od = object_dictionary(path)
    profile = DeviceProfile(name=name, source=str(path))
    for var in _entries(od):
        entry = ObjectEntry(
            index=var.index,  # type: ignore[attr-defined]
            sub=var.subindex,  # type: ignore[attr-defined]
            name=var.name,  # type: ignore[attr-defined]
            data_type=var.data_type or 0,  # type: ignore[attr-defined]
            access=var.access_type,  # type: ignore[attr-defined]
            pdo_mappable=bool(var.pdo_mappable),  # type: ignore[attr-defined]
            default=var.default if isinstance(var.default, int) else None,  # type: ignore[attr-defined]
        )
        profile.objects[(entry.index, entry.sub)] = entry
    identity = od.get(IDENTITY)
    if identity is not None and 1 in identity:
        profile.vendor_id = identity[1].default if isinstance(identity[1].default, int) else None
    if identity is not None and 2 in identity:
        profile.product_code = identity[2].default if isinstance(identity[2].default, int) else None
    if identity is not None and 3 in identity:
        profile.revision = identity[3].default if isinstance(identity[3].default, int) else None
    # vendors often give 0x1018 no DefaultValue (maxon's EPOS4 EDS): CiA 306 [DeviceInfo] states the identity too.
    # 0 there means "not stated" (netcfg's own files write 0 when the profile does not know)
    info = od.device_information
    profile.vendor_id = profile.vendor_id or info.vendor_number or None
    profile.product_code = profile.product_code or info.product_number or None
    profile.revision = profile.revision or info.revision_number or None
    profile.vendor_name = (info.vendor_name or "").strip()
    profile.product_name = (info.product_name or "").strip()
    profile.rpdo_count = sum(1 for i in cia301.pdo_comm_indices("rpdo") if i in od)
    profile.tpdo_count = sum(1 for i in cia301.pdo_comm_indices("tpdo") if i in od)
    if cia301.TPDO_MAP in od:  # TPDO 1 stands for all
        profile.max_mapped_objects = len(od[cia301.TPDO_MAP]) - 1
    if cia301.TPDO_COMM in od:
        subs = {var.subindex for var in _entries({cia301.TPDO_COMM: od[cia301.TPDO_COMM]})}  # type: ignore[attr-defined]
        profile.tpdo_event_timer = 5 in subs
        profile.tpdo_inhibit_time = 3 in subs
    return profile
