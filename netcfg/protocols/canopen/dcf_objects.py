"""A CANopen node's object dictionary while netcfg configures it (Obj, Var: what the EDS and DCF of netcfg.emit.
canopen_dcf describe), and the CiA 301 communication objects netcfg names or builds itself: the PDO communication and
mapping records, and the variables a configuration adds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from netcfg import cia301
from netcfg.devices import WRITABLE
from netcfg.model import Message

U8, U16, U32 = 0x05, 0x06, 0x07  # CiA 301 table 44 data type codes
VAR, ARRAY, RECORD = 0x7, 0x8, 0x9  # CiA 301 table 42 object codes
PdoKind = Literal["rpdo", "tpdo"]

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


# -- a node's object dictionary while it is being configured -------------------------------------------------------
@dataclass
class Var:
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
class Obj:
    subs: dict[int, Var] = field(default_factory=dict)
    name: str | None = None
    object_type: int | None = None  # None: decided from the entries (netcfg.protocols.canopen.dcf's docstring)


Dictionary = dict[int, Obj]


def copy_object(obj: Obj) -> Obj:
    # the constructor, not dataclasses.replace: a third of the time, for 134 entries per drive
    subs = {k: Var(v.name, v.data_type, v.access, v.pdo, v.default, v.relative, v.value) for k, v in obj.subs.items()}
    return Obj(subs, obj.name, obj.object_type)


# -- CiA 301 communication objects -----------------------------------------------------------------------------------
# PDO communication parameter sub-entries (CiA 301 7.5.2.35/37): sub -> (name, data type)
COMM_SUBS = {
    0: ("Highest sub-index supported", U8),
    1: ("COB-ID used by PDO", U32),
    2: ("Transmission type", U8),
    3: ("Inhibit time", U16),
    5: ("Event timer", U16),
    6: ("SYNC start value", U8),
}


def comm_record(kind: PdoKind, inhibit: bool, timer: bool, sync_start: bool) -> Obj:
    name = "RPDO" if kind == "rpdo" else "TPDO"
    obj = Obj(object_type=RECORD)  # named by _standard_name
    subs = [0, 1, 2] + [3] * inhibit + [5] * timer + [6] * sync_start
    for sub in subs:
        sub_name, dtype = COMM_SUBS[sub]
        obj.subs[sub] = Var(sub_name.replace("PDO", name), dtype, "const" if sub == 0 else "rw", default=0)
    obj.subs[2].default = 255  # event-driven, manufacturer-specific: the CiA 301 default
    fix_sub0(obj)
    return obj


def map_record(count: int) -> Obj:
    obj = Obj(object_type=RECORD)  # named by _standard_name
    obj.subs[0] = Var("Number of mapped application objects in PDO", U8, "rw", default=0)
    for sub in range(1, count + 1):
        obj.subs[sub] = Var(f"Application object {sub}", U32, "rw", default=0)
    return obj


def map_entries(mapping: Obj, entries: list[tuple[int, int, int]]) -> None:
    """sub 0 = number of mapped objects, sub k = the k-th entry (CiA 301 7.5.2.36)."""
    sub_var(mapping, 0, "Number of mapped application objects in PDO", U8).configure(len(entries))
    for k, (index, sub, bits) in enumerate(entries, 1):
        sub_var(mapping, k, f"Application object {k}", U32).configure(cia301.pack_mapping(index, sub, bits))
    for k in range(len(entries) + 1, max(mapping.subs) + 1):
        if k in mapping.subs:
            mapping.subs[k].default = 0


def fix_sub0(obj: Obj) -> None:
    sub0 = obj.subs.get(0)
    if sub0 is not None:
        sub0.default = max(obj.subs)


def sub_var(obj: Obj, sub: int, name: str, data_type: int) -> Var:
    return obj.subs.setdefault(sub, Var(name, data_type, "rw", default=0))


def object_var(od: Dictionary, index: int, name: str, data_type: int, access: str, default: int | None) -> Var:
    obj = od.setdefault(index, Obj())
    return obj.subs.setdefault(0, Var(name, data_type, access, default=default))


def pdo_comment(kind: str, n: int, m: Message) -> str:
    assert m.pdo is not None
    entries = ", ".join(f"0x{e.index:04X}:{e.sub} {e.name}" for e in m.pdo.entries)
    return f"{kind.upper()}{n} = {m.name}: COB-ID 0x{m.id:03X}, type {m.pdo.transmission}, {entries}"
