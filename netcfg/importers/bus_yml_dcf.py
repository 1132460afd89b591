"""The DCF/EDS of a bus.yml slave, read as dcfgen reads it: its PDO slots with $NODEID resolved. Used by
netcfg.importers.bus_yml."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from netcfg import cia301


# -- the DCF/EDS of a slave: what dcfgen starts from --------------------------------------------------------------
@dataclass(frozen=True)
class Slot:
    """A PDO slot's values in the DCF (ParameterValue, else DefaultValue), $NODEID resolved."""

    cob_id: int | None
    transmission: int | None
    inhibit_100us: int | None
    event_timer_ms: int | None
    sync_start: int | None
    mapping: tuple[tuple[int, int], ...]


class DeviceFile:
    """One parsed DCF/EDS, shared by every slave that names it: it keeps what it looked up (a bus of 126 identical
    drives asks the same questions 126 times), and only $NODEID differs between the slaves."""

    def __init__(self, od: Any) -> None:
        self.od = od
        self.comments: str = getattr(od, "comments", "") or ""
        self.node_id: int | None = getattr(od, "node_id", None)
        self._raw: dict[tuple[int, int], tuple[int, bool] | None] = {}
        self._numbers: dict[str, list[int]] = {}

    def has(self, index: int, sub: int) -> bool:
        if index not in self.od:
            return False
        obj = self.od[index]
        return sub == 0 if not hasattr(obj, "subindices") else sub in obj

    def _value(self, index: int, sub: int, node_id: int) -> int | None:
        key = (index, sub)
        if key not in self._raw:
            self._raw[key] = self._read(index, sub)
        parsed = self._raw[key]
        if parsed is None:
            return None
        value, relative = parsed
        return value + node_id if relative else value

    def _read(self, index: int, sub: int) -> tuple[int, bool] | None:
        if not self.has(index, sub):
            return None
        var = self.od[index] if not hasattr(self.od[index], "subindices") else self.od[index][sub]
        raw = getattr(var, "value_raw", None) or getattr(var, "default_raw", None)
        return _raw_int(raw) if isinstance(raw, str) else None

    def slot(self, kind: str, number: int, node_id: int) -> Slot | None:
        comm = cia301.pdo_comm_index(kind, number)
        if comm not in self.od:
            return None
        map_index = cia301.pdo_map_index(kind, number)
        count = self._value(map_index, 0, node_id) or 0
        mapping = []
        for k in range(1, count + 1):
            value = self._value(map_index, k, node_id)
            if value:
                mapping.append(cia301.unpack_mapping(value)[:2])
        return Slot(
            self._value(comm, 1, node_id),
            self._value(comm, 2, node_id),
            self._value(comm, 3, node_id) if kind == "tpdo" else None,
            self._value(comm, 5, node_id) if kind == "tpdo" else None,
            self._value(comm, 6, node_id) if kind == "tpdo" else None,
            tuple(mapping),
        )

    def slots(self, kind: str) -> list[int]:
        if kind not in self._numbers:
            self._numbers[kind] = [
                n for n in range(1, cia301.MAX_PDOS + 1) if cia301.pdo_comm_index(kind, n) in self.od
            ]
        return self._numbers[kind]


_RAW = re.compile(r"^(?:\$NODEID\+)?(-?0X[0-9A-F]+|-?[0-9]+)(?:\+\$NODEID)?$")


def _raw_int(raw: str) -> tuple[int, bool] | None:
    """A CiA 306 integer value, and whether '$NODEID+' adds the node id to it (as dcfgen does with the bus.yml's
    node_id)."""
    text = raw.replace(" ", "").upper()
    m = _RAW.match(text)
    if m is None:
        return None
    return int(m.group(1), 0), "$NODEID" in text
