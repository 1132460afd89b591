"""A live CANopen master driven by runtime.json: network set-up over SDO, then the SYNC cycle of seed 000.

Two phases, as in the ALLEX-2 exoskeleton (seed 000, sections 4.3-4.4):

1. `configure_network(cfg, bus)` - the "network management" phase. For each configured slave, through the
   `canopen` package's SDO client: check the device identity (0x1018), switch it to PRE-OPERATIONAL, and for each of
   its PDOs in runtime.json disable it (COB-ID bit 31), write the communication parameters and the mapping, re-enable
   it; disable the device's other PDOs; write the start-up SDO values (the interpolation time period 0x60C2 of a
   CiA 402 drive); read everything back and compare; start the node (NMT). A node that fails is reported with what
   to do and left in PRE-OPERATIONAL; the others carry on. That holds for bus-level failures too: a frame the CAN
   interface refuses to send (python-can's can.CanError, e.g. socketcan's "Transmit buffer full" when nothing
   acknowledges on an unterminated or unpowered bus) or a receive thread that stopped (canopen re-raises its error on
   the next send) fails the node being set up, not the whole set-up. This phase may use canopen's threads (a
   python-can Notifier); it stops them before returning.

2. `MasterCycle(cfg, bus, clock).run(n)` - Figure 7: each period write the RxPDOs, send SYNC, collect the
   synchronous TxPDOs until all have arrived or the read window ends, store the samples, and wait dynamically
   (eq. (1): waiting = T - Pt - K). It uses nothing but `bus.send(msg)`, `bus.recv(timeout)` and the clock (no
   threads, no time module, no Notifier), so the same code runs in real time (SystemClock, any python-can bus) and in
   virtual time (a simulator's clock, and a bus whose recv(timeout) advances that clock; recv(0) must not wait).
   Such a bus overrides recv() itself, not just _recv_internal(): python-can's BusABC.recv() re-checks the timeout
   against the wall clock and would call _recv_internal() again until real time has passed.

Identifiers, mappings, periods and windows all come from runtime.json, and so do the device facts: the expected
identity (node.identity), the COB-ID values (pdo.cob_id), how many PDOs the device has (node.rpdo_count/tpdo_count)
and the start-up SDO writes (node.sdo_init). A runtime.json written before those keys lacks them; the master then
does what it did before they existed: the identity from the node's generated EDS/DCF (`identities_from_dir`), the
COB-ID flag bits netcfg's DCF uses, PDOs 1-4 of the pre-defined connection set, and 0x60C2 = the SYNC period.

This module imports only the standard library, python-can, canopen, netcfg.runtime and netcfg.cia301 (the
standard's numbers, which import nothing).
"""

from __future__ import annotations

import configparser
import csv
import gc
import math
import statistics
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import can
import canopen
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from netcfg import cia301
from netcfg.runtime import Bus, Message, Node, RuntimeConfig, SdoWrite, interpolation_period
from netcfg.runtime.clock import Clock
from netcfg.runtime.codec import CodecError, Number, int_range

__all__ = [
    "CommandFn",
    "CycleRecord",
    "Identity",
    "MasterCycle",
    "MasterRun",
    "NodeSetup",
    "PdoReadback",
    "PeriodStats",
    "SetupReport",
    "TimeStats",
    "canopen_bus",
    "canopen_slaves",
    "configure_network",
    "identities_from_dir",
    "identity_from_eds",
    "identity_from_runtime",
    "interpolation_period",
]

PREDEFINED_PDOS = len(cia301.TPDO_BASE)  # the pre-defined connection set has 4 RPDOs and 4 TPDOs per node
IDENTITY = 0x1018
INTERPOLATION = 0x60C2  # CiA 402 interpolation time period: sub 1 value (UNSIGNED8), sub 2 index (INTEGER8, 10^index s)

NMT_START, NMT_PRE_OPERATIONAL = 0x01, 0x80

# The integer data types a start-up SDO write may have -> (bytes over SDO, signed): BOOLEAN, INTEGERn and UNSIGNEDn
# of CiA 301 table 44. TIME_OF_DAY and TIME_DIFFERENCE are no integers: they hold milliseconds and days apart.
SDO_INTEGERS = {
    code: ((bits + 7) // 8, kind == "signed")
    for code, (name, bits, kind) in cia301.DATA_TYPES.items()
    if name.startswith(("BOOLEAN", "INTEGER", "UNSIGNED"))
}

# Abort codes whose meaning is "the device has no such object"
ABORT_NO_OBJECT = (0x06020000, 0x06090011)

_ABORT_HINTS = {
    0x06020000: "the device has no such object: check that the node's device in the spec is the device fitted",
    0x06090011: "the device has no such sub-index: check that the node's device in the spec is the device fitted",
    0x06010002: "the object is read-only on this device",
    0x06040041: "the device cannot map this object into a PDO: check its EDS (PDOMapping=1) and the spec's PDO map",
    0x06040042: "the mapping is longer than the PDO (8 bytes) or than the device's number of mapped objects",
    0x06040043: "the device rejects this parameter combination: check the PDO's transmission type and timing",
    0x06090030: "the value is outside the device's range: check the spec's value against the device's EDS",
    0x06090031: "the value is above the device's maximum: check the spec against the device's EDS",
    0x06090032: "the value is below the device's minimum: check the spec against the device's EDS",
    0x08000021: "the device refuses because of local control: release its local control (e.g. a commissioning tool)",
    0x08000022: "the device refuses in its present state: it must be PRE-OPERATIONAL with the PDO disabled",
}


# --- identities ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Identity:
    """What a node's 0x1018 must hold. None: not checked (an EDS with product number 0 gives no product code)."""

    vendor_id: int | None
    product_code: int | None = None
    revision: int | None = None
    source: str = ""


def _eds_int(text: str) -> int:
    text = text.strip()
    return int(text, 16) if text.lower().startswith("0x") else int(text, 10)


def identity_from_eds(path: str | Path) -> Identity:
    """The identity an EDS/DCF's [DeviceInfo] declares (VendorNumber, ProductNumber, RevisionNumber)."""
    parser = configparser.ConfigParser(interpolation=None, strict=False)
    parser.optionxform = str  # type: ignore[assignment,method-assign]  # EDS keys are case-sensitive
    with open(path, encoding="utf-8", errors="replace") as fh:
        parser.read_file(fh)
    info = parser["DeviceInfo"]
    product = _eds_int(info["ProductNumber"]) if info.get("ProductNumber", "").strip() else 0
    revision = _eds_int(info["RevisionNumber"]) if info.get("RevisionNumber", "").strip() else 0
    return Identity(_eds_int(info["VendorNumber"]), product or None, revision or None, str(path))


def identity_from_runtime(cfg: RuntimeConfig, node: Node) -> Identity | None:
    """The identity runtime.json states for a node (node.identity); None when it states none or knows no value."""
    ident = node.identity
    if ident is None or (ident.vendor_id is None and ident.product_code is None):
        return None
    return Identity(ident.vendor_id, ident.product_code, ident.revision, cfg.source)


def identities_from_dir(cfg: RuntimeConfig, directory: str | Path, bus_name: str | None = None) -> dict[str, Identity]:
    """Expected identities of a bus's slaves: runtime.json's node.identity where it has one, else (a runtime.json
    written before that key) `<directory>/<node>.dcf` (else `.eds`), as netcfg writes them to
    generated/<system>/canopen/. Nodes without either are left out (not checked)."""
    found = {}
    for node in canopen_slaves(cfg, canopen_bus(cfg, bus_name)):
        stated = identity_from_runtime(cfg, node)
        if stated is not None:
            found[node.name] = stated
            continue
        for suffix in (".dcf", ".eds"):
            path = Path(directory) / f"{node.name}{suffix}"
            if path.is_file():
                found[node.name] = identity_from_eds(path)
                break
    return found


# --- set-up results -------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PdoReadback:
    """One PDO as read back from the node over SDO."""

    kind: str  # "rpdo" | "tpdo"
    number: int
    message: str | None  # the runtime message it carries; None for a PDO the spec does not use
    cob_id: int  # the raw 0x14xx/0x18xx sub 1 value, flag bits included
    transmission: int | None
    inhibit_100us: int | None
    event_timer_ms: int | None
    sync_start: int | None
    entries: tuple[tuple[int, int, int], ...]  # (index, sub, bits)

    @property
    def valid(self) -> bool:
        return not self.cob_id & cia301.PDO_INVALID

    @property
    def can_id(self) -> int:
        return cia301.pdo_can_id(self.cob_id)[0]


@dataclass(frozen=True)
class NodeSetup:
    """The set-up of one node: ok, or an error saying what went wrong and what to do."""

    node: str
    node_id: int
    ok: bool
    error: str | None
    step: str  # the step reached: identity, pre-operational, <PDO> ..., read-back, start, done
    abort_code: int | None = None
    identity: tuple[int, int] | None = None  # (vendor id, product code) read from 0x1018
    pdos: tuple[PdoReadback, ...] = ()
    interpolation: tuple[int, int] | None = None  # 0x60C2 (value, index) read back
    started: bool = False
    notes: tuple[str, ...] = ()
    start_up: tuple[tuple[int, int, int], ...] = ()  # the start-up SDO writes read back: (index, sub, value)

    def __str__(self) -> str:
        if self.ok:
            started = "started (OPERATIONAL)" if self.started else "configured, not started"
            return f"{self.node} (node {self.node_id}): ok, {len(self.pdos)} PDOs verified, {started}"
        return f"{self.node} (node {self.node_id}): FAILED at {self.step}: {self.error}"


@dataclass(frozen=True)
class SetupReport:
    bus: str
    nodes: tuple[NodeSetup, ...]

    @property
    def ok(self) -> bool:
        return all(n.ok for n in self.nodes)

    @property
    def failed(self) -> tuple[NodeSetup, ...]:
        return tuple(n for n in self.nodes if not n.ok)

    def node(self, name: str) -> NodeSetup:
        for n in self.nodes:
            if n.node == name:
                return n
        raise KeyError(f"no node named {name!r} was set up on bus {self.bus!r}")

    def __str__(self) -> str:
        head = f"CANopen set-up of bus {self.bus}: {sum(n.ok for n in self.nodes)}/{len(self.nodes)} nodes ok"
        return "\n".join([head, *(f"  {n}" for n in self.nodes)])


# --- set-up ---------------------------------------------------------------------------------------------------------


class _NodeFailed(Exception):
    def __init__(self, step: str, error: str, abort_code: int | None = None) -> None:
        super().__init__(error)
        self.step, self.error, self.abort_code = step, error, abort_code


def _u(value: int, size: int) -> bytes:
    return (value & ((1 << (8 * size)) - 1)).to_bytes(size, "little")


class _NodeConfigurator:
    """Configures one node; any problem raises _NodeFailed with the text the user reads."""

    def __init__(
        self,
        cfg: RuntimeConfig,
        bus: Bus,
        node: Node,
        remote: canopen.RemoteNode,
        identity: Identity | None,
        interpolation: bool,
        disable_unused: bool,
    ) -> None:
        self.cfg, self.bus, self.node, self.remote = cfg, bus, node, remote
        self.expected_identity, self.interpolation, self.disable_unused = identity, interpolation, disable_unused
        self.step = "identity"
        self.notes: list[str] = []
        self.identity: tuple[int, int] | None = None
        self.pdos = sorted(
            (m for m in cfg.messages_on(bus.name) if m.pdo is not None and m.pdo.node == node.name),
            key=lambda m: (m.pdo.kind != "rpdo", m.pdo.number) if m.pdo else (True, 0),
        )
        self.disabled: list[tuple[str, int]] = []
        self.interp: tuple[int, int] | None = None
        self.written: list[SdoWrite] = []  # start-up SDO writes done, read back at the end
        self.start_up: list[tuple[int, int, int]] = []  # ... and what the read-back found

    def _fail(self, error: str, abort_code: int | None = None) -> _NodeFailed:
        return _NodeFailed(self.step, error, abort_code)

    def _sdo(self, action: str, index: int, sub: int, data: bytes | None = None) -> bytes:
        try:
            if data is None:
                return bytes(self.remote.sdo.upload(index, sub))
            self.remote.sdo.download(index, sub, data)
            return data
        except SdoAbortedError as exc:
            hint = _ABORT_HINTS.get(exc.code, "see the device manual for this abort code")
            value = f" = 0x{int.from_bytes(data, 'little'):X}" if data is not None else ""
            text = SdoAbortedError.CODES.get(exc.code, "unknown abort code")
            raise self._fail(
                f"SDO abort 0x{exc.code:08X} ({text}) on {action} 0x{index:04X}:{sub:02X}{value}; {hint}. "
                f"{self._left()} Fix it and run the set-up again; the other nodes are not affected.",
                exc.code,
            ) from exc
        except SdoCommunicationError as exc:
            timeout_ms = 1000 * self.remote.sdo.RESPONSE_TIMEOUT
            if self.step == "identity":
                raise self._fail(
                    f"no answer to the SDO read of 0x{index:04X}:{sub:02X} within {timeout_ms:.0f} ms ({exc}). "
                    f"Check that the drive is powered, wired and terminated, and set to node id "
                    f"{self.node.node_id} and {self.bus.bitrate // 1000} kbit/s. Nothing was written to it."
                ) from exc
            raise self._fail(
                f"stopped answering SDO ({action} 0x{index:04X}:{sub:02X}, {timeout_ms:.0f} ms: {exc}). "
                f"Check its power and wiring. {self._left()}"
            ) from exc

    def _left(self) -> str:
        if self.step in ("identity", "pre-operational"):
            return "Nothing was written to it."
        if self.step == "read-back":
            return "The node is left in PRE-OPERATIONAL."
        if self.step == "start":
            return "Its configuration was read back correctly, but it was not started: it stays PRE-OPERATIONAL."
        return f"The node is left in PRE-OPERATIONAL; its PDO configuration is incomplete ({self.step})."

    def _read_int(self, index: int, sub: int) -> int:
        return int.from_bytes(self._sdo("read", index, sub), "little")

    def run(self) -> None:
        self.check_identity()
        self.step = "pre-operational"
        self.remote.nmt.send_command(NMT_PRE_OPERATIONAL)
        for msg in self.pdos:
            self.write_pdo(msg)
        if self.disable_unused:
            self.disable_other_pdos()
        if self.interpolation:
            if self.node.sdo_init is None:  # a runtime.json written before sdo_init existed
                self.write_interpolation()
            else:
                self.write_start_up(self.node.sdo_init)

    def check_identity(self) -> None:
        vendor = self._read_int(IDENTITY, 1)
        try:
            product = int.from_bytes(self.remote.sdo.upload(IDENTITY, 2), "little")
        except SdoAbortedError as exc:  # CiA 301 makes only the vendor id mandatory
            if exc.code not in ABORT_NO_OBJECT:
                raise
            product = 0
        self.identity = (vendor, product)
        want = self.expected_identity
        if want is None:
            return
        wrong = (want.vendor_id is not None and vendor != want.vendor_id) or (
            want.product_code is not None and product != want.product_code
        )
        if wrong:
            expected = ", ".join(
                f"{what} 0x{value:08X}"
                for what, value in (("vendor", want.vendor_id), ("product", want.product_code))
                if value is not None
            )
            raise self._fail(
                f"wrong device at this node id: 0x1018 holds vendor 0x{vendor:08X}, product 0x{product:08X}; "
                f"expected {expected} (device '{self.node.device}'"
                + (f", from {Path(want.source).name}" if want.source else "")
                + f"). Check the node id set on the drive ({self.node.node_id}) and that the device fitted is the "
                "one in the spec. Nothing was written to it."
            )

    def write_pdo(self, msg: Message) -> None:
        pdo = msg.pdo
        assert pdo is not None
        comm, mapping = self._indices(pdo.kind, pdo.number)
        self.step = f"{pdo.kind.upper()}{pdo.number} ({msg.name})"
        cob = self._cob_id(msg)
        self._sdo("disabling", comm, 1, _u(cob | cia301.PDO_INVALID, 4))
        self._sdo("writing the transmission type", comm, 2, _u(pdo.transmission, 1))
        if pdo.inhibit_100us is not None:
            self._sdo("writing the inhibit time", comm, 3, _u(pdo.inhibit_100us, 2))
        if pdo.event_timer_ms is not None:
            self._sdo("writing the event timer", comm, 5, _u(pdo.event_timer_ms, 2))
        if pdo.sync_start is not None:
            self._sdo("writing the SYNC start value", comm, 6, _u(pdo.sync_start, 1))
        self._sdo("clearing the mapping", mapping, 0, _u(0, 1))
        for sub, entry in enumerate(pdo.entries, start=1):
            self._sdo("mapping", mapping, sub, _u(cia301.pack_mapping(entry.index, entry.sub, entry.bits), 4))
        self._sdo("writing the number of mapped objects", mapping, 0, _u(len(pdo.entries), 1))
        self._sdo("enabling", comm, 1, _u(cob, 4))

    @staticmethod
    def _indices(kind: str, number: int) -> tuple[int, int]:
        return cia301.pdo_comm_index(kind, number), cia301.pdo_map_index(kind, number)

    @staticmethod
    def _cob_id(msg: Message) -> int:
        """The COB-ID value to write: runtime.json's pdo.cob_id (the value in netcfg's DCF). A runtime.json written
        before that key: the same value, from cia301.pdo_cob_id as the DCF."""
        assert msg.pdo is not None
        if msg.pdo.cob_id is not None:
            return msg.pdo.cob_id
        return cia301.pdo_cob_id(msg.pdo.kind, msg.id, msg.extended)

    def disable_other_pdos(self) -> None:
        """Disable every PDO of the device the spec does not use: as many as runtime.json says it has, else the
        pre-defined connection set's 4 per direction, skipping those the device lacks."""
        used = {(m.pdo.kind, m.pdo.number) for m in self.pdos if m.pdo is not None}
        counts = {"rpdo": self.node.rpdo_count, "tpdo": self.node.tpdo_count}
        for kind in ("rpdo", "tpdo"):
            known = counts[kind]
            for number in range(1, (PREDEFINED_PDOS if known is None else known) + 1):
                if (kind, number) in used:
                    continue
                comm, _ = self._indices(kind, number)
                self.step = f"disabling unused {kind.upper()}{number}"
                if known is not None:  # the device has it: an abort is a fault, reported with its hint
                    cob = self._read_int(comm, 1)
                else:
                    try:
                        cob = int.from_bytes(self.remote.sdo.upload(comm, 1), "little")
                    except SdoAbortedError as exc:
                        if exc.code in ABORT_NO_OBJECT:
                            continue  # the device has fewer PDOs
                        raise
                if not cob & cia301.PDO_INVALID:
                    self._sdo("disabling the unused PDO", comm, 1, _u(cob | cia301.PDO_INVALID, 4))
                self.disabled.append((kind, number))

    def write_start_up(self, writes: Iterable[SdoWrite]) -> None:
        """runtime.json's start-up SDO writes, in order; a device that refuses one fails with the abort's hint."""
        for w in writes:
            self.step = f"start-up write 0x{w.index:04X}:{w.sub:02X}"
            size_sign = SDO_INTEGERS.get(w.data_type)
            if size_sign is None:
                raise self._fail(f"data type 0x{w.data_type:04X} of 0x{w.index:04X}:{w.sub:02X} is not an integer")
            size, signed = size_sign
            lo, hi = int_range(8 * size, signed)
            if not lo <= w.value <= hi:
                raise self._fail(f"0x{w.index:04X}:{w.sub:02X} = {w.value} does not fit its data type")
            self._sdo("writing", w.index, w.sub, _u(w.value, size))
            self.written.append(w)
        got = {(w.index, w.sub): w.value for w in self.written}
        if (INTERPOLATION, 1) in got and (INTERPOLATION, 2) in got:
            self.interp = (got[INTERPOLATION, 1], got[INTERPOLATION, 2])

    def write_interpolation(self) -> None:
        """For a runtime.json without sdo_init: 0x60C2 = the SYNC period, on any slave that has the object."""
        assert self.bus.canopen is not None
        self.step = "interpolation time period 0x60C2"
        value = interpolation_period(self.bus.canopen.sync_period_ns)
        if value is None:
            self.notes.append(
                f"0x60C2 not set: the SYNC period {self.bus.canopen.sync_period_ns} ns is no whole number of "
                "1 ms..1 us units below 256"
            )
            return
        try:
            self.remote.sdo.download(INTERPOLATION, 1, _u(value[0], 1))
        except SdoAbortedError as exc:
            if exc.code in ABORT_NO_OBJECT:
                self.notes.append("no 0x60C2 (not a CiA 402 interpolating drive): interpolation period not set")
                return
            raise
        self._sdo("writing the interpolation time index", INTERPOLATION, 2, _u(value[1], 1))
        self.interp = value

    def read_back(self) -> tuple[PdoReadback, ...]:
        self.step = "read-back"
        found, problems = [], []
        for msg in self.pdos:
            assert msg.pdo is not None
            got = self._read_pdo(msg.pdo.kind, msg.pdo.number, msg.name)
            found.append(got)
            problems += [f"{msg.pdo.kind.upper()}{msg.pdo.number} ({msg.name}) {p}" for p in _differences(msg, got)]
        for kind, number in self.disabled:
            comm, _ = self._indices(kind, number)
            if not self._read_int(comm, 1) & cia301.PDO_INVALID:
                problems.append(f"unused {kind.upper()}{number} is still enabled")
        for w in self.written:
            signed = SDO_INTEGERS[w.data_type][1]
            have = int.from_bytes(self._sdo("read", w.index, w.sub), "little", signed=signed)
            self.start_up.append((w.index, w.sub, have))
            if have != w.value:
                problems.append(f"0x{w.index:04X}:{w.sub:02X} reads {have}, {w.value} written")
        if self.interp is not None and not self.written:  # written from the SYNC period (older runtime.json)
            index = int.from_bytes(self._sdo("read", INTERPOLATION, 2), "little", signed=True)
            got_interp = (self._read_int(INTERPOLATION, 1), index)
            if got_interp != self.interp:
                problems.append(f"0x60C2 reads {got_interp}, {self.interp} written")
        if problems:
            raise self._fail(
                "read-back differs from what was written: " + "; ".join(problems) + ". The device accepted the "
                "writes but holds other values: check its firmware's PDO rules. The node is left in PRE-OPERATIONAL."
            )
        return tuple(found)

    def _read_pdo(self, kind: str, number: int, name: str | None) -> PdoReadback:
        comm, mapping = self._indices(kind, number)
        pdo = next(m.pdo for m in self.pdos if m.pdo is not None and (m.pdo.kind, m.pdo.number) == (kind, number))
        count = self._read_int(mapping, 0)
        return PdoReadback(
            kind=kind,
            number=number,
            message=name,
            cob_id=self._read_int(comm, 1),
            transmission=self._read_int(comm, 2),
            inhibit_100us=self._read_int(comm, 3) if pdo.inhibit_100us is not None else None,
            event_timer_ms=self._read_int(comm, 5) if pdo.event_timer_ms is not None else None,
            sync_start=self._read_int(comm, 6) if pdo.sync_start is not None else None,
            entries=tuple(cia301.unpack_mapping(self._read_int(mapping, s)) for s in range(1, count + 1)),
        )


def _differences(msg: Message, got: PdoReadback) -> list[str]:
    pdo = msg.pdo
    assert pdo is not None
    out = []
    want_cob = _NodeConfigurator._cob_id(msg)
    if got.cob_id != want_cob:
        out.append(f"COB-ID reads 0x{got.cob_id:08X}, 0x{want_cob:08X} written")
    if got.transmission != pdo.transmission:
        out.append(f"transmission type reads {got.transmission}, {pdo.transmission} written")
    for name, want, have in (
        ("inhibit time", pdo.inhibit_100us, got.inhibit_100us),
        ("event timer", pdo.event_timer_ms, got.event_timer_ms),
        ("SYNC start value", pdo.sync_start, got.sync_start),
    ):
        if want is not None and have != want:
            out.append(f"{name} reads {have}, {want} written")
    want_entries = tuple((e.index, e.sub, e.bits) for e in pdo.entries)
    if got.entries != want_entries:
        out.append(f"mapping reads {_fmt_entries(got.entries)}, {_fmt_entries(want_entries)} written")
    return out


def _fmt_entries(entries: Iterable[tuple[int, int, int]]) -> str:
    return "[" + ", ".join(f"0x{i:04X}:{s:02X}/{b}" for i, s, b in entries) + "]"


def configure_network(
    cfg: RuntimeConfig,
    bus: can.BusABC,
    *,
    bus_name: str | None = None,
    nodes: Iterable[str] | None = None,
    identities: Mapping[str, Identity] | None = None,
    sdo_timeout_s: float = 0.5,
    interpolation: bool = True,
    disable_unused: bool = True,
    start: bool = True,
) -> SetupReport:
    """Configure the CANopen slaves of `bus_name` (the config's only CANopen bus by default) over SDO as runtime.json
    says, read it back, and start the nodes that passed. Each node's identity is checked first: the one `identities`
    gives for it, else runtime.json's node.identity; a node with neither is not checked (for a runtime.json written
    before node.identity, pass identities_from_dir). `interpolation` writes the start-up SDO values (node.sdo_init).
    Returns one NodeSetup per node; never raises for a node's fault.

    `bus` stays open and usable by a MasterCycle afterwards: the Notifier this uses is stopped before returning."""
    co_bus = canopen_bus(cfg, bus_name)
    wanted = set(nodes) if nodes is not None else None
    slaves = [n for n in canopen_slaves(cfg, co_bus) if wanted is None or n.name in wanted]
    if wanted is not None and (unknown := wanted - {n.name for n in slaves}):
        raise ValueError(f"not CANopen slaves of bus '{co_bus.name}': {', '.join(sorted(unknown))}")
    network = canopen.Network(bus)
    network.notifier = can.Notifier(bus, network.listeners, timeout=0.02)
    results = []
    try:
        for node in slaves:
            assert node.node_id is not None
            remote = canopen.RemoteNode(node.node_id, canopen.ObjectDictionary())
            remote.sdo.RESPONSE_TIMEOUT = sdo_timeout_s
            network.add_node(remote)
            try:
                results.append(
                    _configure_node(
                        cfg,
                        co_bus,
                        node,
                        remote,
                        (identities or {}).get(node.name) or identity_from_runtime(cfg, node),
                        interpolation,
                        disable_unused,
                        start,
                        network.notifier,
                    )
                )
            finally:
                del network[node.node_id]
    finally:
        network.notifier.stop(timeout=2.0)
        network.notifier = None
    return SetupReport(co_bus.name, tuple(results))


def _configure_node(
    cfg: RuntimeConfig,
    bus: Bus,
    node: Node,
    remote: canopen.RemoteNode,
    identity: Identity | None,
    interpolation: bool,
    disable_unused: bool,
    start: bool,
    notifier: can.Notifier | None = None,
) -> NodeSetup:
    assert node.node_id is not None
    job = _NodeConfigurator(cfg, bus, node, remote, identity, interpolation, disable_unused)
    error, code = None, None
    try:
        job.run()
        readback = job.read_back()
        if start:
            job.step = "start"
            remote.nmt.send_command(NMT_START)
    except _NodeFailed as exc:
        error, code = exc.error, exc.abort_code
    except SdoAbortedError as exc:  # from a step that lets some codes through (no such object)
        text = SdoAbortedError.CODES.get(exc.code, "unknown abort code")
        error, code = f"SDO abort 0x{exc.code:08X} ({text}) at {job.step}. {job._left()}", exc.code
    except SdoCommunicationError as exc:
        error = f"stopped answering SDO at {job.step} ({exc}). {job._left()}"
    except Exception as exc:
        # bus-level failures: canopen's Network.check() re-raises whatever stopped the Notifier's receive thread
        # (python-can's bus.recv raised) on the next send; bus.send raises can.CanError. Anything else is a bug.
        received = notifier is not None and exc is notifier.exception
        if not (received or isinstance(exc, can.CanError)):
            raise
        error = _bus_failure(job, exc, received)
    notes = tuple(job.notes)
    if error is not None:
        return NodeSetup(node.name, node.node_id, False, error, job.step, code, job.identity, notes=notes)
    return NodeSetup(
        node.name,
        node.node_id,
        True,
        None,
        "done",
        None,
        job.identity,
        readback,
        job.interp,
        start,
        notes,
        tuple(job.start_up),
    )


def _bus_failure(job: _NodeConfigurator, exc: Exception, received: bool) -> str:
    """What to tell the user when the CAN interface itself failed while setting up this node."""
    kbit = job.bus.bitrate // 1000
    if received:
        what = (
            f"receiving from the CAN interface stopped at {job.step} ({type(exc).__name__}: {exc}), so no answer can "
            "arrive. Check that the interface is up and its cable plugged in,"
        )
    else:
        what = (
            f"the CAN interface refused to send a frame at {job.step} ({type(exc).__name__}: {exc}). A full transmit "
            "buffer or a bus-off controller means no other device acknowledges its frames. Check"
        )
    return (
        f"{what} the bus termination (120 ohm at each end), that the drives are powered and that every device is set "
        f"to {kbit} kbit/s; then run the set-up again. {job._left()} The other nodes are set up on their own."
    )


def canopen_bus(cfg: RuntimeConfig, bus_name: str | None) -> Bus:
    """The CANopen bus named, or the config's only one; ValueError for a bus of another protocol, or when there is
    no single CANopen bus to default to."""
    if bus_name is not None:
        bus = cfg.bus(bus_name)
        if bus.canopen is None:
            raise ValueError(f"bus '{bus_name}' is a {bus.protocol} bus, not CANopen")
        return bus
    buses = [b for b in cfg.buses if b.canopen is not None]
    if len(buses) != 1:
        names = ", ".join(b.name for b in buses) or "none"
        raise ValueError(f"{cfg.system} has {len(buses)} CANopen buses ({names}); say which one with bus_name")
    return buses[0]


def canopen_slaves(cfg: RuntimeConfig, bus: Bus) -> list[Node]:
    """The slaves a master configures and collects from: every node on the bus with a node id but the masters."""
    return [n for n in (cfg.node(name) for name in bus.nodes) if n.role != "master" and n.node_id is not None]


def _master(cfg: RuntimeConfig, bus: Bus) -> Node:
    assert bus.canopen is not None
    masters = [n for n in (cfg.node(name) for name in bus.nodes) if n.role == "master"]
    producer = [n for n in masters if n.name == bus.canopen.sync_producer]
    if producer or masters:
        return (producer or masters)[0]
    raise ValueError(f"bus '{bus.name}' has no master node")


# --- the master cycle ---------------------------------------------------------------------------------------------

Samples = Mapping[str, Mapping[str, Number]]
CommandFn = Callable[[int, Samples], Mapping[str, Mapping[str, Number]] | None]


@dataclass(frozen=True)
class CycleRecord:
    """One iteration of the master cycle; times are the clock's seconds."""

    index: int
    sync_number: int  # SYNCs sent by this master so far, this one included
    start: float  # the iteration began (commands computed next)
    written: float  # the RxPDOs were sent
    sync_sent: float
    read_done: float  # all due TxPDOs in, or the read window over
    end: float  # the dynamic wait is over: the next iteration's start
    due: tuple[str, ...]  # TxPDOs due at this SYNC
    arrivals: Mapping[str, float] = field(compare=False)  # TxPDO -> clock time received
    values: Mapping[str, Mapping[str, Number]] = field(compare=False)  # TxPDO -> decoded fields
    missing: tuple[str, ...]  # due but not received within the read window
    late: int  # TxPDOs found queued before this SYNC went out (answers to an earlier SYNC)
    other: int  # other frames seen (SDO, EMCY, heartbeat, PDOs of other nodes)
    processing_s: float  # Pt: start -> samples stored
    waiting_s: float  # eq. (1): T - Pt - K (negative: the iteration overran)

    @property
    def period_s(self) -> float:
        return self.end - self.start

    @property
    def write_s(self) -> float:
        return self.written - self.start

    @property
    def read_s(self) -> float:
        return self.read_done - self.sync_sent


@dataclass(frozen=True)
class TimeStats:
    count: int
    mean_s: float
    std_s: float
    min_s: float
    max_s: float

    @classmethod
    def of(cls, values: Sequence[float]) -> TimeStats:
        """std is the population standard deviation (divided by n), as numpy's default and the simulator's
        netcfg.sim.stats.spread: a run's values are all the values, not a sample of a larger set."""
        if not values:
            return cls(0, math.nan, math.nan, math.nan, math.nan)
        return cls(len(values), statistics.fmean(values), statistics.pstdev(values), min(values), max(values))

    def ms(self) -> str:
        if not self.count:
            return "no values"
        return (
            f"mean {1e3 * self.mean_s:.4f} ms, std {1e3 * self.std_s:.4f} ms, min {1e3 * self.min_s:.4f} ms, "
            f"max {1e3 * self.max_s:.4f} ms (n = {self.count})"
        )


@dataclass(frozen=True)
class PeriodStats:
    """Period error statistics as in seed 000 section 5.2: each period's error (actual - T) and the whole run's
    error (its duration - n T; the paper's "gait cycle" of 8 s, whose mean over 220 runs was 1.266 ms)."""

    period_s: float
    errors: TimeStats  # actual period - T, per cycle
    run_s: float  # first start -> last end
    run_error_s: float  # run_s - n T

    def __str__(self) -> str:
        n = self.errors.count
        return (
            f"period error over {n} cycles of {1e3 * self.period_s:g} ms: {self.errors.ms()}\n"
            f"run of {n} cycles: {self.run_s:.6f} s, error {1e3 * self.run_error_s:+.4f} ms "
            f"(mean period {1e3 * self.run_s / max(n, 1):.5f} ms)"
        )


@dataclass(frozen=True)
class MasterRun:
    """What a MasterCycle run saw: per-cycle records, with counts and statistics over them."""

    bus: str
    period_s: float
    read_window_s: float
    k_s: float
    expected: tuple[str, ...]  # synchronous TxPDOs the master collects, runtime.json order
    producers: Mapping[str, str]  # TxPDO -> node
    fields: Mapping[str, tuple[str, ...]]  # TxPDO -> its fields, in frame order
    records: tuple[CycleRecord, ...]
    duplicates: Mapping[str, int]  # a TxPDO received twice within one read window
    bad_frames: Mapping[str, int]  # a TxPDO whose payload did not decode (wrong length)
    send_errors: Mapping[str, int]  # frames the bus refused to send

    @property
    def cycles(self) -> int:
        return len(self.records)

    @property
    def nodes(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(self.producers[m] for m in self.expected))

    def missing_by_node(self) -> dict[str, int]:
        counts = dict.fromkeys(self.nodes, 0)
        for rec in self.records:
            for name in rec.missing:
                counts[self.producers[name]] += 1
        return counts

    def missing_by_message(self) -> dict[str, int]:
        counts = dict.fromkeys(self.expected, 0)
        for rec in self.records:
            for name in rec.missing:
                counts[name] += 1
        return counts

    @property
    def missing(self) -> int:
        return sum(len(rec.missing) for rec in self.records)

    @property
    def late(self) -> int:
        return sum(rec.late for rec in self.records)

    def complete_samples(self, node: str) -> int:
        """Cycles in which every TxPDO of `node` due at that SYNC arrived in the read window."""
        own = {m for m in self.expected if self.producers[m] == node}
        return sum(1 for rec in self.records if own & set(rec.due) and not own & set(rec.missing))

    def period_stats(self) -> PeriodStats:
        errors = [rec.period_s - self.period_s for rec in self.records]
        run = self.records[-1].end - self.records[0].start if self.records else 0.0
        return PeriodStats(self.period_s, TimeStats.of(errors), run, run - self.cycles * self.period_s)

    def read_stats(self) -> TimeStats:
        """SYNC sent -> last due TxPDO received, over complete cycles (Table 5, "reading")."""
        return TimeStats.of([rec.read_s for rec in self.records if rec.due and not rec.missing])

    def write_stats(self) -> TimeStats:
        """Time to compute and send the RxPDOs (Table 5, "writing")."""
        return TimeStats.of([rec.write_s for rec in self.records])

    def columns(self) -> list[str]:
        head = [
            "cycle",
            "sync",
            "start_s",
            "sync_s",
            "write_ms",
            "read_ms",
            "processing_ms",
            "waiting_ms",
            "period_ms",
            "missing",
        ]
        for name in self.expected:
            head += [f"{name}.{f}" for f in self.fields[name]] + [f"{name}.arrival_ms"]
        return head

    def rows(self) -> list[list[str]]:
        """The CSV rows: times relative to the first cycle's start; empty cells for frames that did not arrive."""
        t0 = self.records[0].start if self.records else 0.0
        out = []
        for rec in self.records:
            row = [
                str(rec.index),
                str(rec.sync_number),
                f"{rec.start - t0:.6f}",
                f"{rec.sync_sent - t0:.6f}",
                f"{1e3 * rec.write_s:.4f}",
                f"{1e3 * rec.read_s:.4f}",
                f"{1e3 * rec.processing_s:.4f}",
                f"{1e3 * rec.waiting_s:.4f}",
                f"{1e3 * rec.period_s:.4f}",
                " ".join(rec.missing),
            ]
            for name in self.expected:
                values = rec.values.get(name, {})
                row += ["" if f not in values else repr(values[f]) for f in self.fields[name]]
                arrival = rec.arrivals.get(name)
                row.append("" if arrival is None else f"{1e3 * (arrival - rec.sync_sent):.4f}")
            out.append(row)
        return out

    def write_csv(self, path: str | Path) -> Path:
        """Store the samples as a comma-separated file, like the paper's storage process (section 4.4.3)."""
        path = Path(path)
        with path.open("w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh)
            writer.writerow(self.columns())
            writer.writerows(self.rows())
        return path

    def summary(self) -> str:
        missing = self.missing_by_node()
        lines = [
            f"{self.cycles} cycles on {self.bus}: T = {1e3 * self.period_s:g} ms, read window "
            f"{1e3 * self.read_window_s:g} ms, K = {1e3 * self.k_s:g} ms",
            "complete samples: " + ", ".join(f"{n} {self.complete_samples(n)}" for n in self.nodes),
            f"missing frames: {self.missing}"
            + (" (" + ", ".join(f"{n} {c}" for n, c in missing.items() if c) + ")" if self.missing else ""),
            str(self.period_stats()),
            f"reading (SYNC -> all TxPDOs): {self.read_stats().ms()}",
            f"writing (RxPDOs): {self.write_stats().ms()}",
        ]
        if self.late:
            lines.append(f"late TxPDOs (after their read window): {self.late}")
        for what, counts in (
            ("duplicate", self.duplicates),
            ("undecodable", self.bad_frames),
            ("unsent", self.send_errors),
        ):
            if any(counts.values()):
                lines.append(f"{what} frames: " + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
        return "\n".join(lines)


class MasterCycle:
    """The master cycle of seed 000, Figure 7, driven by runtime.json.

    Each iteration: ask `commands(cycle_index, samples_of_the_previous_cycle)` for RxPDO values
    ({message: {field: value}}), send every periodic RxPDO of the master (with the last values given, zeros before
    any) plus any on-demand RxPDO the commands name (e.g. the interpolation time at gait start), send SYNC, collect
    the TxPDOs due at this SYNC (transmission type n: every n-th SYNC) until all arrived or the read window ends,
    store the samples, then wait dynamically (eq. (1)). A TxPDO that did not arrive is counted as missing for that
    cycle and node, and its cells stay empty: nothing is filled in.

    Dynamic waiting: the paper waits T - Pt - K after measuring the iteration's processing time Pt, i.e. until
    start + T - K. K absorbs what Pt does not measure (the equation itself, the sleep's wake-up latency). The paper
    gives K = 132 "ms", which cannot be milliseconds: with T = 20 ms every wait would be negative. Microseconds
    (0.132 ms) would fit the order of a Raspberry Pi's sleep latency, but the paper does not say, and K is tuned per
    machine anyway. Default 0: SystemClock spins the last 0.5 ms, so the residual error is a few microseconds.
    With drift_free=True the iteration ends at first_start + (i + 1) T - K instead, so errors do not accumulate over
    a run (the paper's anchoring lets them add up to its 1.266 ms per 8 s gait cycle).
    """

    def __init__(
        self,
        cfg: RuntimeConfig,
        bus: can.BusABC,
        clock: Clock,
        *,
        bus_name: str | None = None,
        nodes: Iterable[str] | None = None,
        commands: CommandFn | None = None,
        k_s: float = 0.0,
        period_s: float | None = None,
        read_window_s: float | None = None,
        drift_free: bool = False,
        pause_gc: bool = True,
    ) -> None:
        self.cfg, self.bus, self.clock = cfg, bus, clock
        self.pause_gc = pause_gc
        co_bus = canopen_bus(cfg, bus_name)
        params = co_bus.canopen
        assert params is not None
        self.bus_name = co_bus.name
        self.master = _master(cfg, co_bus)
        slaves = [n.name for n in canopen_slaves(cfg, co_bus)]
        wanted = set(nodes) if nodes is not None else set(slaves)
        if unknown := wanted - set(slaves):
            raise ValueError(f"not CANopen slaves of bus '{co_bus.name}': {', '.join(sorted(unknown))}")
        self.period_s = period_s if period_s is not None else params.sync_period_ns / 1e9
        self.read_window_s = read_window_s if read_window_s is not None else params.collect_window_ns() / 1e9
        self.k_s = k_s
        self.drift_free = drift_free
        self.commands = commands
        on_bus = cfg.messages_on(co_bus.name)
        sync = [m for m in on_bus if m.implicit == "SYNC"]
        self.sync_frame = can.Message(
            arbitration_id=sync[0].id if sync else params.sync_id, is_extended_id=False, dlc=0, data=b""
        )
        self.rpdos = tuple(
            m
            for m in on_bus
            if m.pdo is not None and m.pdo.kind == "rpdo" and m.producer == self.master.name and m.pdo.node in wanted
        )
        tpdos = [
            m
            for m in on_bus
            if m.pdo is not None and m.pdo.kind == "tpdo" and m.pdo.node in wanted and self.master.name in m.consumers
        ]
        # transmission type 0 answers only SYNCs after its data changed: taken when it comes, never waited for nor
        # counted missing (the analysis and the simulator assume it every SYNC, the worst case for the bus)
        self._every = {
            m.name: every
            for m in tpdos
            if m.pdo is not None and m.pdo.transmission != 0 and (every := cia301.sync_every(m.pdo.transmission))
        }
        self.expected = tuple(m for m in tpdos if m.name in self._every)
        self._by_id = {(m.id, m.extended): m for m in tpdos}
        self._last: dict[str, dict[str, Number]] = {m.name: _rest_values(m) for m in self.rpdos}
        self._rpdo_names = {m.name for m in self.rpdos}
        self.syncs = 0  # SYNCs sent; the drives count theirs from NMT start, so "every n-th" agrees

    def _due(self, sync_number: int) -> tuple[Message, ...]:
        return tuple(m for m in self.expected if sync_number % self._every[m.name] == 0)

    def run(self, cycles: int) -> MasterRun:
        """Run `cycles` iterations. With pause_gc, Python's cyclic garbage collector is off meanwhile (and collects
        once afterwards): a full collection of a large heap holds the interpreter for tens of milliseconds, stalling
        this loop and any drive threads in the process past the read window. Reference counting still frees memory.
        """
        was_enabled = gc.isenabled()
        if self.pause_gc:
            gc.disable()
        try:
            return self._run(cycles)
        finally:
            if self.pause_gc and was_enabled:
                gc.enable()
                gc.collect()

    def _run(self, cycles: int) -> MasterRun:
        clock, bus = self.clock, self.bus
        records: list[CycleRecord] = []
        duplicates: Counter[str] = Counter()
        bad: Counter[str] = Counter()
        unsent: Counter[str] = Counter()
        previous: Samples = {}
        first = start = clock.now()
        for i in range(cycles):
            # writing (red in Figure 7): this cycle's commands, computed from the last samples
            asked = self.commands(i, previous) if self.commands is not None else None
            on_demand = self._take(asked or {})
            for msg in self.rpdos:
                if msg.kind == "periodic" or msg.name in on_demand:
                    try:
                        bus.send(msg.to_can(**self._last[msg.name]))
                    except can.CanError:
                        unsent[msg.name] += 1
            written = clock.now()
            # anything already queued cannot answer the SYNC about to go out
            late = other = 0
            while (stale := bus.recv(timeout=0)) is not None:
                if (stale.arbitration_id, bool(stale.is_extended_id)) in self._by_id:
                    late += 1
                else:
                    other += 1
            # reading (orange): SYNC, then the due TxPDOs until all are in or the window is over
            try:
                bus.send(self.sync_frame)
            except can.CanError:
                unsent[f"SYNC 0x{self.sync_frame.arbitration_id:X}"] += 1
            sync_sent = clock.now()
            self.syncs += 1
            due = self._due(self.syncs)
            pending = {m.name for m in due}
            arrivals: dict[str, float] = {}
            values: dict[str, dict[str, Number]] = {}
            deadline = sync_sent + self.read_window_s
            while pending:
                remaining = deadline - clock.now()
                # once the window is over, still take what is already queued: a master descheduled by its operating
                # system looks late, but those frames did arrive; only frames not yet received are missing
                frame = bus.recv(timeout=max(remaining, 0.0))
                if frame is None:
                    if remaining <= 0:
                        break
                    continue
                t = clock.now()
                got = (
                    None
                    if frame.is_error_frame or frame.is_remote_frame
                    else self._by_id.get((frame.arbitration_id, bool(frame.is_extended_id)))
                )
                if got is None:
                    other += 1
                    continue
                if got.name in arrivals:
                    duplicates[got.name] += 1
                    continue
                try:
                    values[got.name] = got.decode(bytes(frame.data))
                except CodecError:
                    bad[got.name] += 1
                    continue
                arrivals[got.name] = t
                pending.discard(got.name)
            read_done = clock.now()
            # storage: kept in memory until the run ends, as the paper does; missing frames stay missing
            missing = tuple(m.name for m in due if m.name not in arrivals)
            previous = values
            processed = clock.now()
            processing = processed - start
            waiting = self.period_s - processing - self.k_s  # eq. (1)
            target = first + (i + 1) * self.period_s - self.k_s if self.drift_free else start + self.period_s - self.k_s
            clock.sleep_until(target)
            end = clock.now()
            records.append(
                CycleRecord(
                    index=i,
                    sync_number=self.syncs,
                    start=start,
                    written=written,
                    sync_sent=sync_sent,
                    read_done=read_done,
                    end=end,
                    due=tuple(m.name for m in due),
                    arrivals=arrivals,
                    values=values,
                    missing=missing,
                    late=late,
                    other=other,
                    processing_s=processing,
                    waiting_s=waiting,
                )
            )
            start = end
        return MasterRun(
            bus=self.bus_name,
            period_s=self.period_s,
            read_window_s=self.read_window_s,
            k_s=self.k_s,
            expected=tuple(m.name for m in self.expected),
            producers={m.name: m.producer for m in self.expected},
            fields={m.name: tuple(f.name for f in m.fields) for m in self.expected},
            records=tuple(records),
            duplicates=dict(duplicates),
            bad_frames=dict(bad),
            send_errors=dict(unsent),
        )

    def _take(self, asked: Mapping[str, Mapping[str, Number]]) -> set[str]:
        """Merge commanded values into the last ones; the names of the RxPDOs commanded."""
        for name, fields in asked.items():
            if name not in self._rpdo_names:
                msg = self.cfg.message(name)  # an unknown name raises, with close matches
                raise ValueError(f"'{msg.name}' is not an RxPDO this master sends on bus '{self.bus_name}'")
            self._last[name].update(fields)
        return set(asked)


def _rest_values(msg: Message) -> dict[str, Number]:
    """Zero for every field (a drive at rest), or the field's minimum when zero is out of range."""
    out: dict[str, Number] = {}
    for f in msg.fields:
        zero: Number = 0
        if f.minimum is not None and f.minimum > 0:
            zero = f.minimum
        elif f.maximum is not None and f.maximum < 0:
            zero = f.maximum
        out[f.name] = zero
    return out
