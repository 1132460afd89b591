"""Network set-up of a CANopen master over SDO (seed 000, section 4.3): identity, PDO communication and mapping
parameters, start-up values, read-back, NMT start; what it found is netcfg.runtime.canopen_setup_report's. See
netcfg.runtime.canopen_master for the whole picture."""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Mapping
from pathlib import Path

import can
import canopen
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from netcfg import cia301
from netcfg.runtime import Bus, Message, Node, RuntimeConfig, SdoWrite, interpolation_period
from netcfg.runtime.canopen_identity import Identity, identity_from_runtime
from netcfg.runtime.canopen_network import canopen_bus, canopen_slaves
from netcfg.runtime.canopen_setup_report import NodeSetup, PdoReadback, SetupReport
from netcfg.runtime.codec import int_range

__all__ = ["NodeSetup", "PdoReadback", "SetupReport", "configure_network", "configure_node"]

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
        self._od: canopen.ObjectDictionary | None = None  # the node's EDS, for object names in messages
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
            raise self._fail(
                f"SDO abort 0x{exc.code:08X} ({cia301.sdo_abort_text(exc.code)}) on {action} "
                f"{self.object_name(index, sub)}{value}; {hint}. "
                f"{self._left()} Fix it and run the set-up again; the other nodes are not affected.",
                exc.code,
            ) from exc
        except SdoCommunicationError as exc:
            timeout_ms = 1000 * self.remote.sdo.RESPONSE_TIMEOUT
            tries = self.remote.sdo.MAX_RETRIES
            waited = f"within {timeout_ms:.0f} ms" + (f", {tries} times" if tries > 1 else "")
            timed_out = (
                f"the master aborted it: 0x{cia301.SDO_TIMED_OUT:08X}, "
                f"{cia301.sdo_abort_text(cia301.SDO_TIMED_OUT)}; sdo_timeout and sdo_retries of the node set the wait"
            )
            if self.step == "identity":
                raise self._fail(
                    f"no answer to the SDO read of {self.object_name(index, sub)} {waited} ({timed_out}). "
                    f"Check that the drive is powered, wired and terminated, and set to node id "
                    f"{self.node.node_id} and {self.bus.bitrate // 1000} kbit/s. Nothing was written to it.",
                    cia301.SDO_TIMED_OUT,
                ) from exc
            raise self._fail(
                f"stopped answering SDO ({action} {self.object_name(index, sub)}: no answer {waited}; {timed_out}). "
                f"Check its power and wiring. {self._left()}",
                cia301.SDO_TIMED_OUT,
            ) from exc

    def object_name(self, index: int, sub: int) -> str:
        """0xIIII:SS and the object's name in the node's EDS (loaded only when a message needs it)."""
        where = f"0x{index:04X}:{sub:02X}"
        if self._od is None:
            self._od = canopen.ObjectDictionary()
            if self.node.eds is not None:
                with contextlib.suppress(Exception):  # a name is a courtesy: an unreadable EDS leaves the number
                    self._od = canopen.import_od(str(self.cfg.path(self.node.eds)))
        try:
            obj = self._od[index]
        except KeyError:
            return where
        if isinstance(obj, canopen.objectdictionary.ODVariable):
            return f"{where} ({obj.name})"
        var = obj.subindices.get(sub)
        return f"{where} ({obj.name}" + (f", {var.name})" if var is not None else ")")

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
    sdo_timeout_s: float | None = None,
    interpolation: bool = True,
    disable_unused: bool = True,
    start: bool = True,
) -> SetupReport:
    """Configure the CANopen slaves of `bus_name` (the config's only CANopen bus by default) over SDO as runtime.json
    says, read it back, and start the nodes that passed. Each node's identity is checked first: the one `identities`
    gives for it, else runtime.json's node.identity; a node with neither is not checked (for a runtime.json written
    before node.identity, pass identities_from_dir). `interpolation` writes the start-up SDO values (node.sdo_init).
    Each SDO request waits `sdo_timeout_s`, else the node's sdo_timeout_ns, and is repeated sdo_retries times.
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
            results.append(
                configure_node(
                    cfg,
                    network,
                    node,
                    bus=co_bus,
                    identity=(identities or {}).get(node.name),
                    sdo_timeout_s=sdo_timeout_s,
                    interpolation=interpolation,
                    disable_unused=disable_unused,
                    start=start,
                )
            )
    finally:
        network.notifier.stop(timeout=2.0)
        network.notifier = None
    return SetupReport(co_bus.name, tuple(results))


def configure_node(
    cfg: RuntimeConfig,
    network: canopen.Network,
    node: Node,
    *,
    bus: Bus,
    identity: Identity | None = None,
    sdo_timeout_s: float | None = None,
    interpolation: bool = True,
    disable_unused: bool = True,
    start: bool = True,
) -> NodeSetup:
    """One node's set-up (configure_network's steps) over `network`, whose frames reach it through a Notifier or
    through whoever calls network.notify (the live master re-configuring a drive that rebooted while it cycles)."""
    assert node.node_id is not None
    remote = canopen.RemoteNode(node.node_id, canopen.ObjectDictionary())
    remote.sdo.RESPONSE_TIMEOUT = sdo_timeout_s if sdo_timeout_s is not None else node.sdo_timeout_ns / 1e9
    remote.sdo.MAX_RETRIES = node.sdo_retries + 1  # canopen counts the first request among its "retries"
    network.add_node(remote)
    try:
        job = _NodeConfigurator(
            cfg, bus, node, remote, identity or identity_from_runtime(cfg, node), interpolation, disable_unused
        )
        return _configure_node(job, start, network.notifier)
    finally:
        del network[node.node_id]


def _configure_node(job: _NodeConfigurator, start: bool, notifier: can.Notifier | None = None) -> NodeSetup:
    node, remote = job.node, job.remote
    assert node.node_id is not None
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
        text = cia301.sdo_abort_text(exc.code)
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
