"""Reading a runtime.json: the input guard, the format and version check, the schema check
(netcfg.runtime.schema), and the mapping of its JSON onto netcfg.runtime.config's classes. Re-exported by
netcfg.runtime."""

from __future__ import annotations

from collections.abc import Iterable
from fractions import Fraction
from pathlib import Path
from typing import Any

from netcfg.inputs import InputError, JsonInputError, parse_json, read_input_text
from netcfg.runtime.actuators import Actuator, ActuatorCommand
from netcfg.runtime.config import (
    DEFAULT_CLOCK_TOLERANCE_PPM,
    Bus,
    CanopenParams,
    EcSlot,
    ErrorAssumption,
    EthernetParams,
    Flow,
    FlowStep,
    FttParams,
    Message,
    Node,
    NodeIdentity,
    Pdo,
    PdoEntry,
    RuntimeConfig,
    SdoWrite,
    Signal,
    SrtEntry,
    Switch,
    SwitchPort,
    Task,
    Trigger,
    TxQueue,
    UdpPorts,
)
from netcfg.runtime.schema import bus_link, check_document

FORMAT = "netcfg-runtime"
SUPPORTED_VERSIONS = (1,)


class RuntimeConfigError(ValueError):
    """The file is not a runtime config this netcfg can read."""


# --- reading -----------------------------------------------------------------------------------------------------


def load(path: str | Path) -> RuntimeConfig:
    """Read a runtime.json; RuntimeConfigError (naming the file) when it is not one this netcfg can read."""
    source = str(path)
    return parse(read_document(path), source)


def read_document(path: str | Path) -> Any:
    """The decoded JSON of a runtime.json, through netcfg's input guard (size, depth and number limits checked
    before parsing); RuntimeConfigError naming the file when it cannot be read or is not JSON."""
    source = str(path)
    try:
        text = read_input_text(path, "runtime config")
    except InputError as exc:
        raise RuntimeConfigError(f"{source}: cannot read the runtime config: {exc}") from exc
    try:
        return parse_json(text)
    except JsonInputError as exc:
        raise RuntimeConfigError(f"{source}: not a runtime config: {exc}") from exc


def parse(data: Any, source: str = "<memory>") -> RuntimeConfig:
    """A runtime config from its decoded JSON."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise RuntimeConfigError(f"{source}: not a netcfg runtime config (format {found!r}, expected {FORMAT!r})")
    version = data.get("version")
    if version not in SUPPORTED_VERSIONS or isinstance(version, bool):
        supported = ", ".join(map(str, SUPPORTED_VERSIONS))
        raise RuntimeConfigError(
            f"{source}: runtime config version {version!r} is not supported; this netcfg reads version "
            f"{supported}. Rebuild it with 'netcfg build' from the netcfg release the master uses."
        )
    problems = check_document(data)  # the same field table the emitter checks what it writes against
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise RuntimeConfigError(
            f"{source}: malformed runtime config: {problems[0]}{more}; rebuild it with 'netcfg build'"
        )
    try:
        cfg = _config(data, source)
    except KeyError as exc:
        raise RuntimeConfigError(
            f"{source}: malformed runtime config version {version}: missing key {exc}; rebuild it with 'netcfg build'"
        ) from exc
    except (TypeError, ValueError, AttributeError) as exc:
        raise RuntimeConfigError(f"{source}: malformed runtime config version {version}: {exc}") from exc
    problems = _problems(cfg)
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise RuntimeConfigError(
            f"{source}: malformed runtime config: {problems[0]}{more}; rebuild it with 'netcfg build'"
        )
    return cfg


_INT_FIELDS = {
    "message": (
        "id",
        "size",
        "period_ns",
        "interval_ns",
        "offset_ns",
        "deadline_ns",
        "jitter_ns",
        "wcrt_ns",
        "wcrt_unsync_ns",
    ),
    "task": ("period_ns", "offset_ns", "wcet_ns", "bcet_ns"),
    "bus": ("bitrate", "id_bits"),
}


def _problems(cfg: RuntimeConfig) -> list[str]:
    """What a hand-edited or damaged file gets wrong: numbers that are not integers, names that lead nowhere."""
    out: list[str] = []

    def ints(kind: str, name: str, obj: object) -> None:
        for attr in _INT_FIELDS[kind]:
            v = getattr(obj, attr)
            if v is not None and (not isinstance(v, int) or isinstance(v, bool) or v < 0):
                out.append(f"{kind} '{name}': {attr} must be a non-negative integer, not {v!r}")

    buses = {b.name for b in cfg.buses}
    nodes = {n.name for n in cfg.nodes}
    messages = {m.name for m in cfg.messages}
    triggers = {t.name for t in cfg.triggers}
    tasks = {t.ref for n in cfg.nodes for t in n.tasks}
    for b in cfg.buses:
        ints("bus", b.name, b)
        out += [f"bus '{b.name}': node '{n}' is not in the config" for n in b.nodes if n not in nodes]
    for n in cfg.nodes:
        out += [f"node '{n.name}': bus '{b}' is not in the config" for b in n.buses if b not in buses]
        for t in n.tasks:
            ints("task", t.ref, t)
            if t.trigger is not None and t.trigger not in triggers:
                out.append(f"task '{t.ref}': trigger '{t.trigger}' is not in the config")
            if t.on_message is not None and t.on_message not in messages:
                out.append(f"task '{t.ref}': message '{t.on_message}' is not in the config")
            if t.sync_bus is not None and t.sync_bus not in buses:
                out.append(f"task '{t.ref}': bus '{t.sync_bus}' is not in the config")
    for m in cfg.messages:
        ints("message", m.name, m)
        if m.bus not in buses:
            out.append(f"message '{m.name}': bus '{m.bus}' is not in the config")
        ends = (m.producer, *m.consumers)
        out += [f"message '{m.name}': node '{x}' is not in the config" for x in ends if x not in nodes]
        out += [f"message '{m.name}': task '{x}' is not in the config" for x in m.sent_by or () if x not in tasks]
    for trig in cfg.triggers:
        out += [f"trigger '{trig.name}': task '{x}' is not in the config" for x in trig.tasks if x not in tasks]
    for f in cfg.flows:
        for step in f.steps:
            known = tasks if step.kind == "task" else messages
            out += [f"flow '{f.name}': {step.kind} '{r}' is not in the config" for r in step.refs if r not in known]
    return out


def _config(d: dict[str, Any], source: str) -> RuntimeConfig:
    buses = tuple(_bus(b) for b in d["buses"])
    carried = {b.name: (b.protocol, b.link) for b in buses}
    return RuntimeConfig(
        format=d["format"],
        version=d["version"],
        system=d["system"],
        spec_sha256=d["spec_sha256"],
        buses=buses,
        nodes=tuple(_node(n) for n in d["nodes"]),
        messages=tuple(_message(m, *carried[m["bus"]]) for m in d["messages"]),
        triggers=tuple(_trigger(t) for t in d["triggers"]),
        flows=tuple(_flow(f) for f in d["flows"]),
        source=source,
    )


def _strs(items: Iterable[Any]) -> tuple[str, ...]:
    return tuple(str(x) for x in items)


def _opt_float(x: Any) -> float | None:
    return None if x is None else float(x)


def _bus(d: dict[str, Any]) -> Bus:
    co, ft, eth = d["canopen"], d["ftt"], d["ethernet"]
    return Bus(
        name=d["name"],
        protocol=d["protocol"],
        link=bus_link(d),
        bitrate=d["bitrate"],
        data_bitrate=d.get("data_bitrate"),
        clock_tolerance_ppm=d.get("clock_tolerance_ppm", DEFAULT_CLOCK_TOLERANCE_PPM),
        ethercat=d.get("ethercat"),
        errors=None if d.get("errors") is None else ErrorAssumption(d["errors"]["burst"], d["errors"]["interval_ns"]),
        id_bits=d["id_bits"],
        nodes=_strs(d["nodes"]),
        canopen=None
        if co is None
        else CanopenParams(
            co["sync_period_ns"],
            co["sync_window_ns"],
            co["read_window_ns"],
            co["sync_producer"],
            co["sync_id"],
            co.get("master_jitter_ns", 0),
            co.get("sync_overflow", 0),
            co.get("sync_completion_ns"),
        ),
        ftt=None if ft is None else _ftt(ft),
        ethernet=None
        if eth is None
        else EthernetParams(
            tuple(
                Switch(
                    s["name"],
                    s["latency_ns"],
                    tuple(SwitchPort(p["port"], p["to"], float(p["cable_m"]), p.get("queue")) for p in s["ports"]),
                    s.get("queue"),
                )
                for s in eth["switches"]
            ),
            None if eth.get("nics") is None else tuple((n["node"], n["queue"]) for n in eth["nics"]),
        ),
    )


def _ftt(d: dict[str, Any]) -> FttParams:
    return FttParams(
        ec_ns=d["ec_ns"],
        tm_size=d["tm_size"],
        tm_id=d["tm_id"],
        tm_ns=d["tm_ns"],
        lsw_ns=d["lsw_ns"],
        master=d["master"],
        macro_cycle_ec=d["macro_cycle_ec"],
        srt=tuple(
            SrtEntry(
                e["ftt_id"],
                e["name"],
                e["kind"],
                _strs(e["targets"]),
                e["period_ec"],
                e["fastest_period_ec"],
                e["init_ec"],
            )
            for e in d["srt"]
        ),
        schedule=tuple(
            EcSlot(
                s["ec"],
                tuple(s["ids"]),
                _strs(s["messages"]),
                _strs(s["triggers"]),
                s["mask"],
                s["sync_ns"],
                s["async_ns"],
                s.get("allowance_ns", 0),
            )
            for s in d["schedule"]
        ),
        sync_first=d.get("windows", "async-first") == "sync-first",
    )


def _node(d: dict[str, Any]) -> Node:
    return Node(
        name=d["name"],
        node_id=d["node_id"],
        role=d["role"],
        buses=_strs(d["buses"]),
        ip=d["ip"],
        device=d["device"],
        heartbeat_ns=d["heartbeat_ns"],
        tx_delay_ns=d["tx_delay_ns"],
        rx_delay_ns=d["rx_delay_ns"],
        tasks=tuple(
            Task(
                d["name"],
                t["name"],
                t["period_ns"],
                t["offset_ns"],
                t["wcet_ns"],
                t["bcet_ns"],
                t["trigger"],
                t["on_message"],
                t.get("sync_bus"),
            )
            for t in d["tasks"]
        ),
        identity=_identity(d.get("identity")),
        eds=d.get("eds"),
        dcf=d.get("dcf"),
        sdo_init=None
        if d.get("sdo_init") is None
        else tuple(SdoWrite(w["index"], w["sub"], w["data_type"], w["value"]) for w in d["sdo_init"]),
        rpdo_count=d.get("rpdo_count"),
        tpdo_count=d.get("tpdo_count"),
        heartbeat_timeout_ns=d.get("heartbeat_timeout_ns"),
        on_loss=d.get("on_loss", "stop_all"),
        on_emcy=d.get("on_emcy", "stop_all"),
        on_reboot=d.get("on_reboot", "stop_node"),
        sdo_timeout_ns=d.get("sdo_timeout_ns", 500_000_000),
        sdo_retries=d.get("sdo_retries", 0),
        safe_stop=d.get("safe_stop", "quick_stop"),
        tx_queue=TxQueue(**d["tx_queue"]) if d.get("tx_queue") else TxQueue(),
        actuator=_actuator(d.get("actuator")),
    )


def _actuator(d: dict[str, Any] | None) -> Actuator | None:
    if d is None:
        return None
    return Actuator(
        profile=d["profile"],
        parameters=tuple((str(k), v) for k, v in d["parameters"]),
        commanded_by=d["commanded_by"],
        commands=tuple(ActuatorCommand(c["command"], c["message"], c["reply"], c["reply_message"])
                       for c in d["commands"]),
        cyclic=tuple((c["profile_message"], c["message"]) for c in d["cyclic"]),
    )


def _identity(d: dict[str, Any] | None) -> NodeIdentity | None:
    return None if d is None else NodeIdentity(d["vendor_id"], d["product_code"], d["revision"])


def _message(d: dict[str, Any], protocol: str, link: str) -> Message:
    pdo, udp, rate = d["pdo"], d["udp"], d["rate_hz"]
    return Message(
        name=d["name"],
        bus=d["bus"],
        protocol=protocol,
        link=link,
        producer=d["producer"],
        consumers=_strs(d["consumers"]),
        id=d["id"],
        extended=bool(d["extended"]),
        size=d["size"],
        kind=d["kind"],
        period_ns=d["period_ns"],
        interval_ns=d["interval_ns"],
        offset_ns=d["offset_ns"],
        deadline_ns=d["deadline_ns"],
        jitter_ns=d["jitter_ns"],
        rate_hz=None if rate is None else Fraction(rate[0], rate[1]),
        window=d["window"],
        ftt_id=d["ftt_id"],
        fd=bool(d.get("fd", False)),
        brs=bool(d.get("brs", False)),
        frame_size=d.get("frame_size", 0),
        remote=bool(d.get("remote", False)),
        udp=None if udp is None else UdpPorts(udp["src_port"], udp["dst_port"]),
        pdo=None
        if pdo is None
        else Pdo(
            kind=pdo["kind"],
            number=pdo["number"],
            node=pdo["node"],
            transmission=pdo["transmission"],
            inhibit_100us=pdo["inhibit_100us"],
            event_timer_ms=pdo["event_timer_ms"],
            sync_start=pdo["sync_start"],
            entries=tuple(PdoEntry(e["index"], e["sub"], e["bits"], e["name"], e["data_type"]) for e in pdo["entries"]),
            cob_id=pdo.get("cob_id"),
        ),
        signals=tuple(
            Signal(
                name=s["name"],
                start_bit=s["start_bit"],
                bits=s["bits"],
                signed=bool(s["signed"]),
                is_float=bool(s["float"]),
                scale=float(s["scale"]),
                offset=float(s["offset"]),
                minimum=_opt_float(s["min"]),
                maximum=_opt_float(s["max"]),
                unit=s["unit"],
                big_endian=s.get("byte_order", "little_endian") == "big_endian",
                mux=s.get("mux"),
                mux_values=tuple(int(v) for v in s.get("mux_values", ())),
                choices=tuple((int(raw), str(name)) for raw, name in s.get("enum", ())),
            )
            for s in d["signals"]
        ),
        implicit=d["implicit"],
        wcrt_ns=d["wcrt_ns"],
        sent_by=None if d.get("sent_by") is None else _strs(d["sent_by"]),
        wcrt_unsync_ns=d.get("wcrt_unsync_ns"),
    )


def _trigger(d: dict[str, Any]) -> Trigger:
    return Trigger(
        d["name"], d["bus"], d["ftt_id"], d["period_ns"], d["interval_ns"], d["offset_ns"], _strs(d["tasks"])
    )


def _flow(d: dict[str, Any]) -> Flow:
    return Flow(
        name=d["name"],
        steps=tuple(FlowStep(s["kind"], _strs(s["refs"])) for s in d["steps"]),
        deadline_ns=d["deadline_ns"],
        latency_min_ns=d["latency_min_ns"],
        latency_max_ns=d["latency_max_ns"],
        unsync_latency_min_ns=d.get("unsync_latency_min_ns"),
        unsync_latency_max_ns=d.get("unsync_latency_max_ns"),
    )
