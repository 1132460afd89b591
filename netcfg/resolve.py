"""Spec -> Model: fill in defaults (identifiers, periods, FTT ids, device objects) and check everything that
needs more than one item to decide: references, identifiers, PDO maps against device dictionaries, EC
multiples, offsets. Like a linter, it reports every problem it finds, not just the first.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Iterable
from pathlib import Path as FsPath
from typing import Any, Literal

from netcfg import cia301, model
from netcfg.devices import DATA_TYPES, DeviceProfile, builtin_profile, builtin_profile_names
from netcfg.devices.eds import EdsError, import_eds
from netcfg.diagnostics import Collector
from netcfg.spec import schema
from netcfg.spec.source import Path, SourceMap
from netcfg.spec.units import Duration, format_ns
from netcfg.timing.frames import APP_ID_BYTES, CAN_MAX_PAYLOAD, MAX_UDP_PAYLOAD
from netcfg.timing.ftt import tm_time_ns
from netcfg.timing.offsets import derive_offsets

CAN_PROTOCOLS = ("can", "canopen", "ftt-can")
MAX_CAN_BITRATE = 1_000_000  # classical CAN, ISO 11898-1
_OBJECT_REF = re.compile(r"^\s*(0x[0-9A-Fa-f]{1,4}|[0-9]{1,5})\s*(?:(?::|sub)\s*(0x[0-9A-Fa-f]{1,2}|[0-9]{1,3}))?\s*$")
# CiA 301 dummy mapping: index 0x0001-0x0007 stands for a data type, to skip bytes in an RPDO.


def resolve(spec: schema.Spec, smap: SourceMap, diags: Collector, spec_dir: FsPath) -> model.Model | None:
    """Build the Model; returns None (with errors in diags) when the spec is inconsistent."""
    r = _Resolver(spec, smap, diags, spec_dir)
    r.run()
    if diags.errors:
        return None
    return r.model


def snake(text: str) -> str:
    """'Position actual value' -> 'position_actual_value', the signal name of a mapped device object; a name
    check_name refuses gets 'obj_' in front ('1st' -> 'obj_1st') or '_obj' behind ('Switch' -> 'switch_obj')."""
    return schema.safe_name(re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_").lower(), "obj", "_obj")


class _Resolver:
    def __init__(self, spec: schema.Spec, smap: SourceMap, diags: Collector, spec_dir: FsPath):
        self.spec = spec
        self.smap = smap
        self.d = diags
        self.spec_dir = spec_dir
        self.model = model.Model(
            system=spec.system,
            description=spec.description,
            file=smap.file,
            source=smap,
            buses={},
            nodes={},
            messages={},
            triggers={},
            flows={},
        )
        self.spec_nodes = {n.name: n for n in spec.nodes}
        self.spec_buses = {b.name: b for b in spec.buses}

    # -- helpers -------------------------------------------------------------------------------------------
    def err(self, code: str, message: str, path: Path) -> None:
        self.d.add(code, message, self.smap.at(path))

    def warn(self, code: str, message: str, path: Path) -> None:
        self.d.add(code, message, self.smap.at(path), "warning")

    def key_or_item(self, path: Path, key: str) -> Path:
        """The key's path when the spec wrote it, else the item's (for values netcfg derived)."""
        return (*path, key) if self.smap.has((*path, key)) else path

    def ns(self, value: Duration | None, path: Path, ec_ns: int | None) -> int | None:
        """Duration -> ns; EC counts need an FTT-CAN bus to give them a length."""
        if value is None:
            return None
        out = value.to_ns(ec_ns)
        if out is None:
            self.err("ec-unit", f"'{value}' is in elementary cycles, which only FTT-CAN buses have; use ms or us", path)
        return out

    def check_offset(self, offset: int | None, period: int | None, path: Path, what: str = "the period") -> None:
        """An offset shifts releases within one period (path: the item with the 'offset' key)."""
        if offset is not None and period is not None and offset >= period:
            self.err(
                "offset",
                f"offset {format_ns(offset)} must be smaller than {what} {format_ns(period)}",
                (*path, "offset"),
            )

    def period_range(
        self, given: tuple[Duration, Duration], period: int | None, path: Path, ec: int | None
    ) -> int | None:
        """FTT-CAN on-line rate adaptation (messages and triggers): [fastest, slowest] around the period, both
        whole numbers of ECs. -> the fastest period, or None when a bound could not be read."""
        rpath = (*path, "period_range")
        lo = self.ns(given[0], (*rpath, 0), ec)
        hi = self.ns(given[1], (*rpath, 1), ec)
        if lo is None or hi is None or period is None:
            return None
        if not 0 < lo <= period <= hi:
            self.err(
                "period-range",
                f"need 0 < fastest <= period <= slowest; got {format_ns(lo)}, {format_ns(period)}, {format_ns(hi)}",
                rpath,
            )
        for k, v in enumerate((lo, hi)):
            if ec and v % ec:
                self.err("ec-multiple", f"{format_ns(v)} is not a whole number of ECs ({format_ns(ec)})", (*rpath, k))
        return lo

    def ec_of(self, bus_names: Iterable[str]) -> int | None:
        ecs = [b.ftt.ec.ns for n in bus_names if (b := self.spec_buses.get(n)) and b.ftt and b.ftt.ec.ns]
        return ecs[0] if len(ecs) == 1 else None

    # -- the passes ----------------------------------------------------------------------------------------
    def run(self) -> None:
        self.check_unique_names()
        self.resolve_buses()
        self.resolve_nodes()
        self.resolve_messages()
        self.check_sync_ids()
        self.add_implicit_messages()
        self.resolve_triggers()
        self.check_tasks_activated()
        self.check_identifiers()
        self.resolve_topologies()
        self.resolve_flows()
        if not self.d.errors:
            derive_offsets(self.model, self.err)

    def check_unique_names(self) -> None:
        kinds: list[tuple[str, list[tuple[str, Any]]]] = [
            ("bus", [(b.name, ("buses", i, "name")) for i, b in enumerate(self.spec.buses)]),
            (
                "node or switch",
                [(n.name, ("nodes", i, "name")) for i, n in enumerate(self.spec.nodes)]
                + [
                    (s.name, ("buses", i, "ethernet", "switches", j, "name"))
                    for i, b in enumerate(self.spec.buses)
                    if b.ethernet
                    for j, s in enumerate(b.ethernet.switches)
                ],
            ),
            (
                "message or trigger",
                [(m.name, ("messages", i, "name")) for i, m in enumerate(self.spec.messages)]
                + [(t.name, ("triggers", i, "name")) for i, t in enumerate(self.spec.triggers)],
            ),
            ("flow", [(f.name, ("flows", i, "name")) for i, f in enumerate(self.spec.flows)]),
        ]
        for i, n in enumerate(self.spec.nodes):
            kinds.append(
                (f"task of node {n.name}", [(t.name, ("nodes", i, "tasks", j, "name")) for j, t in enumerate(n.tasks)])
            )
        for kind, items in kinds:
            seen: dict[str, str] = {}
            for name, path in items:
                key = name.lower()  # generated file names must differ on case-insensitive file systems too
                if key in seen:
                    same = "" if seen[key] == name else f" (as '{seen[key]}': names may differ only in case)"
                    self.err("duplicate-name", f"{kind} name '{name}' is used twice{same}; rename one", path)
                else:
                    seen[key] = name

    def resolve_buses(self) -> None:
        for i, b in enumerate(self.spec.buses):
            path: Path = ("buses", i)
            sections = {"ftt-can": "ftt", "canopen": "canopen", "ethernet-udp": "ethernet"}
            for proto, key in sections.items():
                if getattr(b, key) is not None and b.protocol != proto:
                    self.err(
                        "wrong-section",
                        f"bus '{b.name}' is {b.protocol}; '{key}:' belongs to {proto} buses",
                        (*path, key),
                    )
            if b.protocol in CAN_PROTOCOLS and b.bitrate > MAX_CAN_BITRATE:
                self.err(
                    "bitrate",
                    f"classical CAN runs at most 1 Mbit/s; bus '{b.name}' says {b.bitrate} bit/s",
                    (*path, "bitrate"),
                )
            bus = model.Bus(
                description=b.description,
                name=b.name,
                protocol=b.protocol,
                bitrate=b.bitrate,
                id_bits=b.id_bits,
                nodes=[n.name for n in self.spec.nodes if b.name in n.buses],
                messages=[],
                path=path,
            )
            if b.protocol == "ftt-can":
                self.resolve_ftt(b, bus, path)
            elif b.protocol == "canopen":
                self.resolve_canopen(b, bus, path)
            elif b.protocol == "ethernet-udp" and b.ethernet:
                bus.switches = [
                    model.Switch(
                        s.name, {p.port: p.to for p in s.ports}, {p.port: p.cable for p in s.ports}, s.latency.ns or 0
                    )
                    for s in b.ethernet.switches
                ]
            self.model.buses[b.name] = bus

    def masters(self, bus: str) -> list[str]:
        return [n.name for n in self.spec.nodes if bus in n.buses and n.role == "master"]

    def resolve_ftt(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        if b.ftt is None:
            self.err("missing-section", f"FTT-CAN bus '{b.name}' needs 'ftt: {{ec: 5 ms, tm_size: 5}}'", path)
            return
        f = b.ftt
        fpath = (*path, "ftt")
        if f.ec.ns is None or f.ec.ns == 0:
            self.err("ec", "the elementary cycle needs a length in time units, e.g. 'ec: 5 ms'", (*fpath, "ec"))
            return
        ec = f.ec.ns
        lsw = self.ns(f.lsw, (*fpath, "lsw"), ec)
        tm_ns = tm_time_ns(f.tm_size, b.id_bits == 29, b.bitrate)
        if lsw is not None and lsw + tm_ns > ec:
            self.err(
                "lsw",
                f"LSW {format_ns(lsw)} plus the trigger message ({format_ns(tm_ns)}) exceeds the "
                f"EC of {format_ns(ec)}; shorten the LSW",
                (*fpath, "lsw"),
            )
        master = f.master
        if master is None:
            ms = self.masters(b.name)
            if len(ms) != 1:
                self.err(
                    "ftt-master",
                    f"FTT-CAN bus '{b.name}' needs one node with 'role: master' (found "
                    f"{len(ms)}) or 'ftt: {{master: <node>}}'",
                    fpath,
                )
                return
            master = ms[0]
        elif master not in self.spec_nodes or b.name not in self.spec_nodes[master].buses:
            self.err("unknown-node", f"FTT-CAN master '{master}' is not a node on bus '{b.name}'", (*fpath, "master"))
            return
        bus.ftt = model.FttBus(
            ec_ns=ec, tm_size=f.tm_size, lsw_ns=ec - tm_ns if lsw is None else lsw, tm_id=f.tm_id, master=master
        )

    def resolve_canopen(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        if b.canopen is None:
            self.err("missing-section", f"CANopen bus '{b.name}' needs 'canopen: {{sync_period: 20 ms}}'", path)
            return
        c = b.canopen
        cpath = (*path, "canopen")
        period = self.ns(c.sync_period, (*cpath, "sync_period"), None)
        window = self.ns(c.sync_window, (*cpath, "sync_window"), None)
        read = self.ns(c.read_window, (*cpath, "read_window"), None)
        if period is None:
            return
        if period == 0 or period % 1000:
            self.err(
                "sync-period",
                "the SYNC period (0x1006) is a whole, positive number of microseconds",
                (*cpath, "sync_period"),
            )
        for name, value in (("sync_window", window), ("read_window", read)):
            if value is not None and value > period:
                self.err(
                    "sync-window",
                    f"{name} {format_ns(value)} is longer than the SYNC period {format_ns(period)}",
                    (*cpath, name),
                )
        producer = c.sync_producer
        if producer is None:
            ms = self.masters(b.name)
            if len(ms) != 1:
                self.err(
                    "sync-producer",
                    f"CANopen bus '{b.name}' needs one node with 'role: master' (found "
                    f"{len(ms)}) or 'canopen: {{sync_producer: <node>}}'",
                    cpath,
                )
                return
            producer = ms[0]
        elif producer not in self.spec_nodes or b.name not in self.spec_nodes[producer].buses:
            self.err(
                "unknown-node", f"SYNC producer '{producer}' is not a node on bus '{b.name}'", (*cpath, "sync_producer")
            )
            return
        bus.canopen = model.CanopenBus(
            sync_period_ns=period, sync_window_ns=window, read_window_ns=read, sync_producer=producer, sync_id=c.sync_id
        )

    def resolve_nodes(self) -> None:
        ids: dict[tuple[str, int], str] = {}
        for i, n in enumerate(self.spec.nodes):
            path: Path = ("nodes", i)
            for j, bname in enumerate(n.buses):
                if bname not in self.spec_buses:
                    self.err(
                        "unknown-bus",
                        f"node '{n.name}' sits on bus '{bname}', which is not defined; "
                        f"known buses: {', '.join(sorted(self.spec_buses)) or 'none'}",
                        (*path, "buses", j),
                    )
            if len(set(n.buses)) != len(n.buses):
                self.err("duplicate-name", f"node '{n.name}' lists the same bus twice", (*path, "buses"))
            protocols = {self.spec_buses[b].protocol for b in n.buses if b in self.spec_buses}
            on_canopen = "canopen" in protocols
            if n.node_id is not None:
                if on_canopen and n.node_id not in cia301.NODE_IDS:
                    self.err("node-id", f"CANopen node ids are 1..127; '{n.name}' has {n.node_id}", (*path, "node_id"))
                elif not 0 <= n.node_id <= 255:
                    self.err("node-id", f"node ids are 0..255; '{n.name}' has {n.node_id}", (*path, "node_id"))
                for bname in n.buses:
                    key = (bname, n.node_id)
                    if key in ids:
                        self.err(
                            "duplicate-node-id",
                            f"node id {n.node_id} of '{n.name}' is already used by '{ids[key]}' on bus '{bname}'",
                            (*path, "node_id"),
                        )
                    ids[key] = n.name
            elif on_canopen:
                self.err("node-id", f"node '{n.name}' is on a CANopen bus and needs a node_id (1..127)", path)
            device = self.load_device(n, path, on_canopen)
            if n.heartbeat is not None and not on_canopen:
                self.err(
                    "wrong-section",
                    "heartbeat is a CANopen service; this node is on no CANopen bus",
                    (*path, "heartbeat"),
                )
            hb = self.ns(n.heartbeat, (*path, "heartbeat"), None)
            if hb is not None and (hb % 1_000_000 or hb > 65_535_000_000):
                self.err(
                    "heartbeat",
                    "the heartbeat time (0x1017) is whole milliseconds, at most 65535 ms",
                    (*path, "heartbeat"),
                )
            if n.ip is not None and any(int(p) > 255 for p in n.ip.split(".")):
                self.err("ip", f"'{n.ip}' is not an IPv4 address", (*path, "ip"))
            ec = self.ec_of(n.buses)
            tasks = {}
            for j, t in enumerate(n.tasks):
                tasks[t.name] = self.resolve_task(n.name, t, (*path, "tasks", j), ec)
            self.model.nodes[n.name] = model.Node(
                description=n.description,
                name=n.name,
                node_id=n.node_id,
                buses=tuple(n.buses),
                role=n.role,
                device=device,
                heartbeat_ns=hb or None,
                ip=n.ip,
                tasks=tasks,
                path=path,
                tx_delay_ns=self.ns(n.tx_delay, (*path, "tx_delay"), None) or 0,
                rx_delay_ns=self.ns(n.rx_delay, (*path, "rx_delay"), None) or 0,
            )

    def load_device(self, n: schema.Node, path: Path, on_canopen: bool) -> DeviceProfile | None:
        if n.device is None:
            return None
        dpath = (*path, "device")
        if not on_canopen:
            self.err("wrong-section", "device profiles describe CANopen devices; this node is on no CANopen bus", dpath)
            return None
        if isinstance(n.device, str):
            try:
                return builtin_profile(n.device)
            except KeyError:
                self.err(
                    "unknown-device",
                    f"no built-in device profile '{n.device}'; built-in: "
                    f"{', '.join(builtin_profile_names())}, or give a vendor file as 'device: {{eds: x.eds}}'",
                    dpath,
                )
                return None
        file = (self.spec_dir / n.device.eds).resolve()
        if not file.is_file():
            self.err(
                "eds-missing",
                f"EDS file '{n.device.eds}' not found (looked for {file}); paths are relative to the spec",
                (*dpath, "eds"),
            )
            return None
        try:
            profile = _cached_eds(str(file), file.stat().st_mtime_ns, n.device.eds)
            return dataclasses.replace(profile, source=n.device.eds)  # name the file as the spec wrote it
        except EdsError as exc:
            self.err("eds-invalid", f"{n.device.eds}: {exc}", (*dpath, "eds"))
            return None

    def resolve_task(self, node: str, t: schema.Task, path: Path, ec: int | None) -> model.Task:
        period = self.ns(t.period, (*path, "period"), ec)
        offset = self.ns(t.offset, (*path, "offset"), ec) or 0
        wcet = self.ns(t.wcet, (*path, "wcet"), ec) or 0
        bcet = self.ns(t.bcet, (*path, "bcet"), ec)
        if wcet <= 0:
            self.err("wcet", f"task '{node}.{t.name}' needs a worst-case execution time above zero", (*path, "wcet"))
        if bcet is None:
            bcet = wcet
        elif bcet > wcet:
            self.err("bcet", f"best case {format_ns(bcet)} exceeds worst case {format_ns(wcet)}", (*path, "bcet"))
        if period is not None:
            if period <= 0:
                self.err("period", "a task period must be above zero", (*path, "period"))
            else:
                self.check_offset(offset, period, path)
                if wcet > period:
                    self.err(
                        "wcet",
                        f"WCET {format_ns(wcet)} exceeds the period {format_ns(period)}: the task can never keep up",
                        (*path, "wcet"),
                    )
        if t.on_message is not None and t.period is not None:
            self.err("task-period", "an event-driven task ('on_message') has no period", (*path, "period"))
        sync_bus = None
        if t.sync:
            sync_bus, period = self.sync_task(node, t, path, period)
            self.check_offset(offset, period, path, "the SYNC period")
        return model.Task(
            description=t.description,
            node=node,
            name=t.name,
            period_ns=period,
            offset_ns=offset,
            wcet_ns=wcet,
            bcet_ns=bcet,
            trigger=None,
            on_message=t.on_message,
            path=path,
            sync_bus=sync_bus,
        )

    def sync_task(self, node: str, t: schema.Task, path: Path, period: int | None) -> tuple[str | None, int | None]:
        """A SYNC-driven task takes its period from its node's CANopen bus."""
        buses = [b for b in self.spec_nodes[node].buses if b in self.model.buses and self.model.buses[b].canopen]
        if len(buses) != 1:
            self.err(
                "task-sync",
                f"task '{node}.{t.name}' runs on SYNC, so its node must be on exactly one CANopen "
                f"bus (it is on {len(buses)})",
                (*path, "sync"),
            )
            return None, period
        if t.on_message is not None:
            self.err("task-sync", "a task runs either on SYNC or on a message, not both", (*path, "sync"))
        sync_period = self.model.buses[buses[0]].canopen.sync_period_ns  # type: ignore[union-attr]
        if period is not None and period != sync_period:
            self.err(
                "task-period",
                f"a SYNC task runs every SYNC ({format_ns(sync_period)}); drop its period",
                (*path, "period"),
            )
        return buses[0], sync_period

    # -- messages ------------------------------------------------------------------------------------------
    def message_bus(self, m: schema.Message, path: Path) -> schema.Bus | None:
        ends = [m.producer, *m.consumers]
        for k, name in enumerate(ends):
            if name not in self.spec_nodes:
                where = (*path, "producer") if k == 0 else (*path, "consumers", k - 1)
                self.err(
                    "unknown-node",
                    f"message '{m.name}' names node '{name}', which is not defined; "
                    f"known nodes: {_some(self.spec_nodes)}",
                    where,
                )
        if any(name not in self.spec_nodes for name in ends):
            return None
        if m.bus is not None:
            if m.bus not in self.spec_buses:
                self.err(
                    "unknown-bus",
                    f"bus '{m.bus}' is not defined; known buses: {_some(self.spec_buses)}",
                    (*path, "bus"),
                )
                return None
            bus = self.spec_buses[m.bus]
        else:
            common = set(self.spec_nodes[m.producer].buses) & set(self.spec_buses)  # undefined ones are reported
            for c in m.consumers:
                common &= set(self.spec_nodes[c].buses)
            if len(common) != 1:
                self.err(
                    "which-bus",
                    f"message '{m.name}': producer and consumers share "
                    f"{'no bus' if not common else 'several buses'}; say 'bus: <name>'",
                    path,
                )
                return None
            bus = self.spec_buses[common.pop()]
        for k, name in enumerate(ends):
            if bus.name not in self.spec_nodes[name].buses:
                where = (*path, "producer") if k == 0 else (*path, "consumers", k - 1)
                self.err("not-on-bus", f"node '{name}' is not on bus '{bus.name}'; add the bus to its 'buses'", where)
        if m.producer in m.consumers:
            self.err("self-consumer", f"'{m.producer}' both produces and consumes '{m.name}'", (*path, "consumers"))
        if len(set(m.consumers)) != len(m.consumers):
            self.err("duplicate-name", "a consumer is listed twice", (*path, "consumers"))
        return bus

    def resolve_messages(self) -> None:
        for i, m in enumerate(self.spec.messages):
            path: Path = ("messages", i)
            sbus = self.message_bus(m, path)
            if sbus is None:
                continue
            bus = self.model.buses[sbus.name]
            msg = self.resolve_message(m, sbus, bus, path)
            if msg is not None:
                self.model.messages[msg.name] = msg
                bus.messages.append(msg)

    def resolve_message(self, m: schema.Message, sbus: schema.Bus, bus: model.Bus, path: Path) -> model.Message | None:
        proto = sbus.protocol
        ec = bus.ftt.ec_ns if bus.ftt else None
        if proto == "ftt-can" and bus.ftt is None:
            return None  # the bus error is reported already
        # --- what is sent: size, signals, PDO map
        pdo = None
        signals: tuple[model.Signal, ...] = ()
        size = m.size
        if m.pdo is not None:
            if proto != "canopen":
                self.err("wrong-section", f"PDOs exist on CANopen buses; '{sbus.name}' is {proto}", (*path, "pdo"))
                return None
            got = self.resolve_pdo(m, sbus, bus, path)
            if got is None:
                return None
            pdo, signals = got
            pdo_size = math.ceil(sum(e.bits for e in pdo.entries) / 8)
            if size is not None and size != pdo_size:
                self.err(
                    "size",
                    f"size {size} disagrees with the PDO map, which fills {pdo_size} bytes; drop 'size'",
                    (*path, "size"),
                )
            size = pdo_size
        if m.signals is not None:
            if pdo is not None:
                self.err("wrong-section", "give either a PDO map or signals, not both", (*path, "signals"))
            signals = self.layout_signals(m.signals, (*path, "signals"))
            sig_size = math.ceil(max((s.start_bit + s.bits for s in signals), default=0) / 8)
            if size is not None and size < sig_size:
                self.err("size", f"size {size} is too small for the signals ({sig_size} bytes)", (*path, "size"))
            size = max(size or 0, sig_size)
        if size is None:
            self.err("size", f"message '{m.name}' needs a payload: 'size: <bytes>', 'signals:' or a PDO map", path)
            return None
        if proto in CAN_PROTOCOLS and size > CAN_MAX_PAYLOAD:
            self.err(
                "payload",
                f"{size} bytes do not fit a classical CAN frame (at most 8); split the message",
                (*path, "size") if m.size is not None else path,
            )
        if proto == "ethernet-udp" and APP_ID_BYTES + size > MAX_UDP_PAYLOAD:
            self.err(
                "payload",
                f"{size} bytes plus the 1-byte message id exceed one unfragmented UDP datagram "
                f"({MAX_UDP_PAYLOAD} bytes)",
                (*path, "size"),
            )
        # --- when it is sent
        timing = self.resolve_timing(m, bus, pdo, path, ec)
        if timing is None:
            return None
        kind, period, interval, offset, offset_auto, rate = timing
        deadline = self.ns(m.deadline, (*path, "deadline"), ec)
        if deadline is not None and deadline <= 0:
            self.err("deadline", "a deadline must be above zero", (*path, "deadline"))
        if deadline is None:
            deadline = interval
        jitter = self.ns(m.jitter, (*path, "jitter"), ec) or 0
        # --- identifier
        extended = m.extended if m.extended is not None else (sbus.id_bits == 29)
        window = None
        ftt_id = None
        ident = m.id
        if proto == "ftt-can":
            window = m.window or ("sync" if kind == "periodic" else "async")
            if window == "sync":
                if kind != "periodic":
                    self.err(
                        "ftt-window",
                        "only periodic messages go in the synchronous window; make it 'window: "
                        "async' or give it a period",
                        (*path, "window"),
                    )
                ftt_id = m.ftt_id  # None -> assigned after all explicit ids are known
            elif m.ftt_id is not None:
                self.err("ftt-window", "ftt_id names synchronous messages; this one is asynchronous", (*path, "ftt_id"))
            if window == "async" and ident is None:
                self.err(
                    "id-missing",
                    "asynchronous FTT-CAN messages need an explicit CAN 'id' (lower = higher "
                    "priority in the asynchronous window)",
                    path,
                )
        else:
            for key in ("window", "ftt_id"):
                if getattr(m, key) is not None:
                    self.err(
                        "wrong-section", f"'{key}' is an FTT-CAN setting; bus '{sbus.name}' is {proto}", (*path, key)
                    )
        if pdo is not None and ident is None:
            node = self.spec_nodes[pdo.device_node]
            if node.node_id is not None and node.node_id in cia301.NODE_IDS:
                ident = cia301.default_pdo_cob_id(pdo.kind, pdo.number, node.node_id)
            if ident is None:
                self.err(
                    "id-missing",
                    f"{pdo.kind.upper()} {pdo.number} has no CiA 301 default COB-ID (only PDOs 1-4 "
                    "have one); give an explicit 'id'",
                    path,
                )
        if ident is None and proto in ("can", "canopen", "ethernet-udp"):
            what = "the application message id (Table 6.1 style, 0..255)" if proto == "ethernet-udp" else "a CAN id"
            if pdo is None:
                self.err("id-missing", f"message '{m.name}' needs an explicit 'id': {what}", path)
        if ident is not None:
            limit = 0xFF if proto == "ethernet-udp" else (0x1FFFFFFF if extended else 0x7FF)
            if ident > limit:
                width = "one byte" if limit == 0xFF else ("29 bits" if extended else "11 bits")
                self.err("id-range", f"id 0x{ident:X} does not fit {width} (max 0x{limit:X})", (*path, "id"))
        if proto == "ethernet-udp" and m.extended is not None:
            self.err("wrong-section", "'extended' is a CAN setting", (*path, "extended"))
        if m.udp is not None and proto != "ethernet-udp":
            self.err("wrong-section", "'udp' belongs to ethernet-udp buses", (*path, "udp"))
        return model.Message(
            name=m.name,
            bus=sbus.name,
            producer=m.producer,
            consumers=tuple(m.consumers),
            id=ident if ident is not None else -1,
            extended=bool(extended) and proto != "ethernet-udp",
            size=size,
            kind=kind,
            period_ns=period,
            interval_ns=interval,
            offset_ns=offset,
            offset_auto=offset_auto,
            deadline_ns=deadline,
            jitter_ns=jitter,
            path=path,
            window=window,
            ftt_id=ftt_id,
            pdo=pdo,
            signals=signals,
            rate_hz=rate,
            udp_ports=(m.udp.src_port, m.udp.dst_port) if m.udp else None,
            description=m.description,
        )

    def resolve_timing(self, m: schema.Message, bus: model.Bus, pdo: model.Pdo | None, path: Path, ec: int | None):
        """-> (kind, period, interval, offset, offset_auto, rate) or None."""
        period = self.ns(m.period, (*path, "period"), ec)
        mit = self.ns(m.min_interarrival, (*path, "min_interarrival"), ec)
        rate = m.rate
        if rate is not None:
            if period is not None:
                self.err("period", "give either 'period' or 'rate', not both", (*path, "rate"))
            period = round(1_000_000_000 / rate)  # at least 1: units.parse_frequency admits at most 1 GHz
        kind = m.type
        # CANopen PDOs: the transmission type says when a TPDO goes out (CiA 301, 0x1800 sub 2).
        if pdo is not None and pdo.kind == "tpdo" and bus.canopen is not None:
            sync = bus.canopen.sync_period_ns
            tt = pdo.transmission
            if 1 <= tt <= 240:
                derived = tt * sync
                if period is not None and period != derived:
                    self.err(
                        "period",
                        f"transmission type {tt} sends on every {tt}. SYNC, i.e. every "
                        f"{format_ns(derived)}; the period {format_ns(period)} disagrees (drop it)",
                        (*path, "period"),
                    )
                period, kind = derived, kind or "periodic"
            elif tt == 0 and period is None and mit is None:
                mit, kind = sync, kind or "sporadic"  # acyclic synchronous: at most once per SYNC
            elif tt >= 254 and pdo.event_timer_ms and period is None and mit is None:
                period, kind = pdo.event_timer_ms * 1_000_000, kind or "periodic"
            if pdo.inhibit_100us and kind != "periodic":
                inhibit = pdo.inhibit_100us * 100_000
                mit = max(mit or 0, inhibit)
        if kind is None:
            if period is not None:
                kind = "periodic"
            elif mit is not None:
                kind = "sporadic"
            else:
                self.err(
                    "message-type",
                    f"say how often '{m.name}' is sent: 'period: 10 ms', "
                    "'min_interarrival: 100 ms' (sporadic) or 'type: on-demand'",
                    path,
                )
                return None
        if kind == "periodic":
            if period is None:
                self.err("period", "a periodic message needs 'period' (or 'rate')", path)
                return None
            if period <= 0:
                self.err("period", "a period must be above zero", (*path, "period"))
                return None
            if mit is not None and m.min_interarrival is not None:
                self.err("message-type", "'min_interarrival' is for sporadic messages", (*path, "min_interarrival"))
        elif kind == "sporadic":
            if mit is None or mit <= 0:
                self.err("min-interarrival", "a sporadic message needs 'min_interarrival' above zero", path)
                return None
            if m.period is not None or m.rate is not None:
                self.err(
                    "message-type",
                    "sporadic messages have 'min_interarrival', not a period",
                    (*path, "period" if m.period is not None else "rate"),
                )
        else:  # on-demand
            for key in ("period", "rate", "min_interarrival", "period_range"):
                if getattr(m, key) is not None:
                    self.err("message-type", f"on-demand messages have no '{key}'", (*path, key))
        interval = period if kind == "periodic" else mit
        # FTT-CAN on-line rate adaptation: the load and the analysis use the fastest admissible period.
        if m.period_range is not None:
            if bus.protocol != "ftt-can" or kind != "periodic":
                self.err("period-range", "period_range is for periodic FTT-CAN messages", (*path, "period_range"))
            else:
                fastest = self.period_range(m.period_range, period, path, ec)
                interval = interval if fastest is None else fastest
        offset_auto = m.offset == "auto"
        offset = None
        if isinstance(m.offset, Duration):
            offset = self.ns(m.offset, (*path, "offset"), ec)
        if m.offset is not None and kind != "periodic":
            self.err("offset", "only periodic messages have an offset", (*path, "offset"))
        if offset_auto and bus.protocol != "ftt-can":
            self.err(
                "offset",
                "'offset: auto' is derived from FTT-CAN flows; give this message a duration",
                (*path, "offset"),
            )
        self.check_offset(offset, period, path)
        if bus.protocol == "ftt-can" and ec and kind == "periodic" and (m.window or "sync") == "sync":
            for key, value in (("period", period), ("offset", offset)):
                if value is not None and value % ec:
                    self.err(
                        "ec-multiple",
                        f"{key} {format_ns(value)} is not a whole number of elementary cycles "
                        f"({format_ns(ec)}); use a multiple such as {format_ns(max(ec, value // ec * ec))}",
                        (*path, key if key != "period" or m.rate is None else "rate"),
                    )
            if offset is None and not offset_auto:
                offset = 0
        return kind, (period if kind == "periodic" else None), interval, offset, offset_auto, rate

    def parse_object_ref(self, ref: int | str, path: Path) -> tuple[int, int] | None:
        if isinstance(ref, bool):
            ref = str(ref)
        if isinstance(ref, int):
            index, sub = ref, 0
        else:
            mm = _OBJECT_REF.match(ref)
            if not mm:
                self.err(
                    "object-ref", f"cannot read object {ref!r}; write 0x6064 or '0x30D1:2' (index:sub-index)", path
                )
                return None
            index = int(mm.group(1), 0)
            sub = int(mm.group(2), 0) if mm.group(2) else 0
        if not (0 <= index <= 0xFFFF and 0 <= sub <= 0xFF):
            self.err(
                "object-ref",
                f"object 0x{index:X}:{sub} is outside the object dictionary (index <= 0xFFFF, sub-index <= 0xFF)",
                path,
            )
            return None
        return index, sub

    def resolve_pdo(self, m: schema.Message, sbus: schema.Bus, bus: model.Bus, path: Path):
        p = m.pdo
        assert p is not None
        ppath = (*path, "pdo")
        kind: Literal["tpdo", "rpdo"] = "tpdo" if p.tpdo is not None else "rpdo"
        number = p.tpdo if p.tpdo is not None else p.rpdo
        assert number is not None
        if kind == "tpdo":
            holders = [m.producer]
        else:
            holders = list(m.consumers)
            if len(holders) > 1 and m.id is None:
                self.err(
                    "id-missing", "an RPDO received by several nodes has no single default COB-ID; give 'id'", ppath
                )
        device_node = holders[0]
        devices = [(h, self.model.nodes[h].device) for h in holders if h in self.model.nodes]
        for h, dev in devices:
            if dev is None:
                role = "produces" if kind == "tpdo" else "receives"
                self.err(
                    "no-device",
                    f"'{h}' {role} this {kind.upper()} but has no device profile to check the map "
                    "against; give it 'device: <profile>' or 'device: {eds: file.eds}'",
                    ppath,
                )
                continue
            count = dev.tpdo_count if kind == "tpdo" else dev.rpdo_count
            if number > count:
                self.err(
                    "pdo-number",
                    f"device {dev.name} of '{h}' ({dev.source}) has {count} {kind.upper()}s; {kind.upper()} {number} "
                    "does not exist",
                    (*ppath, kind),
                )
            if kind == "tpdo" and p.event_timer is not None and not dev.tpdo_event_timer:
                self.err(
                    "event-timer",
                    f"device {dev.name} has no TPDO event timer (0x18xx sub-index 5); use a "
                    "SYNC transmission type instead",
                    (*ppath, "event_timer"),
                )
            if kind == "tpdo" and p.inhibit is not None and not dev.tpdo_inhibit_time:
                self.err(
                    "inhibit", f"device {dev.name} has no TPDO inhibit time (0x18xx sub-index 3)", (*ppath, "inhibit")
                )
            if len(p.map) > dev.max_mapped_objects:
                self.err(
                    "pdo-length",
                    f"device {dev.name} maps at most {dev.max_mapped_objects} objects per PDO; "
                    f"this map has {len(p.map)}",
                    (*ppath, "map"),
                )
        tt = p.transmission
        if 241 <= tt <= 251:
            self.err(
                "transmission",
                f"transmission type {tt} is reserved (CiA 301); use 0-240, 254 or 255",
                (*ppath, "transmission"),
            )
        elif kind == "rpdo" and tt in (252, 253):
            self.err("transmission", "transmission types 252/253 (RTR) exist only for TPDOs", (*ppath, "transmission"))
        if p.sync_start is not None and (kind != "tpdo" or not 1 <= tt <= 240):
            self.err(
                "sync-start",
                "a SYNC start value (0x18xx sub-index 6) applies to synchronous TPDOs (transmission type 1-240) only",
                (*ppath, "sync_start"),
            )
        inhibit = self.ns(p.inhibit, (*ppath, "inhibit"), None)
        inhibit_100us = None
        if inhibit is not None:
            if kind == "rpdo":
                self.err("inhibit", "inhibit times limit transmitters: set it on TPDOs", (*ppath, "inhibit"))
            if inhibit % 100_000 or inhibit > 65_535 * 100_000:
                self.err(
                    "inhibit", "the inhibit time is stored in units of 100 us (at most 6.5535 s)", (*ppath, "inhibit")
                )
            inhibit_100us = inhibit // 100_000
        timer = self.ns(p.event_timer, (*ppath, "event_timer"), None)
        timer_ms = None
        if timer is not None:
            if timer % 1_000_000 or timer > 65_535 * 1_000_000 or timer == 0:
                self.err("event-timer", "the event timer is whole milliseconds, 1..65535 ms", (*ppath, "event_timer"))
            timer_ms = timer // 1_000_000
            if tt < 254:
                self.warn(
                    "event-timer",
                    f"the event timer only acts with transmission type 254/255, not {tt}",
                    (*ppath, "event_timer"),
                )
        entries: list[model.PdoEntry] = []
        names: dict[str, int] = {}
        for k, item in enumerate(p.map):
            epath = (*ppath, "map", k)
            ref = item.object if isinstance(item, schema.PdoEntry) else item
            parsed = self.parse_object_ref(ref, epath)
            if parsed is None:
                continue
            index, sub = parsed
            if cia301.is_dummy(index, sub):
                if kind == "tpdo":
                    self.err("pdo-dummy", "dummy entries (0x0001-0x0007) only pad RPDOs", epath)
                bits = DATA_TYPES[index][1]
                name = f"pad{k}"
                entries.append(model.PdoEntry(index, sub, bits, name, index))
                continue
            obj = None
            for h, dev in devices:
                if dev is None:
                    continue
                found = dev.lookup(index, sub)
                where = f"device {dev.name} of '{h}' ({dev.source})"
                has_subs = sub == 0 and any(i == index and k > 0 for i, k in dev.objects)
                hint = f" (it has sub-indices: give '0x{index:04X}:1')" if has_subs else ""
                if found is None:
                    self.err("unknown-object", f"object 0x{index:04X}:{sub} does not exist in {where}{hint}", epath)
                    continue
                if not found.pdo_mappable:
                    self.err(
                        "not-mappable",
                        f"object 0x{index:04X}:{sub} '{found.name}' of {where} is not PDO-mappable{hint}",
                        epath,
                    )
                elif kind == "rpdo" and not found.writable:
                    self.err(
                        "pdo-direction",
                        f"object 0x{index:04X}:{sub} '{found.name}' of {where} is read-only "
                        f"({found.access}) and cannot be written by an RPDO; map it in a TPDO",
                        epath,
                    )
                elif kind == "tpdo" and not found.readable:
                    self.err(
                        "pdo-direction",
                        f"object 0x{index:04X}:{sub} '{found.name}' of {where} is write-only "
                        f"({found.access}) and cannot be sent in a TPDO",
                        epath,
                    )
                if found.bits == 0:
                    self.err("not-mappable", f"object 0x{index:04X}:{sub} has no fixed size ({found.type_name})", epath)
                obj = obj or found
            if obj is None:
                continue
            name = item.name if isinstance(item, schema.PdoEntry) and item.name else snake(obj.name)
            if name in names:
                self.err(
                    "duplicate-name",
                    f"signal name '{name}' appears twice in this PDO; name one with '{{object: ..., name: ...}}'",
                    epath,
                )
            names[name] = k
            entries.append(model.PdoEntry(index, sub, obj.bits, name, obj.data_type))
        total = sum(e.bits for e in entries)
        if total > 64:
            self.err("pdo-length", f"the PDO map holds {total} bits; a CAN frame carries at most 64", (*ppath, "map"))
        if not entries and not p.map:
            self.err("pdo-length", "a PDO needs at least one mapped object", (*ppath, "map"))
        if len(entries) != len(p.map):
            return None
        pdo = model.Pdo(
            kind=kind,
            number=number,
            device_node=device_node,
            transmission=tt,
            inhibit_100us=inhibit_100us,
            event_timer_ms=timer_ms,
            sync_start=p.sync_start,
            entries=tuple(entries),
        )
        signals, start = [], 0
        for e in entries:
            kind_name = DATA_TYPES.get(e.data_type, ("", 0, "unsigned"))[2]
            signals.append(model.Signal(e.name, start, e.bits, kind_name == "signed", kind_name == "float"))
            start += e.bits
        return pdo, tuple(signals)

    def layout_signals(self, sigs: list[schema.Signal], path: Path) -> tuple[model.Signal, ...]:
        out, start, seen = [], 0, set()
        for k, s in enumerate(sigs):
            if s.name in seen:
                self.err("duplicate-name", f"signal '{s.name}' appears twice", (*path, k, "name"))
            seen.add(s.name)
            if s.min is not None and s.max is not None and s.min > s.max:
                self.err("signal-range", f"signal '{s.name}': min {s.min} is above max {s.max}", (*path, k))
            if s.float and s.bits not in (32, 64):
                self.err("signal-float", f"signal '{s.name}': a float has 32 or 64 bits", (*path, k, "bits"))
            if s.start_bit is not None:
                if s.start_bit < start:
                    self.err(
                        "signal-overlap",
                        f"signal '{s.name}' starts at bit {s.start_bit}, inside the previous "
                        f"signal (which ends before bit {start}); signals go in bit order",
                        (*path, k, "start_bit"),
                    )
                start = max(start, s.start_bit)
            out.append(model.Signal(s.name, start, s.bits, s.signed, s.float, s.scale, s.offset, s.min, s.max, s.unit))
            start += s.bits
        return tuple(out)

    def claim_implicit_name(self, name: str, what: str) -> None:
        """Implicit messages appear under their own name in reports: no spec message may use it."""
        for i, m in enumerate(self.spec.messages):
            if m.name.lower() == name.lower():
                self.err(
                    "duplicate-name",
                    f"message name '{m.name}' is taken by {what}; rename the message",
                    ("messages", i, "name"),
                )

    def check_sync_ids(self) -> None:
        """A device whose COB-ID SYNC (0x1005) is constant cannot follow another SYNC identifier."""
        for bus in self.model.buses.values():
            if bus.canopen is None:
                continue
            for name in bus.nodes:
                node = self.model.nodes.get(name)
                entry = node.device.lookup(0x1005, 0) if node and node.device else None
                fixed = entry is not None and entry.access == "const" and entry.default is not None
                if fixed and entry.default & 0x7FF != bus.canopen.sync_id:  # type: ignore[union-attr,operator]
                    self.err(
                        "sync-id",
                        f"device {node.device.name} of '{name}' has a fixed COB-ID SYNC (0x1005) of "  # type: ignore[union-attr]
                        f"0x{entry.default & 0x7FF:03X}; bus '{bus.name}' uses 0x{bus.canopen.sync_id:03X}",  # type: ignore[union-attr,operator]
                        (*bus.path, "canopen", "sync_id"),
                    )

    def add_implicit_messages(self) -> None:
        """CANopen buses carry SYNC and heartbeats that the spec does not list as messages."""
        for bus in self.model.buses.values():
            if bus.canopen is None:
                continue
            co = bus.canopen
            params = self.spec_buses[bus.name].canopen
            size = 1 if params is not None and params.sync_counter else 0
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
            )
            self.claim_implicit_name(sync.name, "the SYNC of bus " + bus.name)
            bus.messages.insert(0, sync)
            for name in bus.nodes:
                node = self.model.nodes.get(name)
                if node is None or node.heartbeat_ns is None or node.node_id is None:
                    continue
                self.claim_implicit_name(f"{name}_heartbeat", f"the heartbeat of node {name}")
                bus.messages.append(
                    model.Message(
                        name=f"{name}_heartbeat",
                        bus=bus.name,
                        producer=name,
                        consumers=tuple(n for n in bus.nodes if n != name) or (name,),
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
                    )
                )

    # -- FTT-CAN triggers and ids --------------------------------------------------------------------------
    def resolve_triggers(self) -> None:
        used: dict[tuple[str, int], str] = {}
        for m in self.model.messages.values():
            if m.ftt_id is not None:
                key = (m.bus, m.ftt_id)
                if key in used:
                    self.err(
                        "duplicate-ftt-id", f"FTT id {m.ftt_id} is already used by '{used[key]}'", (*m.path, "ftt_id")
                    )
                used[key] = m.name
        for i, t in enumerate(self.spec.triggers):
            path: Path = ("triggers", i)
            sbus = self.spec_buses.get(t.bus)
            bus = self.model.buses.get(t.bus)
            if sbus is None or bus is None:
                self.err(
                    "unknown-bus",
                    f"bus '{t.bus}' is not defined; known buses: {_some(self.spec_buses)}",
                    (*path, "bus"),
                )
                continue
            if sbus.protocol != "ftt-can":
                self.err(
                    "wrong-section",
                    f"triggers are FTT-CAN synchronous triggers; bus '{t.bus}' is {sbus.protocol}",
                    (*path, "bus"),
                )
                continue
            if bus.ftt is None:
                continue
            ec = bus.ftt.ec_ns
            key = (t.bus, t.ftt_id)
            if key in used:
                self.err("duplicate-ftt-id", f"FTT id {t.ftt_id} is already used by '{used[key]}'", (*path, "ftt_id"))
            used[key] = t.name
            period = self.ns(t.period, (*path, "period"), ec) or 0
            offset = self.ns(t.offset, (*path, "offset"), ec) if isinstance(t.offset, Duration) else None
            interval = period
            if t.period_range is not None:
                fastest = self.period_range(t.period_range, period, path, ec)
                interval = period if fastest is None else fastest
            for key_name, value in (("period", period), ("offset", offset)):
                if value is not None and value % ec:
                    self.err(
                        "ec-multiple",
                        f"{key_name} {format_ns(value)} is not a whole number of elementary cycles ({format_ns(ec)})",
                        (*path, key_name),
                    )
            if period <= 0:
                self.err("period", "a trigger period must be at least one EC", (*path, "period"))
            else:
                self.check_offset(offset, period, path)
            for j, ref in enumerate(t.tasks):
                node_name, task_name = ref.split(".", 1)
                node = self.model.nodes.get(node_name)
                if node is None or task_name not in node.tasks:
                    self.err(
                        "unknown-task",
                        f"trigger '{t.name}' activates '{ref}', which is not a task (write node.task)",
                        (*path, "tasks", j),
                    )
                    continue
                if t.bus not in node.buses:
                    self.err("not-on-bus", f"node '{node_name}' is not on bus '{t.bus}'", (*path, "tasks", j))
                task = node.tasks[task_name]
                if task.trigger is not None:
                    self.err(
                        "task-trigger",
                        f"task '{ref}' is already activated by trigger '{task.trigger}'",
                        (*path, "tasks", j),
                    )
                    continue
                if task.period_ns is not None and task.period_ns != period:
                    self.err(
                        "task-trigger",
                        f"task '{ref}' has period {format_ns(task.period_ns)} but its trigger "
                        f"fires every {format_ns(period)}; drop the task's period",
                        (*path, "tasks", j),
                    )
                node.tasks[task_name] = dataclasses.replace(
                    task, period_ns=period, trigger=t.name, offset_ns=offset or 0
                )
            self.model.triggers[t.name] = model.Trigger(
                description=t.description,
                name=t.name,
                bus=t.bus,
                ftt_id=t.ftt_id,
                period_ns=period,
                interval_ns=interval,
                offset_ns=offset,
                offset_auto=t.offset == "auto",
                tasks=tuple(t.tasks),
                path=path,
            )
        # Synchronous messages without an explicit FTT id take the lowest free ones, in spec order.
        for bus in self.model.buses.values():
            if bus.ftt is None:
                continue
            free = (k for k in range(10_000) if (bus.name, k) not in used)
            for m in bus.messages:
                if m.window == "sync" and m.ftt_id is None:
                    m.ftt_id = next(free)
                    used[(bus.name, m.ftt_id)] = m.name
                if m.window == "sync" and m.id < 0:
                    m.id = self.spec_buses[bus.name].ftt.sync_id_base + m.ftt_id  # type: ignore[union-attr,operator]
            capacity = 8 * bus.ftt.tm_size
            for (bname, k), owner in sorted(used.items()):
                if bname == bus.name and k >= capacity:
                    item = self.model.messages.get(owner) or self.model.triggers.get(owner)
                    path = self.key_or_item(item.path, "ftt_id") if item else bus.path
                    self.err(
                        "ftt-id-range",
                        f"FTT id {k} of '{owner}' does not fit the {bus.ftt.tm_size}-byte "
                        f"trigger message (ids 0..{capacity - 1}); raise tm_size or renumber",
                        path,
                    )

    def check_tasks_activated(self) -> None:
        for node in self.model.nodes.values():
            for task in node.tasks.values():
                if task.on_message is not None:
                    msg = self.model.messages.get(task.on_message)
                    if msg is None:
                        self.err(
                            "unknown-message",
                            f"task '{task.ref}' runs on message '{task.on_message}', which is not defined",
                            (*task.path, "on_message"),
                        )
                    elif node.name not in msg.consumers:
                        self.err(
                            "on-message",
                            f"'{node.name}' does not consume '{msg.name}'; add it to the consumers",
                            (*task.path, "on_message"),
                        )
                    if task.trigger is not None:
                        self.err("task-trigger", f"task '{task.ref}' is both event-driven and triggered", task.path)
                elif task.period_ns is None and task.trigger is None:
                    self.err(
                        "task-period",
                        f"task '{task.ref}' has no period, no trigger and no 'on_message'; say what activates it",
                        task.path,
                    )

    # -- identifiers ---------------------------------------------------------------------------------------
    def check_identifiers(self) -> None:
        for bus in self.model.buses.values():
            if bus.protocol == "ethernet-udp":
                seen_eth: dict[tuple[str, int], str] = {}
                for m in bus.messages:
                    if m.id < 0:
                        continue
                    key = (m.producer, m.id)
                    if key in seen_eth:
                        self.err(
                            "duplicate-id",
                            f"'{m.producer}' already sends message id 0x{m.id:02X} as '{seen_eth[key]}'",
                            (*m.path, "id"),
                        )
                    seen_eth[key] = m.name
                continue
            taken: dict[tuple[bool, int], str] = {}
            if bus.ftt is not None:
                taken[(False, bus.ftt.tm_id)] = "the FTT-CAN trigger message"
            if bus.canopen is not None:
                taken[(False, cia301.NMT_ID)] = "NMT"
                for name in bus.nodes:
                    node = self.model.nodes.get(name)
                    if node is None or node.node_id is None or node.node_id not in cia301.NODE_IDS:
                        continue
                    for service, cob in cia301.node_services(node.node_id).items():
                        if service.startswith("heartbeat") and node.heartbeat_ns:
                            continue  # the implicit heartbeat message below claims it
                        taken.setdefault((False, cob), f"{service} of node '{name}' (id {node.node_id})")
                for lss in cia301.LSS_IDS:
                    taken.setdefault((False, lss), "LSS")
            for m in bus.messages:
                if m.id < 0:
                    continue
                id_key = (m.extended, m.id)
                if id_key in taken:
                    self.err(
                        "duplicate-id",
                        f"identifier 0x{m.id:03X} of '{m.name}' collides with {taken[id_key]}; pick a free one",
                        self.key_or_item(m.path, "id"),
                    )
                    continue
                taken[id_key] = f"'{m.name}'"
                if bus.canopen is not None and m.pdo is not None and not m.extended and cia301.restricted(m.id):
                    self.err(
                        "restricted-id",
                        f"COB-ID 0x{m.id:03X} is restricted by CiA 301 (reserved for NMT, "
                        "SYNC/EMCY, TIME, SDO, heartbeat or LSS); PDOs must not use it",
                        self.key_or_item(m.path, "id"),
                    )

    # -- Ethernet topology ---------------------------------------------------------------------------------
    def resolve_topologies(self) -> None:
        """Every node of an Ethernet bus hangs on one switch port, and the cables form a tree (no spanning tree
        protocol is assumed, so a loop, parallel cables included, would flood the network)."""
        for bus in self.model.buses.values():
            if bus.protocol != "ethernet-udp":
                continue
            import networkx as nx  # only Ethernet buses need it; keeps start-up fast for CAN specs

            graph: nx.Graph = nx.Graph()
            switch_names = {s.name for s in bus.switches}
            attached: dict[str, str] = {}
            sbus = self.spec_buses[bus.name]
            assert sbus.ethernet is not None or not bus.switches
            for j, sw in enumerate(sbus.ethernet.switches if sbus.ethernet else []):
                spath = (*bus.path, "ethernet", "switches", j)
                graph.add_node(sw.name)
                ports: set[int] = set()
                for k, p in enumerate(sw.ports):
                    ppath = (*spath, "ports", k)
                    if p.port in ports:
                        self.err("topology", f"switch '{sw.name}' lists port {p.port} twice", (*ppath, "port"))
                        continue
                    ports.add(p.port)
                    where = f"{sw.name} port {p.port}"
                    if p.to not in switch_names and p.to not in bus.nodes:
                        self.err(
                            "unknown-node",
                            f"{where} leads to '{p.to}', which is neither a switch nor a node on bus '{bus.name}'",
                            (*ppath, "to"),
                        )
                        continue
                    if p.to == sw.name:
                        self.err("topology", f"{where} is cabled to its own switch", (*ppath, "to"))
                        continue
                    if p.to not in switch_names and p.to in attached:
                        self.err(
                            "topology", f"node '{p.to}' is cabled twice ({attached[p.to]} and {where})", (*ppath, "to")
                        )
                        continue
                    if p.to in graph and nx.has_path(graph, sw.name, p.to):
                        loop = " - ".join(nx.shortest_path(graph, p.to, sw.name))
                        self.err(
                            "topology",
                            f"the cable from {where} to '{p.to}' closes a loop ({loop} - {p.to}); "
                            "switched Ethernet without a spanning tree needs a tree: remove one cable",
                            (*ppath, "to"),
                        )
                        continue
                    attached[p.to] = where
                    graph.add_edge(sw.name, p.to)
            if not bus.switches:
                if len(bus.nodes) == 2:
                    graph.add_edge(*bus.nodes)
                elif len(bus.nodes) > 2:
                    self.err(
                        "topology",
                        f"bus '{bus.name}' has {len(bus.nodes)} nodes but no switch; add 'ethernet: "
                        "{switches: [...]}' saying which node hangs on which port",
                        bus.path,
                    )
                    continue
            for n in bus.nodes:
                if bus.switches and n not in graph:
                    self.err("topology", f"node '{n}' is on bus '{bus.name}' but on no switch port; cable it", bus.path)
            if graph.number_of_nodes() and not nx.is_connected(graph):
                parts = " / ".join(", ".join(sorted(c)) for c in nx.connected_components(graph))
                self.err(
                    "topology",
                    f"the cabling of bus '{bus.name}' falls apart into {parts}; connect the switches",
                    (*bus.path, "ethernet"),
                )

    # -- flows ---------------------------------------------------------------------------------------------
    def resolve_flows(self) -> None:
        for i, f in enumerate(self.spec.flows):
            path: Path = ("flows", i)
            steps: list[model.FlowStep] = []
            ok = True
            for j, item in enumerate(f.chain):
                spath = (*path, "chain", j)
                refs = [item] if isinstance(item, str) else item
                if not refs:
                    self.err("flow-chain", "an empty list is not a step", spath)
                    ok = False
                    continue
                kinds = set()
                for k, ref in enumerate(refs):
                    rpath = spath if isinstance(item, str) else (*spath, k)
                    if "." in ref:
                        node_name, _, task_name = ref.partition(".")
                        node = self.model.nodes.get(node_name)
                        if node is None or task_name not in node.tasks:
                            self.err("unknown-task", f"flow '{f.name}': '{ref}' is not a task (node.task)", rpath)
                            ok = False
                        kinds.add("task")
                    elif ref in self.model.messages:
                        kinds.add("message")
                    else:
                        self.err(
                            "unknown-message",
                            f"flow '{f.name}': '{ref}' is neither a message nor a task (tasks are written node.task)",
                            rpath,
                        )
                        ok = False
                if len(kinds) > 1:
                    self.err("flow-chain", "a parallel step holds either tasks or messages, not both", spath)
                    ok = False
                elif kinds:
                    steps.append(model.FlowStep(kinds.pop(), tuple(refs)))  # type: ignore[arg-type]
            if ok:
                ok = self.check_flow_links(f.name, steps, path)
            if ok and steps[-1].kind != "task":
                self.err(
                    "flow-chain",
                    f"flow '{f.name}' must end with the task that uses the data (node.task)",
                    (*path, "chain", len(steps) - 1),
                )
            self.model.flows[f.name] = model.Flow(
                description=f.description,
                name=f.name,
                steps=tuple(steps),
                deadline_ns=self.ns(f.deadline, (*path, "deadline"), None),
                path=path,
            )

    def check_flow_links(self, flow: str, steps: list[model.FlowStep], path: Path) -> bool:
        """Each step must hand its data to the next: a producer to its message, a message to a consumer,
        a task to a task on the same node."""
        ok = True
        for j in range(1, len(steps)):
            before, after = steps[j - 1], steps[j]
            where = (*path, "chain", j)
            if before.kind == "message" and after.kind == "message":
                self.err(
                    "flow-chain",
                    f"flow '{flow}': two message steps in a row; put the task that relays the data between them",
                    where,
                )
                ok = False
            elif before.kind == "task" and after.kind == "message":
                nodes = {r.split(".")[0] for r in before.refs}
                for ref in after.refs:
                    msg = self.model.messages[ref]
                    if msg.producer not in nodes:
                        self.err(
                            "flow-chain",
                            f"flow '{flow}': '{ref}' is produced by '{msg.producer}', not by {_names(nodes)}",
                            where,
                        )
                        ok = False
            elif before.kind == "message" and after.kind == "task":
                for ref in after.refs:
                    node = ref.split(".")[0]
                    if not any(node in self.model.messages[m].consumers for m in before.refs):
                        self.err("flow-chain", f"flow '{flow}': '{node}' consumes none of {_names(before.refs)}", where)
                        ok = False
            else:
                nodes = {r.split(".")[0] for r in before.refs}
                for ref in after.refs:
                    if ref.split(".")[0] not in nodes:
                        self.err(
                            "flow-chain",
                            f"flow '{flow}': '{ref}' follows tasks of {_names(nodes)} without a "
                            "message in between; data crosses nodes only in messages",
                            where,
                        )
                        ok = False
        return ok


def _names(items: Iterable[str]) -> str:
    return ", ".join(f"'{x}'" for x in sorted(items))


def _some(names: Iterable[str], limit: int = 8) -> str:
    items = sorted(names)
    more = f" (+{len(items) - limit} more)" if len(items) > limit else ""
    return (", ".join(items[:limit]) or "none") + more


_EDS_CACHE: dict[tuple[str, int], DeviceProfile] = {}


def _cached_eds(file: str, mtime: int, display: str) -> DeviceProfile:
    """Specs with many identical drives import their EDS once."""
    key = (file, mtime)
    if key not in _EDS_CACHE:
        _EDS_CACHE[key] = import_eds(FsPath(file), FsPath(display).stem)
    return _EDS_CACHE[key]
