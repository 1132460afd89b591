"""The core of resolution: the state one run shares (spec, source positions, diagnostics, the model built so
far), the checks every protocol needs (names, nodes, tasks, a message's common fields, identifiers) and the hooks a
protocol fills in (`BusRules`). Each protocol's rules live in their own module beside this one.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Mapping
from pathlib import Path as FsPath
from typing import Any, cast

from netcfg import model
from netcfg.diagnostics import Collector
from netcfg.protocols import PROTOCOLS, Protocol, over
from netcfg.resolve.signals import last_byte, layout_signals
from netcfg.rules import BusRules, Release
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
        self.actuator_replies: dict[str, str] = {}  # an actuator's reply message -> the task that sends it
        self.spec_buses = {b.name: b for b in spec.buses}
        self.protocols = {name: rules(self) for name, rules in protocols.items()}

    def protocol(self, name: str) -> BusRules:
        return self.protocols[name]

    def bus_protocol(self, b: schema.Bus) -> Protocol:
        """The protocol a spec's bus runs: its `protocol:` over its `link:` (resolve_buses reports a pair netcfg
        does not model, and the named protocol stands in for it meanwhile)."""
        chosen = over(b.protocol, b.link)
        return chosen if isinstance(chosen, Protocol) else PROTOCOLS[b.protocol]

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
            for name, rules in self.protocols.items():
                key = rules.section
                if key is not None and getattr(b, key) is not None and self.protocols[b.protocol] is not rules:
                    self.err(
                        "wrong-section",
                        f"bus '{b.name}' is {b.protocol}; '{key}:' belongs to {name} buses",
                        (*path, key),
                    )
            chosen = over(b.protocol, b.link)
            if isinstance(chosen, str):
                self.err("link", chosen, (*path, "link"))
            proto = self.bus_protocol(b)
            link = proto.link
            bus = model.Bus(
                description=b.description,
                name=b.name,
                protocol=cast(model.Protocol, proto.name),  # a name of PROTOCOLS, which model.Protocol lists
                link=link.name,
                arbitrates=link.arbitrates,
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
                    interval = b.errors.interval.to_ns(self.protocol(b.protocol).cycle_ns(b))
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
            if b.data_bitrate is not None and not link.data_phase and not isinstance(chosen, str):
                self.err(
                    "wrong-section",
                    f"'data_bitrate' is the CAN FD data phase; bus '{b.name}' is {bus.protocol} on {link.name}: "
                    "remove it, or run the bus on CAN FD (protocol: can-fd, or link: can-fd)",
                    (*path, "data_bitrate"),
                )
            self.protocol(proto.name).resolve_bus(b, bus, path)
            self.model.buses[b.name] = bus

    def task_refs(self) -> list[str]:
        """Every task as a flow step names it: node.task."""
        return [f"{n.name}.{t}" for n in self.model.nodes.values() for t in n.tasks]

    def masters(self, bus: str) -> list[str]:
        return [n.name for n in self.spec.nodes if bus in n.buses and n.role == "master"]

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
        rules = self.protocol(bus.protocol)
        ec = rules.cycle_ns(sbus)
        if not rules.carries_messages(bus):
            return None  # the bus error is reported already
        if rules.pdo_messages and m.pdo is None:
            rules.check_fields(m, path)  # says what the bus's messages are
            return None
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
            signals = layout_signals(self, m.signals, (*path, "signals"))
            sig_size = max((last_byte(s) + 1 for s in signals), default=0)
            if size is not None and size < sig_size:
                # the signal that reaches furthest is the mistake (or the size is): name it, at its own line
                j, far = max(enumerate(signals), key=lambda item: last_byte(item[1]))
                order = "big-endian" if far.big_endian else "little-endian"
                self.err(
                    "size",
                    f"signal '{far.name}' of message '{m.name}' (start bit {far.start_bit}, {far.bits} bits, {order}) "
                    f"reaches byte {last_byte(far)}, outside the message's {size} bytes; move the signal or make "
                    f"'size: {sig_size}'",
                    (*path, "signals", j, "start_bit") if self.smap.has((*path, "signals", j, "start_bit"))
                    else (*path, "signals", j),
                )
            size = max(size or 0, sig_size)
        if size is None:
            self.err("size", f"message '{m.name}' needs a payload: 'size: <bytes>', 'signals:' or a PDO map", path)
            return None
        rules.link_rules(bus).check_payload(m, size, path)
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
        fd, brs = rules.link_rules(bus).frame_format(m, path)
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
            timing = rules.pdo_timing(pdo, bus, (kind, period, mit), path, spec_jitter)
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
        offset = rules.release_offset(m, Release(kind, period, offset, offset_auto), path, ec)
        return kind, (period if kind == "periodic" else None), interval, offset, offset_auto, rate

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
                elif task.period_ns is None and task.trigger is None and not self._on_a_cycle(task):
                    self.err(
                        "task-period",
                        f"task '{task.ref}' has no period, no trigger and no 'on_message'; say what activates it",
                        task.path,
                    )

    def _on_a_cycle(self, task: model.Task) -> bool:
        """The spec puts the task on its bus's cycle (`sync: true`): without one, that is the error said."""
        _, i, _, j = task.path
        return bool(self.spec.nodes[int(i)].tasks[int(j)].sync)

    def check_identifiers(self) -> None:
        for bus in self.model.buses.values():
            self.protocol(bus.protocol).check_identifiers(bus)


def quoted_names(items: Iterable[str]) -> str:
    return ", ".join(f"'{x}'" for x in sorted(items))
