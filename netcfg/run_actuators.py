"""`netcfg run` on an actuator bus, as a library: the bus, the simulated actuators, the drills, the master
(netcfg.runtime.actuator_master) and its result as text or as the JSON document.

The JSON document: {"ok", "system", "bus", "period_ms", "cycles", "ended_by", "actuators": {name: {"profile",
"state", "enabled", "commands", "replies", "missing", "late", "reply_delay_us": {"min", "mean", "max"} | null,
"reply_bound_us", "loss_timeout_ms", "heard": {message: frames}, "last": {message: {field: SI value}}, "states",
"errors", "lost_at_s", "stopped_at_s", "safe_stop"}}, "events": [{"t_s", "node", "kind", "detail", "action"}],
"drills": [{"t_s", "what"}], "unknown_frames", "simulated": {name: frames sent} | null}.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import AbstractContextManager
from functools import partial
from pathlib import Path
from typing import Any

from netcfg.runtime.actuator_master import ActuatorMaster, ActuatorRun, ActuatorRunPlan
from netcfg.runtime.actuator_plan import plan_actuators
from netcfg.runtime.codec import CodecError
from netcfg.runtime.config import RuntimeConfig

Arm = Callable[[Callable[[str], None]], None]


def parse_setting(text: str) -> tuple[tuple[str, str], str, float | str]:
    """'NODE.COMMAND.FIELD=VALUE' -> ((node, command), field, number or value name)."""
    where, eq, value = text.partition("=")
    parts = where.split(".")
    if not eq or len(parts) != 3 or not all(parts) or not value:
        raise ValueError(f"--set {text!r}: write NODE.COMMAND.FIELD=VALUE, e.g. wrist.mit_command.kp=20")
    try:
        number: float | str = float(value)
    except ValueError:
        number = value  # a value name (ODrive's CLOSED_LOOP_CONTROL)
    return (parts[0], parts[1]), parts[2], number


def run_actuator_bus(
    cfg: RuntimeConfig,
    bus_name: str,
    *,
    interface: str,
    channel: str | None,
    simulated: bool,
    cycles: int | None,
    duration_s: float | None,
    settings: list[str],
    kills: list[tuple[str, float]],
    faults: list[tuple[str, float]],
    log: Path | None,
    stop_on_signals: Callable[[], AbstractContextManager[Arm]],
    fmt: str,
) -> int:
    """The command's work once the configuration is read; its exit code (0 ok, 1 a fault, 2 usage or I/O)."""
    import can

    from netcfg import jsontext
    from netcfg.runtime.bus_log import BusLog

    values: dict[tuple[str, str], dict[str, float | str]] = {}
    try:
        for text in settings:
            key, field, value = parse_setting(text)
            values.setdefault(key, {})[field] = value
        plans = plan_actuators(cfg, bus_name, values)
        master = ActuatorMaster(plans, bus_name)
    except (ValueError, CodecError) as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    names = {p.name for p in plans}
    for node, _ in [*kills, *faults]:
        if node not in names:
            print(f"netcfg: '{node}' is not an actuator of bus '{bus_name}' ({', '.join(sorted(names))})",
                  file=sys.stderr)
            return 2
    period_s = master.period_ns / 1e9
    if duration_s is not None:
        cycles = max(1, math.ceil(duration_s / period_s - 1e-9))
    bench = None
    if simulated:
        from netcfg.runtime.simulated_actuator import ActuatorBench

        bench = ActuatorBench(cfg, bus_name, channel=str(channel), interface=interface).start()
    try:
        try:
            raw = can.Bus(interface=interface, channel=channel, bitrate=cfg.bus(bus_name).bitrate)
        except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as exc:
            print(f"netcfg: cannot open the CAN interface {interface!r} channel {channel!r}: {exc}", file=sys.stderr)
            return 2
        try:
            bus = BusLog(raw, log)
        except (OSError, ValueError) as exc:
            raw.shutdown()
            print(f"netcfg: cannot write the log {log}: {exc}", file=sys.stderr)
            return 2
        drills: list[tuple[float, str, Callable[[], None]]] = []
        if bench is not None:
            drills += [(at, f"{node} killed", bench[node].kill) for node, at in kills]
            drills += [(at, f"{node} reports an error", partial(bench[node].fault)) for node, at in faults]
        with bus, stop_on_signals() as arm:
            arm(master.stop)
            result = master.run(bus, ActuatorRunPlan(cycles=cycles, drills=drills))
    finally:
        if bench is not None:
            bench.stop()
    simulated_frames = {n: a.answered for n, a in bench.actuators.items()} if bench is not None else None
    doc = result_document(result, cfg.system, simulated_frames)
    if fmt == "json":
        print(jsontext.dumps(doc, indent=2))
    else:
        print(result_text(doc))
        if log is not None:
            print(f"bus log: {log}")
    return 0 if doc["ok"] else 1


def result_document(run: ActuatorRun, system: str, simulated: Mapping[str, int] | None = None) -> dict[str, Any]:
    actuators = {}
    for name, a in run.actuators.items():
        d = a.delay_us
        actuators[name] = {
            "profile": a.profile, "state": a.state, "enabled": a.enabled, "commands": a.commands,
            "replies": a.replies, "missing": a.missing, "late": a.late,
            "reply_delay_us": {"min": round(d[0], 1), "mean": round(d[2] / d[3], 1), "max": round(d[1], 1)}
            if d else None,
            "reply_bound_us": a.bound_us, "loss_timeout_ms": a.loss_timeout_ms, "heard": dict(sorted(a.heard.items())),
            "last": {m: {k: _number(v) for k, v in vals.items()} for m, vals in sorted(a.last.items())},
            "states": dict(sorted(a.states.items())), "errors": list(a.errors), "lost_at_s": a.lost_at_s,
            "stopped_at_s": a.stopped_at_s, "safe_stop": a.safe_stop,
        }
    return {
        "ok": run.ok, "system": system, "bus": run.bus, "period_ms": run.period_ns / 1e6, "cycles": run.cycles,
        "ended_by": run.ended_by, "actuators": actuators,
        "events": [{"t_s": e.t_s, "node": e.node, "kind": e.kind, "detail": e.detail, "action": e.action}
                   for e in run.events],
        "drills": [{"t_s": t, "what": what} for t, what in run.drills],
        "unknown_frames": run.unknown_frames, "simulated": dict(simulated) if simulated is not None else None,
    }


def _number(v: float) -> float:
    return round(float(v), 6)


def result_text(doc: Mapping[str, Any]) -> str:
    lines = [f"== {doc['system']}: actuator bus {doc['bus']}, {doc['cycles']} cycles of {doc['period_ms']:g} ms, "
             f"ended by {doc['ended_by']}"]
    head = ("actuator", "profile", "state", "enable", "commands", "replies", "missing", "late", "delay us min/mean/max",
            "bound us", "safe stop")
    rows: list[tuple[str, ...]] = [head]
    for name, a in doc["actuators"].items():
        d = a["reply_delay_us"]
        rows.append((
            name, a["profile"], a["state"], a["enabled"] or "-", str(a["commands"]), str(a["replies"]),
            str(a["missing"]), str(a["late"]), f"{d['min']:.0f}/{d['mean']:.0f}/{d['max']:.0f}" if d else "-",
            f"{a['reply_bound_us']:.0f}" if a["reply_bound_us"] is not None else "-", a["safe_stop"] or "-",
        ))
    lines += _table(rows)
    for name, a in doc["actuators"].items():
        states = ", ".join(f"{k} {v}" for k, v in a["states"].items())
        if states:
            lines.append(f"  {name}: {states}")
    for d in doc["drills"]:
        lines.append(f"drill: {d['t_s']:.3f} s {d['what']}")
    for e in doc["events"]:
        action = f" -> {e['action']}" if e["action"] else ""
        lines.append(f"{e['t_s']:.3f} s {e['node']} {e['kind']}: {e['detail']}{action}")
    lines.append("result: OK" if doc["ok"] else "result: FAILED")
    return "\n".join(lines)


def _table(rows: list[tuple[str, ...]]) -> Iterator[str]:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for k, r in enumerate(rows):
        yield "  " + "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
        if k == 0:
            yield "  " + "  ".join("-" * w for w in widths)
