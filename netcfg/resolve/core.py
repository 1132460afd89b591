"""The core of resolution: the state one run shares (spec, source positions, diagnostics, the model built so
far), the checks every protocol needs (names, nodes, tasks, a message's common fields, identifiers) and the hooks a
protocol fills in (`BusRules`). Each protocol's rules live in their own module beside this one.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Mapping
from pathlib import Path as FsPath
from typing import Any

from netcfg import cia301, model
from netcfg.diagnostics import Collector
from netcfg.protocols import PROTOCOLS
from netcfg.protocols.canopen import resolve as canopen
from netcfg.rules import BusRules
from netcfg.spec import schema
from netcfg.spec.source import Path, SourceMap
from netcfg.spec.suggest import did_you_mean, some_names
from netcfg.spec.units import Duration, format_ns


class Resolver:
    """What one resolution shares; the protocol modules read and extend it through their `BusRules`."""

    def __init__(
        self,
        spec: schema.Spec,
        smap: SourceMap,
        diags: Collector,
        spec_dir: FsPath,
        protocols: Mapping[str, type[BusRules]],
    ):
        self.spec = spec
        self.smap = smap
        self.d = diags
        self.spec_dir = spec_dir
        self.slowest: dict[Path, int] = {}  # period_range's slowest period, by the message's or trigger's path
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
        self.shared_node_ids: set[str] = set()  # nodes whose node id another node on one of their buses has too
        self.spec_buses = {b.name: b for b in spec.buses}
        self.protocols = {name: rules(self) for name, rules in protocols.items()}

    def protocol(self, name: str) -> BusRules:
        return self.protocols[name]

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
        self.slowest[path] = hi
        return lo

    def ec_of(self, bus_names: Iterable[str]) -> int | None:
        ecs = [b.ftt.ec.ns for n in bus_names if (b := self.spec_buses.get(n)) and b.ftt and b.ftt.ec.ns]
        return ecs[0] if len(ecs) == 1 else None

    # -- the passes every spec goes through ---------------------------------------------------------------
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
            for proto, rules in self.protocols.items():
                key = rules.section
                if key is not None and getattr(b, key) is not None and b.protocol != proto:
                    self.err(
                        "wrong-section",
                        f"bus '{b.name}' is {b.protocol}; '{key}:' belongs to {proto} buses",
                        (*path, key),
                    )
            link = PROTOCOLS[b.protocol].link
            bus = model.Bus(
                description=b.description,
                name=b.name,
                protocol=b.protocol,
                link=link.name,
                bitrate=b.bitrate,
                id_bits=b.id_bits,
                clock_tolerance_ppm=b.clock_tolerance,
                nodes=[n.name for n in self.spec.nodes if b.name in n.buses],
                messages=[],
                path=path,
            )
            if b.errors is not None:
                if not link.arbitrates:
                    self.err(
                        "wrong-section",
                        f"'errors' is the CAN bit-error model; bus '{b.name}' is Ethernet, whose frames a bit error "
                        "simply drops (model that with the messages' deadlines)",
                        (*path, "errors"),
                    )
                else:
                    ec_ns = b.ftt.ec.to_ns(None) if b.ftt is not None else None
                    interval = b.errors.interval.to_ns(ec_ns)
                    if interval is None or interval <= 0:
                        self.err(
                            "errors",
                            "the error interval must be a time longer than 0, e.g. interval: 10ms",
                            (*path, "errors", "interval"),
                        )
                    else:
                        bus.errors = model.BitErrors(b.errors.burst, interval, b.errors.ber)
            if "clock_tolerance" in b.model_fields_set and not link.arbitrates:
                self.warn(
                    "wrong-section",
                    f"'clock_tolerance' is counted by the CAN analysis; bus '{b.name}' is Ethernet, where it has no "
                    "effect (flows take the largest of the CAN buses'): remove it",
                    (*path, "clock_tolerance"),
                )
            if b.data_bitrate is not None and not link.data_phase:
                self.err(
                    "wrong-section",
                    f"'data_bitrate' is the CAN FD data phase; bus '{b.name}' is {b.protocol}",
                    (*path, "data_bitrate"),
                )
            self.protocol(b.protocol).resolve_bus(b, bus, path)
            self.model.buses[b.name] = bus

    def task_refs(self) -> list[str]:
        """Every task as a flow step names it: node.task."""
        return [f"{n.name}.{t}" for n in self.model.nodes.values() for t in n.tasks]

    def masters(self, bus: str) -> list[str]:
        return [n.name for n in self.spec.nodes if bus in n.buses and n.role == "master"]

    def resolve_nodes(self) -> None:
        ids: dict[tuple[str, int], str] = {}
        for i, n in enumerate(self.spec.nodes):
            path: Path = ("nodes", i)
            for j, bname in enumerate(n.buses):
                if bname not in self.spec_buses:
                    self.err(
                        "unknown-bus",
                        f"node '{n.name}' sits on bus '{bname}', which is not defined"
                        f"{did_you_mean(bname, self.spec_buses)}; known buses: {some_names(self.spec_buses)}",
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
                        self.shared_node_ids.update((n.name, ids[key]))
                        self.err(
                            "duplicate-node-id",
                            f"node id {n.node_id} of '{n.name}' is already used by '{ids[key]}' on bus '{bname}'",
                            (*path, "node_id"),
                        )
                    ids[key] = n.name
            elif on_canopen:
                self.err("node-id", f"node '{n.name}' is on a CANopen bus and needs a node_id (1..127)", path)
            device = canopen.load_device(self, n, path, on_canopen)
            # a node on a misspelt bus may well be on a CANopen one: the unknown bus is the one error
            if n.heartbeat is not None and not on_canopen and all(b in self.spec_buses for b in n.buses):
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
            hb_timeout = self.ns(n.heartbeat_timeout, (*path, "heartbeat_timeout"), None)
            if hb_timeout is not None and (
                hb is None or hb_timeout <= hb or hb_timeout % 1_000_000 or hb_timeout > 65_535_000_000
            ):
                self.err(
                    "heartbeat",
                    "heartbeat_timeout (the master's consumer time, 0x1016) is whole milliseconds, at most 65535 ms, "
                    "and longer than the node's heartbeat producer time; give the node a 'heartbeat' first",
                    (*path, "heartbeat_timeout"),
                )
                hb_timeout = None
            whole_ms = hb is not None and not hb % 1_000_000 and hb <= 65_535_000_000
            if hb and whole_ms and not canopen.device_has_heartbeat(self, device, hb, (*path, "heartbeat")):
                hb = hb_timeout = None  # reported; no heartbeat the device cannot send
            if hb and hb_timeout is None:
                # Lely dcfgen's default heartbeat_multiplier (3.0): two heartbeats may be lost; 0x1016 holds 16 bits
                hb_timeout = min(3 * hb, 65_535_000_000)
            sdo_timeout = self.ns(n.sdo_timeout, (*path, "sdo_timeout"), None)
            if sdo_timeout is not None and not 0 < sdo_timeout <= 60_000_000_000:
                self.err(
                    "sdo-timeout",
                    "sdo_timeout (how long the master waits for each SDO answer) is more than 0 and at most 60 s",
                    (*path, "sdo_timeout"),
                )
                sdo_timeout = None
            if sdo_timeout is None:
                sdo_timeout = 500_000_000  # what `netcfg run` waited before the key existed
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
                heartbeat_timeout_ns=hb_timeout,
                on_loss=n.on_loss,
                on_emcy=n.on_emcy,
                on_reboot=n.on_reboot,
                sdo_timeout_ns=sdo_timeout,
                sdo_retries=n.sdo_retries,
                safe_stop=n.safe_stop,
                ip=n.ip,
                tasks=tasks,
                path=path,
                tx_delay_ns=self.ns(n.tx_delay, (*path, "tx_delay"), None) or 0,
                rx_delay_ns=self.ns(n.rx_delay, (*path, "rx_delay"), None) or 0,
                scheduling=n.scheduling,
                tx_queue=_tx_queue(n.tx_queue),
            )
            on_can = any(sb.name in n.buses and PROTOCOLS[sb.protocol].link.arbitrates for sb in self.spec.buses)
            if n.tx_queue.policy == "fifo" and not on_can:
                self.warn(
                    "wrong-section",
                    f"node '{n.name}' is on no CAN bus: its tx_queue has no effect (an Ethernet NIC's queue is its "
                    "nic_queue): remove it",
                    (*path, "tx_queue"),
                )

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
            sync_bus, period = canopen.sync_task(self, node, t, path, period)
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
            priority=t.priority,
        )

    # -- messages ------------------------------------------------------------------------------------------
    def message_bus(self, m: schema.Message, path: Path) -> schema.Bus | None:
        ends = [m.producer, *m.consumers]
        for k, name in enumerate(ends):
            if name not in self.spec_nodes:
                where = (*path, "producer") if k == 0 else (*path, "consumers", k - 1)
                self.err(
                    "unknown-node",
                    f"message '{m.name}' names node '{name}', which is not defined"
                    f"{did_you_mean(name, self.spec_nodes)}; known nodes: {some_names(self.spec_nodes)}",
                    where,
                )
        if any(name not in self.spec_nodes for name in ends):
            return None
        if m.bus is not None:
            if m.bus not in self.spec_buses:
                self.err(
                    "unknown-bus",
                    f"bus '{m.bus}' is not defined{did_you_mean(m.bus, self.spec_buses)}; "
                    f"known buses: {some_names(self.spec_buses)}",
                    (*path, "bus"),
                )
                return None
            bus = self.spec_buses[m.bus]
        else:
            common = set(self.spec_nodes[m.producer].buses) & set(self.spec_buses)  # undefined ones are reported
            for c in m.consumers:
                common &= set(self.spec_nodes[c].buses)
            if not common and any(b not in self.spec_buses for n in ends for b in self.spec_nodes[n].buses):
                return None  # a node's bus is misspelt: reported on the node, and the likely cause of this
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
        rules = self.protocol(sbus.protocol)
        ec = bus.ftt.ec_ns if bus.ftt else None
        if not rules.carries_messages(bus):
            return None  # the bus error is reported already
        # --- what is sent: size, signals, PDO map
        pdo = None
        signals: tuple[model.Signal, ...] = ()
        size = m.size
        if m.pdo is not None:
            got = rules.resolve_pdo(m, sbus, bus, path)
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
            sig_size = max((_last_byte(s) + 1 for s in signals), default=0)
            if size is not None and size < sig_size:
                # the signal that reaches furthest is the mistake (or the size is): name it, at its own line
                j, far = max(enumerate(signals), key=lambda item: _last_byte(item[1]))
                order = "big-endian" if far.big_endian else "little-endian"
                self.err(
                    "size",
                    f"signal '{far.name}' of message '{m.name}' (start bit {far.start_bit}, {far.bits} bits, {order}) "
                    f"reaches byte {_last_byte(far)}, outside the message's {size} bytes; move the signal or make "
                    f"'size: {sig_size}'",
                    (*path, "signals", j, "start_bit") if self.smap.has((*path, "signals", j, "start_bit"))
                    else (*path, "signals", j),
                )
            size = max(size or 0, sig_size)
        if size is None:
            self.err("size", f"message '{m.name}' needs a payload: 'size: <bytes>', 'signals:' or a PDO map", path)
            return None
        rules.check_payload(m, size, path)
        # --- when it is sent
        timing = self.resolve_timing(m, bus, pdo, path, ec)
        if timing is None:
            return None
        kind, period, interval, offset, offset_auto, rate = timing
        deadline = self.ns(m.deadline, (*path, "deadline"), ec)
        if deadline is not None and deadline <= 0:
            self.err("deadline", f"message '{m.name}': a deadline must be above zero", (*path, "deadline"))
        if deadline is None:
            deadline = interval
        jitter = self.ns(m.jitter, (*path, "jitter"), ec) or 0
        # --- identifier
        extended = m.extended if m.extended is not None else (sbus.id_bits == 29)
        window, ftt_id = rules.resolve_window(m, sbus, kind, path)
        ident = rules.message_id(m, pdo, path)
        if ident is None and rules.explicit_ids and pdo is None:
            self.err("id-missing", f"message '{m.name}' needs an explicit 'id': {rules.id_meaning}", path)
        if ident is not None:
            limit, width = rules.id_limit(bool(extended))
            if ident > limit:
                # an 11-bit overflow is most often a 29-bit identifier written without saying so
                fits_29 = not extended and ident <= 0x1FFFFFFF
                hint = "; make it a 29-bit identifier with 'extended: true'" if fits_29 else ""
                self.err(
                    "id-range",
                    f"message '{m.name}': id 0x{ident:X} does not fit {width} (max 0x{limit:X}){hint}",
                    (*path, "id"),
                )
        rules.check_fields(m, path)
        fd, brs = rules.frame_format(m, path)
        return model.Message(
            name=m.name,
            bus=sbus.name,
            producer=m.producer,
            consumers=tuple(m.consumers),
            id=ident if ident is not None else -1,
            extended=bool(extended) and rules.extended_ids,
            size=size,
            kind=kind,
            period_ns=period,
            interval_ns=interval,
            slowest_ns=self.slowest.get(path),
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
            fd=fd,
            brs=brs,
            may_be_lost=m.may_be_lost,
        )

    def resolve_timing(self, m: schema.Message, bus: model.Bus, pdo: model.Pdo | None, path: Path, ec: int | None):
        """-> (kind, period, interval, offset, offset_auto, rate) or None."""
        rules = self.protocol(bus.protocol)
        period = self.ns(m.period, (*path, "period"), ec)
        mit = self.ns(m.min_interarrival, (*path, "min_interarrival"), ec)
        rate = m.rate
        if rate is not None:
            if period is not None:
                self.err("period", "give either 'period' or 'rate', not both", (*path, "rate"))
            period = round(1_000_000_000 / rate)  # at least 1: units.parse_frequency admits at most 1 GHz
        kind = m.type
        if pdo is not None:
            spec_jitter = (m.jitter.to_ns(ec) or 0) if m.jitter is not None else 0  # reported below if in EC
            timing = rules.pdo_timing(pdo, bus, kind, period, mit, path, spec_jitter)
            if timing is None:
                return None
            kind, period, mit = timing
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
                self.err("period", f"message '{m.name}': a period must be above zero", (*path, "period"))
                return None
            if mit is not None and m.min_interarrival is not None:
                self.err("message-type", "'min_interarrival' is for sporadic messages", (*path, "min_interarrival"))
        elif kind == "sporadic":
            if mit is None or mit <= 0:
                self.err("min-interarrival", "a sporadic message needs 'min_interarrival' above zero", path)
                return None
            # a PDO's own settings may make a message with a period sporadic (an event timer between its sends)
            if (m.period is not None or m.rate is not None) and (pdo is None or m.type == "sporadic"):
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
            if not rules.rate_adaptation or kind != "periodic":
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
        if offset_auto and not rules.auto_offsets:
            self.err(
                "offset",
                "'offset: auto' is derived from FTT-CAN flows; give this message a duration",
                (*path, "offset"),
            )
        self.check_offset(offset, period, path)
        offset = rules.release_offset(m, kind, period, offset, offset_auto, path, ec)
        return kind, (period if kind == "periodic" else None), interval, offset, offset_auto, rate

    def layout_signals(self, sigs: list[schema.Signal], path: Path) -> tuple[model.Signal, ...]:
        from netcfg.runtime.codec import int_range  # the runtime package only when a spec has signals

        out: list[model.Signal] = []
        start, seen = 0, set()
        names = {s.name for s in sigs}
        switches = {s.mux.signal for s in sigs if s.mux is not None}
        for k, s in enumerate(sigs):
            if s.name in seen:
                self.err("duplicate-name", f"signal '{s.name}' appears twice", (*path, k, "name"))
            seen.add(s.name)
            if s.min is not None and s.max is not None and s.min > s.max:
                self.err("signal-range", f"signal '{s.name}': min {s.min} is above max {s.max}", (*path, k))
            if s.float and s.bits not in (32, 64):
                self.err("signal-float", f"signal '{s.name}': a float has 32 or 64 bits", (*path, k, "bits"))
            big = s.byte_order == "big_endian"
            if big and s.start_bit is None:
                self.err(
                    "signal-start",
                    f"signal '{s.name}' is big-endian: give its start_bit (its most significant bit, DBC numbering)",
                    (*path, k),
                )
                continue
            begin = start if s.start_bit is None else s.start_bit
            if big and s.bits > begin % 8 + 1 + 8 * (63 - begin // 8):  # runs past the largest payload
                self.err("signal-start", f"signal '{s.name}' runs past byte 63", (*path, k, "start_bit"))
                continue
            if s.mux is not None and (s.mux.signal not in names or s.mux.signal == s.name):
                self.err(
                    "signal-mux",
                    f"signal '{s.name}' is multiplexed by '{s.mux.signal}', which is not another signal of the "
                    "message",
                    (*path, k, "mux", "signal"),
                )
            lo, hi = int_range(s.bits, s.signed)
            for raw in s.enum or {}:
                if not lo <= raw <= hi:
                    self.err(
                        "signal-enum",
                        f"signal '{s.name}': value {raw} of its enum does not fit {s.bits} bits ({lo}..{hi})",
                        (*path, k, "enum"),
                    )
            out.append(
                model.Signal(
                    s.name,
                    begin,
                    s.bits,
                    s.signed,
                    s.float,
                    s.scale,
                    s.offset,
                    s.min,
                    s.max,
                    s.unit,
                    big_endian=big,
                    mux=s.mux.signal if s.mux is not None else None,
                    mux_values=tuple(s.mux.values) if s.mux is not None else (),
                    choices=tuple(sorted((s.enum or {}).items())),
                    is_multiplexer=s.name in switches,
                )
            )
            if not big:
                start = begin + s.bits
        self.check_signal_overlap(out, {s.name: k for k, s in enumerate(sigs)}, path)
        return tuple(out)

    def check_signal_overlap(self, signals: list[model.Signal], index: dict[str, int], path: Path) -> None:
        """Two signals may share bits only when no frame carries both (different values of one multiplexer)."""
        from netcfg.runtime.codec import byte_ops

        by_name = {s.name: s for s in signals}

        def conditions(s: model.Signal) -> dict[str, set[int]]:
            out: dict[str, set[int]] = {}
            while s.mux is not None and s.mux not in out and s.mux in by_name:
                out[s.mux] = set(s.mux_values)
                s = by_name[s.mux]
            return out

        masks = [sum(op.mask << (8 * op.index) for op in byte_ops(s.start_bit, s.bits, s.big_endian)) for s in signals]
        conds = [conditions(s) for s in signals]
        for b, sb in enumerate(signals):
            for a in range(b):
                if not masks[a] & masks[b]:
                    continue
                if any(m in conds[b] and not (v & conds[b][m]) for m, v in conds[a].items()):
                    continue  # never in the same frame
                sa = signals[a]
                self.err(
                    "signal-overlap",
                    f"signal '{sb.name}' (start bit {sb.start_bit}, {sb.bits} bits) overlaps signal '{sa.name}' "
                    f"(start bit {sa.start_bit}, {sa.bits} bits); move it to free bits",
                    (*path, index[sb.name], "start_bit"),
                )
                break

    def claim_implicit_name(self, name: str, what: str) -> None:
        """Implicit messages appear under their own name in reports: no spec message may use it."""
        for i in self.message_names.get(name.lower(), ()):
            self.err(
                "duplicate-name",
                f"message name '{self.spec.messages[i].name}' is taken by {what}; rename the message",
                ("messages", i, "name"),
            )

    @functools.cached_property
    def message_names(self) -> dict[str, list[int]]:
        """Lower-cased spec message name -> the messages' indices: one pass, not one per implicit message (126
        heartbeats against 378 PDOs)."""
        out: dict[str, list[int]] = {}
        for i, m in enumerate(self.spec.messages):
            out.setdefault(m.name.lower(), []).append(i)
        return out

    def check_tasks_activated(self) -> None:
        for node in self.model.nodes.values():
            for task in node.tasks.values():
                if task.on_message is not None:
                    msg = self.model.messages.get(task.on_message)
                    if msg is None and any(m.name == task.on_message for m in self.spec.messages):
                        pass  # the message is in the spec but has errors of its own, reported where they are
                    elif msg is None:
                        self.err(
                            "unknown-message",
                            f"task '{task.ref}' runs on message '{task.on_message}', which is not defined"
                            f"{did_you_mean(task.on_message, [m.name for m in self.spec.messages])}",
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

    def check_identifiers(self) -> None:
        for bus in self.model.buses.values():
            self.protocol(bus.protocol).check_identifiers(bus)


def quoted_names(items: Iterable[str]) -> str:
    return ", ".join(f"'{x}'" for x in sorted(items))


def _last_byte(s: model.Signal) -> int:
    """The highest payload byte a signal touches (imported here: the runtime package only for signals)."""
    from netcfg.runtime.codec import last_byte

    return last_byte(s.start_bit, s.bits, s.big_endian)


def _tx_queue(q: schema.TxQueue) -> model.TxQueue:
    """`tx_queue: fifo` arrives as the mapping {policy: fifo} with its defaults."""
    return model.TxQueue(policy=q.policy, depth=q.depth, on_full=q.on_full)
