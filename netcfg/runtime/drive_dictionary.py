"""The object dictionary of a simulated CANopen drive (netcfg.runtime.drives), as a device keeps it.

Owns DriveDictionary: a canopen.LocalNode's values read and written as the application does, the drive's factory
state (numbers zeroed, an identity, every PDO disabled), the PDO configuration as the master wrote it (PdoSlot,
re-read after every write to it), the CiA 301 checks a device makes of SDO writes to its PDO parameters, the CiA
402 controlword's way to the power state machine, and the PDO payloads packed from and applied to the dictionary.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable
from canopen.objectdictionary.datatypes import NUMBER_TYPES, SIGNED_TYPES
from canopen.sdo import SdoAbortedError

from netcfg import cia301
from netcfg.cia301 import PDO_INVALID, RPDO_COMM, RPDO_MAP, TPDO_COMM, TPDO_MAP
from netcfg.runtime.cia402 import CONTROLWORD, STATUSWORD, PowerStateMachine
from netcfg.runtime.codec import int_range

PDO_SLOTS = cia301.MAX_PDOS
MAX_PDO_BITS = 64  # a classic CAN frame

# SDO abort codes (CiA 301, table 22) the drive answers with
ABORT_NOT_MAPPABLE = 0x06040041
ABORT_PDO_LENGTH = 0x06040042
ABORT_VALUE_RANGE = 0x06090030
ABORT_DEVICE_STATE = 0x08000022


@dataclass(frozen=True)
class PdoSlot:
    """One PDO as the drive's object dictionary holds it now."""

    number: int  # 1-based
    can_id: int
    extended: bool
    valid: bool
    transmission: int
    sync_start: int
    entries: tuple[tuple[int, int, int], ...]  # (index, sub, bits)
    inhibit_100us: int = 0  # TPDOs: sub 3, the least gap between two sends
    event_timer_ms: int = 0  # sub 5: a TPDO's send due after this long without one; an RPDO's deadline (0: off)

    @property
    def event_driven(self) -> bool:
        return self.valid and bool(self.entries) and self.transmission >= 254

    @property
    def bits(self) -> int:
        return sum(b for _, _, b in self.entries)


class DriveDictionary:
    """A drive's object dictionary and its PDO configuration. Faults (for tests): `identity=(vendor_id,
    product_code)` puts other values in 0x1018; `abort_writes={index: abort_code}` aborts every SDO write to those
    objects with that code ({(index, sub): code}: to one sub-index)."""

    def __init__(
        self,
        node_id: int,
        object_dictionary: str | Path | canopen.ObjectDictionary,
        *,
        name: str | None,
        clear_pdos: bool,
        strict_pdo_writes: bool,
        identity: tuple[int, int] | None,
        abort_writes: Mapping[int | tuple[int, int], int] | None,
    ) -> None:
        od = object_dictionary if isinstance(object_dictionary, canopen.ObjectDictionary) else str(object_dictionary)
        self.node = canopen.LocalNode(node_id, od)
        self.name = name or f"node{node_id}"
        self.strict_pdo_writes = strict_pdo_writes
        self.abort_writes = dict(abort_writes or {})
        self.sdo_writes: list[tuple[int, int]] = []  # accepted SDO writes, in order
        self.rpdos_applied = 0
        # the PDO configuration, re-read from the object dictionary after any write to it
        self._dirty = True
        self._sync_id = 0x80
        self._tpdos: tuple[PdoSlot, ...] = ()
        self._rpdos: dict[tuple[int, bool], PdoSlot] = {}
        # the PDO slots the object dictionary has (0-based), looked up once
        self._rx_slots = tuple(n for n in range(PDO_SLOTS) if self.has(RPDO_COMM + n, 1))
        self._tx_slots = tuple(n for n in range(PDO_SLOTS) if self.has(TPDO_COMM + n, 1))
        self._identity, self._clear_on_boot = identity, clear_pdos
        self._fill_values(identity)
        if clear_pdos:
            self._clear_pdos()
        self.node.add_write_callback(self._on_sdo_write)
        # a CiA 402 drive (controlword and statusword in its dictionary) runs the power state machine
        self.power: PowerStateMachine | None = None
        if self.has(CONTROLWORD) and self.has(STATUSWORD):
            self.power = PowerStateMachine()
            self._show_state()

    # --- object dictionary access ----------------------------------------------------------------------------

    def has(self, index: int, sub: int = 0) -> bool:
        return self._variable(index, sub) is not None

    def value(self, index: int, sub: int = 0) -> Any:
        """The object's current value, decoded by its data type."""
        var = self._require(index, sub)
        return var.decode_raw(self.node.get_data(index, sub))

    def set_value(self, index: int, sub: int, value: Any) -> None:
        """Set an object as the application would (no SDO checks); integers are clamped to the type's range."""
        var = self._require(index, sub)
        if var.data_type in NUMBER_TYPES and isinstance(value, int):
            lo, hi = int_range(len(var), var.data_type in SIGNED_TYPES)
            value = min(max(value, lo), hi)
        self._store(index, sub, var.encode_raw(value))

    def _variable(self, index: int, sub: int = 0) -> ODVariable | None:
        od = self.node.object_dictionary
        if index not in od:
            return None
        obj = od[index]
        if isinstance(obj, ODVariable):
            return obj if sub == 0 else None
        var: ODVariable | None = obj.subindices.get(sub)  # only the sub-indices the EDS lists
        return var

    def _require(self, index: int, sub: int) -> ODVariable:
        var = self._variable(index, sub)
        if var is None:
            raise KeyError(f"{self.name}: no object 0x{index:04X}:{sub:02X} in its object dictionary")
        return var

    def _store(self, index: int, sub: int, data: bytes) -> None:
        self.node.data_store.setdefault(index, {})[sub] = bytes(data)
        if index == 0x1005 or index in cia301.PDO_PARAMETERS:
            self._dirty = True

    def _int(self, index: int, sub: int, default: int = 0) -> int:
        if not self.has(index, sub):
            return default
        try:
            return int(self.value(index, sub))
        except SdoAbortedError:
            return default

    def _fill_values(self, identity: tuple[int, int] | None) -> None:
        """Give every number object without a value a zero, and 0x1018 an identity (the EDS may have no
        product code), as a powered-up device has."""
        od = self.node.object_dictionary
        for index in od:
            obj = od[index]
            variables = [obj] if isinstance(obj, ODVariable) else [obj[s] for s in obj]
            for var in variables:
                if var.value is None and var.default is None and var.data_type in NUMBER_TYPES:
                    self._store(var.index, var.subindex, var.encode_raw(0))
        info = od.device_information
        if self.has(0x1018, 2) and info.product_number is not None and self._int(0x1018, 2) == 0:
            self.set_value(0x1018, 2, int(info.product_number))
        if self.has(0x1018, 4) and self._int(0x1018, 4) == 0:
            self.set_value(0x1018, 4, self.node.id)  # a serial number that tells drives apart
        if identity is not None:
            self.set_value(0x1018, 1, identity[0])
            self.set_value(0x1018, 2, identity[1])

    def _clear_pdos(self) -> None:
        for comm, mapping, slots in ((RPDO_COMM, RPDO_MAP, self._rx_slots), (TPDO_COMM, TPDO_MAP, self._tx_slots)):
            for n in slots:
                self._store(comm + n, 1, (self._int(comm + n, 1) | PDO_INVALID).to_bytes(4, "little"))
                if self.has(comm + n, 2):
                    self._store(comm + n, 2, bytes([255]))
                if self.has(mapping + n, 0):
                    self._store(mapping + n, 0, bytes([0]))
                    for sub in range(1, self._map_capacity(mapping + n) + 1):
                        self._store(mapping + n, sub, bytes(4))

    def _map_capacity(self, map_index: int) -> int:
        obj = self.node.object_dictionary[map_index]
        return max((s for s in obj if isinstance(s, int)), default=0) if isinstance(obj, (ODRecord, ODArray)) else 0

    def _show_state(self) -> None:
        if self.power is not None:
            self._store(STATUSWORD, 0, self.power.statusword.to_bytes(2, "little"))

    # --- the PDO configuration ---------------------------------------------------------------------------------

    def _slot(self, comm: int, mapping: int, n: int) -> PdoSlot:
        cob = self._int(comm + n, 1, PDO_INVALID)
        count = self._int(mapping + n, 0)
        entries = [cia301.unpack_mapping(self._int(mapping + n, sub)) for sub in range(1, count + 1)]
        can_id, extended = cia301.pdo_can_id(cob)
        return PdoSlot(
            number=n + 1,
            can_id=can_id,
            extended=extended,
            valid=not cob & PDO_INVALID,
            transmission=self._int(comm + n, 2, 255),
            sync_start=self._int(comm + n, 6),
            entries=tuple(entries),
            inhibit_100us=self._int(comm + n, 3) if comm == TPDO_COMM else 0,
            event_timer_ms=self._int(comm + n, 5),  # an RPDO's: its deadline (CiA 301 7.5.2.35), 0 none
        )

    def _rebuild(self) -> None:
        self._dirty = False
        self._sync_id = self._int(0x1005, 0, 0x80) & 0x7FF
        self._tpdos = tuple(self._slot(TPDO_COMM, TPDO_MAP, n) for n in self._tx_slots)
        rpdos = (self._slot(RPDO_COMM, RPDO_MAP, n) for n in self._rx_slots)
        self._rpdos = {(slot.can_id, slot.extended): slot for slot in rpdos if slot.valid}

    def pdo_slots(self) -> tuple[tuple[str, int, int, bool, int, tuple[tuple[int, int, int], ...]], ...]:
        """(kind, number, CAN id, valid, transmission type, entries) of every PDO, as the drive holds them now."""
        rx = [self._slot(RPDO_COMM, RPDO_MAP, n) for n in self._rx_slots]
        tx = [self._slot(TPDO_COMM, TPDO_MAP, n) for n in self._tx_slots]
        return tuple(
            (kind, s.number, s.can_id, s.valid, s.transmission, s.entries)
            for kind, slots in (("rpdo", rx), ("tpdo", tx))
            for s in slots
        )

    # --- SDO writes: faults and CiA 301 checks --------------------------------------------------------------------

    def _on_sdo_write(self, index: int, subindex: int, od: ODVariable, data: bytes, **_: Any) -> None:
        code = self.abort_writes.get((index, subindex), self.abort_writes.get(index))
        if code is not None:
            raise SdoAbortedError(code)
        if self.strict_pdo_writes:
            self._check_pdo_write(index, subindex, od, data)
        self.sdo_writes.append((index, subindex))
        if index == CONTROLWORD and self.power is not None:
            self.power.controlword(int.from_bytes(data[:2], "little"))
            self._show_state()
        if index == 0x1005 or index in cia301.PDO_PARAMETERS:
            self._dirty = True  # LocalNode stores the value after this callback; re-read it at the next frame

    def _check_pdo_write(self, index: int, sub: int, od: ODVariable, data: bytes) -> None:
        is_map = RPDO_MAP <= index < RPDO_MAP + PDO_SLOTS or TPDO_MAP <= index < TPDO_MAP + PDO_SLOTS
        is_comm = RPDO_COMM <= index < RPDO_COMM + PDO_SLOTS or TPDO_COMM <= index < TPDO_COMM + PDO_SLOTS
        if not (is_map or is_comm) or od.data_type not in NUMBER_TYPES:
            return
        value = int(od.decode_raw(data))
        if is_comm:
            if sub == 1:
                old = self._int(index, 1, PDO_INVALID)
                # CiA 301: the identifier of a valid PDO cannot change; disable it first
                if not old & PDO_INVALID and not value & PDO_INVALID and (old ^ value) & cia301.COB_ID_MASK:
                    raise SdoAbortedError(ABORT_VALUE_RANGE)
            return
        comm = index - cia301.MAP_OFFSET
        if not self._int(comm, 1, PDO_INVALID) & PDO_INVALID:
            raise SdoAbortedError(ABORT_DEVICE_STATE)  # mapping of a valid PDO
        if sub == 0:
            if value > self._map_capacity(index):
                raise SdoAbortedError(ABORT_PDO_LENGTH)
            if sum(self._int(index, s) & 0xFF for s in range(1, value + 1)) > MAX_PDO_BITS:
                raise SdoAbortedError(ABORT_PDO_LENGTH)
            return
        if self._int(index, 0) != 0:
            raise SdoAbortedError(ABORT_DEVICE_STATE)  # entries change only while sub-index 0 is 0
        if value == 0:
            return
        target, target_sub, bits = cia301.unpack_mapping(value)
        if cia301.is_dummy(target, target_sub):  # a dummy entry just reserves bits
            return
        var = self._variable(target, target_sub)
        if var is None or not var.pdo_mappable or bits == 0 or bits > len(var):
            raise SdoAbortedError(ABORT_NOT_MAPPABLE)

    # --- PDO payloads ---------------------------------------------------------------------------------------------

    def _pack(self, slot: PdoSlot) -> bytes:
        """The mapped objects' current values, least significant bit first (CiA 301 PDO layout)."""
        acc, offset = 0, 0
        for index, sub, bits in slot.entries:
            raw = 0
            if not cia301.is_dummy(index, sub):
                raw = int.from_bytes(self.node.get_data(index, sub), "little") & ((1 << bits) - 1)
            acc |= raw << offset
            offset += bits
        return acc.to_bytes((offset + 7) // 8, "little")

    def _apply(self, slot: PdoSlot, data: bytes) -> None:
        acc, offset = int.from_bytes(data, "little"), 0
        for index, sub, bits in slot.entries:
            raw = (acc >> offset) & ((1 << bits) - 1)
            offset += bits
            var = self._variable(index, sub)
            if var is None:
                continue  # dummy entry
            size = len(var)
            if var.data_type in SIGNED_TYPES and bits < size and raw >> (bits - 1):
                raw |= ((1 << size) - 1) ^ ((1 << bits) - 1)  # sign-extend a shortened signed value
            self._store(index, sub, raw.to_bytes(max(size // 8, (bits + 7) // 8), "little"))
        self.rpdos_applied += 1
