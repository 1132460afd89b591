"""CANopen (CiA 301): the SYNC settings of a bus, device profiles, SYNC-driven tasks, PDO timing by transmission
type, default COB-IDs, the implicit SYNC and heartbeat messages and the identifiers the services reserve. The PDO
maps themselves are checked in `netcfg.protocols.canopen.pdo`."""

from __future__ import annotations

import dataclasses
import pathlib
from typing import TYPE_CHECKING

from netcfg import cia301, model
from netcfg.devices import DATA_TYPE_CODES, DeviceProfile, ObjectEntry, builtin_profile, builtin_profile_names
from netcfg.devices.eds import EdsError, cached_profile
from netcfg.diagnostics import Position
from netcfg.inputs import check_input_path
from netcfg.links.canfd import OverCanLinks
from netcfg.protocols.canopen import pdo as pdo_map
from netcfg.protocols.canopen.services import fd_services
from netcfg.rules import Rate
from netcfg.spec import schema
from netcfg.spec.source import Path
from netcfg.spec.suggest import did_you_mean
from netcfg.spec.units import format_ns

if TYPE_CHECKING:
    from netcfg.rules import Resolution


class CanopenRules(OverCanLinks):  # over classical CAN (CiA 301) or CAN FD (CANopen FD, CiA 1301)
    name = "canopen"
    section = "canopen"
    device_nodes = True

    def resolve_bus(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        super().resolve_bus(b, bus, path)
        self.resolve_canopen(b, bus, path)

    def resolve_canopen(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        c: schema.CanopenParams | None = self.required_section(b, "CANopen", "{sync_period: 20 ms}", path)
        if c is None:
            return
        cpath = (*path, "canopen")
        period = self.r.ns(c.sync_period, (*cpath, "sync_period"), None)
        window = self.r.ns(c.sync_window, (*cpath, "sync_window"), None)
        read = self.r.ns(c.read_window, (*cpath, "read_window"), None)
        if period is None:
            return
        if period == 0 or period % 1000:
            self.r.err(
                "sync-period",
                "the SYNC period (0x1006) is a whole, positive number of microseconds",
                (*cpath, "sync_period"),
            )
        for name, value in (("sync_window", window), ("read_window", read)):
            if value is not None and value > period:
                self.r.err(
                    "sync-window",
                    f"{name} {format_ns(value)} is longer than the SYNC period {format_ns(period)}",
                    (*cpath, name),
                )
        producer = self.section_master(
            b, c.sync_producer, cpath, "sync_producer", "SYNC producer", "CANopen", "sync-producer"
        )
        if producer is None:
            return
        # CiA 301 0x1019: 0 (no counter) or an overflow value 2..240; `true` takes the largest
        overflow = 240 if c.sync_counter is True else int(c.sync_counter)
        if c.sync_counter is not False and not 2 <= overflow <= 240:
            self.r.err(
                "sync-counter",
                f"sync_counter {c.sync_counter} is no SYNC counter overflow value (0x1019): write true or 2..240",
                (*cpath, "sync_counter"),
            )
            overflow = 0
        bus.canopen = model.CanopenBus(
            sync_period_ns=period,
            sync_window_ns=window,
            read_window_ns=read,
            sync_producer=producer,
            sync_id=c.sync_id,
            master_jitter_ns=self.r.ns(c.master_jitter, (*cpath, "master_jitter"), None) or 0,
            sync_overflow=overflow,
        )

    def resolve_items(self) -> None:
        self.check_sync_ids()
        self.add_implicit_messages()

    def resolve_pdo(
        self, m: schema.Message, sbus: schema.Bus, bus: model.Bus, path: Path
    ) -> tuple[model.Pdo, tuple[model.Signal, ...]] | None:
        return pdo_map.resolve_pdo(self.r, m, sbus, bus, path)

    def pdo_timing(self, pdo: model.Pdo, bus: model.Bus, rate: Rate, path: Path, jitter: int = 0) -> Rate | None:
        # CANopen PDOs: the transmission type says when a TPDO goes out (CiA 301, 0x1800 sub 2).
        if pdo.kind != "tpdo" or bus.canopen is None:
            return rate
        kind, period, mit = rate
        sync = bus.canopen.sync_period_ns
        tt = pdo.transmission
        if 1 <= tt <= 240 and period is not None and period != tt * sync:
            self.r.err(
                "period",
                f"transmission type {tt} sends on every {tt}. SYNC, i.e. every "
                f"{format_ns(tt * sync)}; the period {format_ns(period)} disagrees (drop it)",
                (*path, "period"),
            )
        timing = cia301.tpdo_timing(tt, sync, pdo.event_timer_ms, pdo.inhibit_100us, kind, period, mit, jitter)
        if timing[0] == "sporadic" and timing[2] is None and pdo.event_timer_ms:
            node = self.r.model.nodes.get(pdo.node)
            dev = node.device if node is not None else None
            if dev is not None and not dev.tpdo_event_timer:
                return None  # a timer the device lacks is reported at the PDO
            fix = (
                "give it an 'inhibit' time (the shortest gap the bus can take; the device holds every send to it)"
                if dev is None or dev.tpdo_inhibit_time
                else f"device {dev.name} has no inhibit time, so drop the event timer and give 'min_interarrival'"
            )
            said = ", whatever 'min_interarrival' says of the application," if mit is not None else ""
            self.r.err(
                "event-timer",
                f"TPDO {pdo.number} (transmission type {tt}) is sent on every application event and whenever its "
                f"event timer runs out; the timer may run out just before an application event{said} so only an "
                f"inhibit time (0x18xx sub-index 3) bounds how often it is sent: {fix}, or say 'type: on-demand' if "
                "application events come only at start-up and mode changes",
                (*path, "pdo", "event_timer"),
            )
            return None
        return timing

    def message_id(self, m: schema.Message, pdo: model.Pdo | None, path: Path) -> int | None:
        ident = m.id
        if pdo is not None and ident is None:
            node = self.r.spec_nodes[pdo.node]
            if node.node_id is None or node.node_id not in cia301.NODE_IDS:
                return None  # a missing or wrong node id is reported at the node; the default follows once it is fixed
            ident = cia301.default_pdo_cob_id(pdo.kind, pdo.number, node.node_id)
            if ident is None:
                self.r.err(
                    "id-missing",
                    f"{pdo.kind.upper()} {pdo.number} has no CiA 301 default COB-ID (only PDOs 1-4 "
                    "have one); give an explicit 'id'",
                    path,
                )
        return ident

    def id_source_node(self, m: model.Message) -> str | None:
        if m.implicit == "heartbeat":
            return m.producer
        if m.pdo is not None and not self.r.smap.has((*m.path, "id")):
            return m.pdo.node  # the CiA 301 default COB-ID of its device's PDO
        return None

    def reserved_ids(self, bus: model.Bus) -> dict[tuple[bool, int], str]:
        taken: dict[tuple[bool, int], str] = {}
        if bus.canopen is not None:
            taken[(False, cia301.NMT_ID)] = "NMT"
            for name in bus.nodes:
                node = self.r.model.nodes.get(name)
                if node is None or node.node_id is None or node.node_id not in cia301.NODE_IDS:
                    continue
                for service, cob in cia301.node_services(node.node_id).items():
                    if service.startswith("heartbeat") and node.heartbeat_ns:
                        continue  # the implicit heartbeat message below claims it
                    taken.setdefault((False, cob), f"{service} of node '{name}' (id {node.node_id})")
            for lss in cia301.LSS_IDS:
                taken.setdefault((False, lss), "LSS")
        return taken

    def check_message_id(self, bus: model.Bus, m: model.Message) -> None:
        if bus.canopen is not None and m.pdo is not None and not m.extended and cia301.restricted(m.id):
            self.r.err(
                "restricted-id",
                f"COB-ID 0x{m.id:03X} is restricted by CiA 301 (reserved for NMT, "
                "SYNC/EMCY, TIME, SDO, heartbeat or LSS); PDOs must not use it",
                self.r.key_or_item(m.path, "id"),
            )

    def check_sync_ids(self) -> None:
        """A device whose COB-ID SYNC (0x1005) is constant cannot follow another SYNC identifier."""
        for bus in self.r.model.buses.values():
            if bus.canopen is None:
                continue
            for name in bus.nodes:
                node = self.r.model.nodes.get(name)
                entry = node.device.lookup(0x1005, 0) if node and node.device else None
                fixed = entry is not None and entry.access == "const" and entry.default is not None
                if fixed and entry.default & 0x7FF != bus.canopen.sync_id:  # type: ignore[union-attr,operator]
                    self.r.err(
                        "sync-id",
                        f"device {node.device.name} of '{name}' has a fixed COB-ID SYNC (0x1005) of "  # type: ignore[union-attr]
                        f"0x{entry.default & 0x7FF:03X}; bus '{bus.name}' uses 0x{bus.canopen.sync_id:03X}",  # type: ignore[union-attr,operator]
                        (*bus.path, "canopen", "sync_id"),
                    )

    def add_implicit_messages(self) -> None:
        """CANopen buses carry SYNC and heartbeats that the spec does not list as messages."""
        for bus in self.r.model.buses.values():
            if bus.canopen is None:
                continue
            co = bus.canopen
            size = 1 if co.sync_overflow else 0  # the counter byte
            fd = fd_services(bus)
            others = tuple(n for n in bus.nodes if n != co.sync_producer)
            cpath: Path = (*bus.path, "canopen")
            sync = model.Message(
                name=f"{bus.name}_SYNC",
                bus=bus.name,
                producer=co.sync_producer,
                consumers=others or (co.sync_producer,),
                id=co.sync_id,
                extended=False,
                size=size,
                kind="periodic",
                period_ns=co.sync_period_ns,
                interval_ns=co.sync_period_ns,
                offset_ns=0,
                offset_auto=False,
                deadline_ns=co.sync_window_ns or co.sync_period_ns,
                jitter_ns=0,
                path=cpath,
                implicit="SYNC",
                fd=fd,
                brs=fd,
            )
            self.r.claim_implicit_name(sync.name, "the SYNC of bus " + bus.name)
            bus.messages.insert(0, sync)
            supervisors = self.r.model.canopen_masters(bus)
            for name in bus.nodes:
                node = self.r.model.nodes.get(name)
                if node is None or node.heartbeat_ns is None or node.node_id is None:
                    continue
                self.r.claim_implicit_name(f"{name}_heartbeat", f"the heartbeat of node {name}")
                bus.messages.append(
                    model.Message(
                        name=f"{name}_heartbeat",
                        bus=bus.name,
                        producer=name,
                        # the nodes whose consumer heartbeat times (0x1016) list it, as the DCFs configure them
                        consumers=tuple(s for s in supervisors if s != name)
                        if node.heartbeat_timeout_ns is not None
                        else (),
                        id=cia301.HEARTBEAT_BASE + node.node_id,
                        extended=False,
                        size=1,
                        kind="periodic",
                        period_ns=node.heartbeat_ns,
                        interval_ns=node.heartbeat_ns,
                        offset_ns=None,
                        offset_auto=False,
                        deadline_ns=node.heartbeat_ns,
                        jitter_ns=0,
                        path=(*node.path, "heartbeat"),
                        implicit="heartbeat",
                        fd=fd,
                        brs=fd,
                    )
                )


def load_device(r: Resolution, n: schema.Node, path: Path, on_canopen: bool) -> DeviceProfile | None:
    if n.device is None:
        return None
    dpath = (*path, "device")
    if not on_canopen:
        if all(b in r.spec_buses for b in n.buses):  # an unknown bus is reported on its own
            r.err("wrong-section", "device profiles describe CANopen devices; this node is on no CANopen bus", dpath)
        return None
    if isinstance(n.device, (str, schema.ProfileDevice)):
        name = n.device if isinstance(n.device, str) else n.device.profile
        try:
            base = builtin_profile(name)
        except KeyError:
            r.err(
                "unknown-device",
                f"no built-in device profile '{name}'{did_you_mean(name, builtin_profile_names())}; built-in: "
                f"{', '.join(builtin_profile_names())}, or give a vendor file as 'device: {{eds: x.eds}}'",
                dpath if isinstance(n.device, str) else (*dpath, "profile"),
            )
            return None
        return base if isinstance(n.device, str) else _with_objects(r, base, n.device, dpath)
    assert isinstance(n.device, schema.EdsDevice)  # an actuator profile is netcfg.resolve.actuators'
    try:  # the input guard: a NUL byte, a symlink loop or a missing file is placed at the spec's line
        file = check_input_path(r.spec_dir, n.device.eds, "EDS file")
    except ValueError as exc:
        r.err("eds-missing", str(exc), (*dpath, "eds"))
        return None
    try:
        profile = cached_profile(file, n.device.eds)
        return dataclasses.replace(profile, source=n.device.eds)  # name the file as the spec wrote it
    except EdsError as exc:
        if exc.line is None:
            r.err("eds-invalid", f"{n.device.eds}: {exc}", (*dpath, "eds"))
        else:  # at the device file's own line, the spec's naming it alongside
            named = r.smap.at((*dpath, "eds"))
            eds_file = str(pathlib.PurePath(named.file).parent / n.device.eds)
            r.d.add(
                "eds-invalid",
                f"{exc} (device file of node '{n.name}', named at {named.file}:{named.line}:{named.column}); fix the "
                "value or ask the vendor for a corrected file",
                Position(eds_file, exc.line, exc.column or 1),
            )
        return None


def _with_objects(r: Resolution, base: DeviceProfile, device: schema.ProfileDevice, dpath: Path) -> DeviceProfile:
    """A built-in profile with the spec's own application objects: not the built-in one any more (its EDS is the
    spec's, so bus.yml and the DCF comments do not call it by the profile's name)."""
    objects = dict(base.objects)
    for i, o in enumerate(device.objects):
        key = (o.index, o.sub)
        if key in objects:
            r.err(
                "device-object",
                f"object 0x{o.index:04X}:{o.sub} '{o.name}' is already in profile '{device.profile}' as "
                f"'{objects[key].name}'; give each object once",
                (*dpath, "objects", i, "index"),
            )
            continue
        objects[key] = ObjectEntry(
            index=o.index,
            sub=o.sub,
            name=o.name,
            data_type=DATA_TYPE_CODES[o.type],
            access=o.access,
            pdo_mappable=o.pdo,
            default=o.default,
        )
    return dataclasses.replace(base, name=base.name, source=f"spec:{device.profile}", objects=objects)


def device_has_heartbeat(r: Resolution, dev: DeviceProfile | None, hb_ns: int, path: Path) -> bool:
    """A node's heartbeat is its producer heartbeat time (0x1017), which the DCF sets and the master writes by SDO: the
    device must have it writable, or hold that very value, as the event timer is checked against 0x18xx sub 5."""
    if dev is None:
        return True
    entry = dev.lookup(cia301.HEARTBEAT_TIME, 0)
    if entry is not None and (entry.writable or entry.default == hb_ns // 1_000_000):
        return True
    why = "has no producer heartbeat time (0x1017)" if entry is None else f"has 0x1017 {entry.access} (not writable)"
    r.err(
        "heartbeat",
        f"device {dev.name} ({dev.source}) {why}: it cannot send this heartbeat, and the master's SDO write of it "
        "would abort; drop 'heartbeat' from this node",
        path,
    )
    return False
