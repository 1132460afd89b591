"""CANopen device profiles: the objects a device has, their data types, access and PDO mappability.

A profile comes either from netcfg's own built-in files (devices/profiles/*.yaml, written from the
CiA 301/402 standards and the vendors' firmware documentation) or from a vendor EDS file, read with the
`canopen` package's EDS importer.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from importlib import resources

import yaml

from netcfg.cia301 import DATA_TYPES  # re-exported: the profiles' data type codes are CiA 301's

DATA_TYPE_CODES = {name: code for code, (name, _, _) in DATA_TYPES.items()}

READABLE = frozenset({"ro", "rw", "rwr", "rww", "const"})
WRITABLE = frozenset({"wo", "rw", "rwr", "rww"})
ACCESS_TYPES = READABLE | WRITABLE


@dataclass(frozen=True)
class ObjectEntry:
    index: int
    sub: int
    name: str
    data_type: int
    access: str
    pdo_mappable: bool
    default: int | None = None

    @property
    def bits(self) -> int:
        return DATA_TYPES.get(self.data_type, ("?", 0, "?"))[1]

    @property
    def type_name(self) -> str:
        return DATA_TYPES.get(self.data_type, (f"0x{self.data_type:04X}", 0, "?"))[0]

    @property
    def readable(self) -> bool:
        return self.access in READABLE

    @property
    def writable(self) -> bool:
        return self.access in WRITABLE

    @property
    def ref(self) -> str:
        return f"0x{self.index:04X}:{self.sub}"


@dataclass
class DeviceProfile:
    name: str
    source: str  # "builtin:<name>" or the EDS file path as written in the spec
    objects: dict[tuple[int, int], ObjectEntry] = field(default_factory=dict)
    vendor_id: int | None = None
    product_code: int | None = None
    revision: int | None = None  # 0x1018 sub 3 / [DeviceInfo] RevisionNumber; None: not known
    vendor_name: str = ""  # [DeviceInfo] VendorName / ProductName of the vendor's file; "": not known
    product_name: str = ""
    rpdo_count: int = 4
    tpdo_count: int = 4
    max_mapped_objects: int = 8
    tpdo_event_timer: bool = True  # whether 0x18xx sub 5 exists
    tpdo_inhibit_time: bool = True  # whether 0x18xx sub 3 exists

    def lookup(self, index: int, sub: int) -> ObjectEntry | None:
        return self.objects.get((index, sub))

    def has_index(self, index: int) -> bool:
        return any(i == index for i, _ in self.objects)


def builtin_names(kind: str) -> list[str]:
    """The names of the built-in files of one kind: "profiles" (CANopen devices) or "actuators"."""
    folder = resources.files("netcfg.devices").joinpath(kind)
    return sorted(p.name.removesuffix(".yaml") for p in folder.iterdir() if p.name.endswith(".yaml"))


def builtin_text(kind: str, name: str) -> str:
    """A built-in file's text by its kind and name; KeyError for an unknown name."""
    if name not in builtin_names(kind):
        raise KeyError(name)
    return resources.files("netcfg.devices").joinpath(kind).joinpath(f"{name}.yaml").read_text("utf-8")


def builtin_profile_names() -> list[str]:
    return builtin_names("profiles")


@cache
def builtin_profile(name: str) -> DeviceProfile:
    """Load a built-in profile by name; raises KeyError for an unknown name."""
    text = builtin_text("profiles", name)
    raw = yaml.safe_load(text)
    profile = DeviceProfile(
        name=name,
        source=f"builtin:{name}",
        vendor_id=raw.get("vendor_id"),
        product_code=raw.get("product_code"),
        revision=raw.get("revision"),
        vendor_name=raw.get("vendor_name", ""),
        product_name=raw.get("product_name", ""),
        rpdo_count=raw["rpdo_count"],
        tpdo_count=raw["tpdo_count"],
        max_mapped_objects=raw["max_mapped_objects"],
        tpdo_event_timer=raw["tpdo_event_timer"],
        tpdo_inhibit_time=raw["tpdo_inhibit_time"],
    )
    for obj in raw["objects"]:
        entry = ObjectEntry(
            index=obj["index"],
            sub=obj.get("sub", 0),
            name=obj["name"],
            data_type=DATA_TYPE_CODES[obj["type"]],
            access=obj["access"],
            pdo_mappable=obj.get("pdo", False),
            default=obj.get("default"),
        )
        profile.objects[(entry.index, entry.sub)] = entry
    return profile
