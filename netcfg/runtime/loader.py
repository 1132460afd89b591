"""Reading a runtime.json: the input guard, the format and version check, the schema check
(netcfg.runtime.schema), and the mapping of its JSON onto netcfg.runtime.config's classes. Re-exported by
netcfg.runtime."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from fractions import Fraction
from pathlib import Path
from typing import Any, TypeVar

from netcfg.inputs import InputError, JsonInputError, parse_json, read_input_text
from netcfg.runtime import config, pdos
from netcfg.runtime.actuators import Actuator, ActuatorCommand
from netcfg.runtime.config import RuntimeConfig
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
    return _record(
        RuntimeConfig,
        d,
        buses=buses,
        nodes=tuple(_node(n) for n in d["nodes"]),
        messages=tuple(_message(m, *carried[m["bus"]]) for m in d["messages"]),
        triggers=tuple(_record(config.Trigger, t, tasks=_strs(t["tasks"])) for t in d["triggers"]),
        flows=tuple(_flow(f) for f in d["flows"]),
        source=source,
    )


R = TypeVar("R")
_REQUIRED = object()


_KEYS: dict[type, tuple[tuple[str, Any], ...]] = {}


def _keys(cls: type) -> tuple[tuple[str, Any], ...]:
    """(field, default) of each field a record takes; _REQUIRED where it has no default."""
    keys = _KEYS.get(cls)
    if keys is None:
        keys = _KEYS[cls] = tuple(
            (f.name, _REQUIRED if f.default is dataclasses.MISSING else f.default)
            for f in dataclasses.fields(cls)
            if f.init
        )
    return keys


def _record(cls: type[R], d: Mapping[str, Any], **given: Any) -> R:
    """One of runtime.json's objects as the record cls: runtime.json names each key as the record's field, and a
    field with a default is a key added later within version 1, so a file written before it may lack it (read as
    that default). `given`: the fields read otherwise (nested records, tuples, renamed keys)."""
    for key, default in _keys(cls):
        if key not in given:
            given[key] = d[key] if default is _REQUIRED else d.get(key, default)
    return cls(**given)


def _strs(items: Iterable[Any]) -> tuple[str, ...]:
    return tuple(str(x) for x in items)


def _opt_float(x: Any) -> float | None:
    return None if x is None else float(x)


def _bus(d: dict[str, Any]) -> config.Bus:
    co, ft, eth, errors = d["canopen"], d["ftt"], d["ethernet"], d.get("errors")
    return _record(
        config.Bus,
        d,
        link=bus_link(d),
        errors=None if errors is None else _record(config.ErrorAssumption, errors),
        nodes=_strs(d["nodes"]),
        canopen=None if co is None else _record(config.CanopenParams, co),
        ftt=None if ft is None else _ftt(ft),
        ethernet=None if eth is None else _ethernet(eth),
    )


def _ethernet(d: dict[str, Any]) -> config.EthernetParams:
    return config.EthernetParams(
        tuple(
            _record(
                config.Switch,
                s,
                ports=tuple(_record(config.SwitchPort, p, cable_m=float(p["cable_m"])) for p in s["ports"]),
            )
            for s in d["switches"]
        ),
        None if d.get("nics") is None else tuple((n["node"], n["queue"]) for n in d["nics"]),
    )


def _ftt(d: dict[str, Any]) -> config.FttParams:
    return _record(
        config.FttParams,
        d,
        srt=tuple(_record(config.SrtEntry, e, targets=_strs(e["targets"])) for e in d["srt"]),
        schedule=tuple(
            _record(
                config.EcSlot,
                s,
                ids=tuple(s["ids"]),
                messages=_strs(s["messages"]),
                triggers=_strs(s["triggers"]),
            )
            for s in d["schedule"]
        ),
        sync_first=d.get("windows", "async-first") == "sync-first",
    )


def _node(d: dict[str, Any]) -> config.Node:
    identity, sdo_init = d.get("identity"), d.get("sdo_init")
    return _record(
        config.Node,
        d,
        buses=_strs(d["buses"]),
        tasks=tuple(_record(config.Task, t, node=d["name"]) for t in d["tasks"]),
        identity=None if identity is None else _record(config.NodeIdentity, identity),
        sdo_init=None if sdo_init is None else tuple(_record(config.SdoWrite, w) for w in sdo_init),
        tx_queue=config.TxQueue(**d["tx_queue"]) if d.get("tx_queue") else config.TxQueue(),
        actuator=_actuator(d.get("actuator")),
    )


def _actuator(d: dict[str, Any] | None) -> Actuator | None:
    if d is None:
        return None
    return _record(
        Actuator,
        d,
        parameters=tuple((str(k), v) for k, v in d["parameters"]),
        commands=tuple(_record(ActuatorCommand, c) for c in d["commands"]),
        cyclic=tuple((c["profile_message"], c["message"]) for c in d["cyclic"]),
    )


def _message(d: dict[str, Any], protocol: str, link: str) -> config.Message:
    pdo, udp, rate, sent_by = d["pdo"], d["udp"], d["rate_hz"], d.get("sent_by")
    return _record(
        config.Message,
        d,
        protocol=protocol,
        link=link,
        consumers=_strs(d["consumers"]),
        extended=bool(d["extended"]),
        rate_hz=None if rate is None else Fraction(rate[0], rate[1]),
        fd=bool(d.get("fd", False)),
        brs=bool(d.get("brs", False)),
        remote=bool(d.get("remote", False)),
        udp=None if udp is None else _record(config.UdpPorts, udp),
        pdo=None
        if pdo is None
        else _record(pdos.Pdo, pdo, entries=tuple(_record(pdos.PdoEntry, e) for e in pdo["entries"])),
        signals=tuple(
            config.Signal(
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
        sent_by=None if sent_by is None else _strs(sent_by),
    )


def _flow(d: dict[str, Any]) -> config.Flow:
    return _record(
        config.Flow, d, steps=tuple(_record(config.FlowStep, s, refs=_strs(s["refs"])) for s in d["steps"])
    )
