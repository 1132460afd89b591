"""Import a vendor EDS/DCF (CiA 306) into a DeviceProfile, using the `canopen` package's importer."""

from __future__ import annotations

import logging
from functools import lru_cache
from pathlib import Path
from typing import Any

from netcfg import cia301
from netcfg.devices import DeviceProfile, ObjectEntry


class EdsError(Exception):
    pass


def _entries(od: object) -> list[object]:
    import canopen.objectdictionary as cod

    out: list[object] = []
    for obj in od.values():  # type: ignore[attr-defined]
        if isinstance(obj, cod.ODVariable):
            out.append(obj)
        else:
            out.extend(obj.values())
    return out


def object_dictionary(path: Path) -> Any:
    """canopen's object dictionary of an EDS/DCF file, parsed once per file version: a bus of many identical drives
    names one file many times, and the bus.yml importer and resolve both read it. Callers only read it.
    OSError propagates; canopen's own errors too (they are of many kinds)."""
    return _parsed(str(path), path.stat().st_mtime_ns)


@lru_cache(maxsize=64)
def _parsed(file: str, mtime_ns: int) -> Any:
    import canopen

    logging.getLogger("canopen").setLevel(logging.ERROR)
    return canopen.import_od(file)


def cached_profile(path: Path, display: str) -> DeviceProfile:
    """The profile of an EDS file, built once per file version (named after the file as the spec writes it)."""
    return _profile(str(path), path.stat().st_mtime_ns, Path(display).stem)


@lru_cache(maxsize=64)
def _profile(file: str, mtime_ns: int, name: str) -> DeviceProfile:
    return import_eds(Path(file), name)


def import_eds(path: Path, name: str) -> DeviceProfile:
    """Read an EDS file; EdsError carries a message for the user if canopen cannot parse it."""
    try:
        od = object_dictionary(path)
    except Exception as exc:  # canopen raises many kinds for bad files; report them all the same way
        raise EdsError(f"canopen could not read the EDS file: {exc}") from exc
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
    identity = od.get(0x1018)
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
    profile.rpdo_count = sum(1 for i in cia301.pdo_comm_indices("rpdo") if i in od)
    profile.tpdo_count = sum(1 for i in cia301.pdo_comm_indices("tpdo") if i in od)
    if cia301.TPDO_MAP in od:  # TPDO 1 stands for all
        profile.max_mapped_objects = len(od[cia301.TPDO_MAP]) - 1
    if cia301.TPDO_COMM in od:
        subs = {var.subindex for var in _entries({cia301.TPDO_COMM: od[cia301.TPDO_COMM]})}  # type: ignore[attr-defined]
        profile.tpdo_event_timer = 5 in subs
        profile.tpdo_inhibit_time = 3 in subs
    return profile
