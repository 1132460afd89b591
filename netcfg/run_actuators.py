"""`netcfg run` on actuator buses, as a library: the buses, the simulated actuators, the drills, one master per bus
(netcfg.runtime.actuator_master), all at once, and their result as text or as the JSON document.

The JSON document: {"ok", "system", "bus", "period_ms", "cycles", "ended_by", "actuators": {name: {"profile",
"state", "enabled", "commands", "replies", "missing", "late", "reply_delay_us": {"min", "mean", "max"} | null,
"reply_bound_us", "loss_timeout_ms", "heard": {message: frames}, "last": {message: {field: SI value}}, "states",
"errors", "lost_at_s", "stopped_at_s", "safe_stop"}}, "sends": {"late_max_us", "late_mean_us", "missed_releases"}
(how late after its release the host sent each command; a release sent a whole period or more late is missed),
"events": [{"t_s", "node", "kind", "detail", "action"}],
"drills": [{"t_s", "what"}], "unknown_frames", "simulated": {name: frames sent} | null}: one bus's; a run of
several buses prints {"ok", "system", "buses": [one such document per bus]}.
"""

from __future__ import annotations

import math
import sys
import threading
from collections.abc import Callable, Iterator, Mapping
from contextlib import AbstractContextManager
from functools import partial
from pathlib import Path
from typing import Any

from netcfg.runtime.actuator_master import ActuatorMaster, ActuatorRun, ActuatorRunPlan
from netcfg.runtime.actuator_plan import plan_actuators
from netcfg.runtime.codec import CodecError
from netcfg.runtime.config import RuntimeConfig
from netcfg.runtime.drills import Drill

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


def run_actuator_buses(
    cfg: RuntimeConfig,
    bus_names: list[str],
    *,
    interface: str,
    channels: Mapping[str, str | None],
    simulated: bool,
    cycles: int | None,
    duration_s: float | None,
    settings: list[str],
    drills: list[Drill],
    log: Path | None,
    stop_on_signals: Callable[[], AbstractContextManager[Arm]],
    fmt: str,
) -> int:
    """The command's work once the configuration is read: one master per bus (`channels`: each bus's python-can
    channel), all at once, each bus's cycle counted in its own control period; their frames in one log, each under
    its bus's name when there are several. An actuator's stop_all stops every bus. The exit code: 0 ok, 1 a
    fault, 2 usage or I/O."""
    import can

    from netcfg import jsontext
    from netcfg.runtime.bus_log import BusLog, LogFile

    bus_of = {n.name: b for n in cfg.nodes if n.actuator is not None for b in n.buses if b in bus_names}
    values: dict[str, dict[tuple[str, str], dict[str, float | str]]] = {b: {} for b in bus_names}
    masters: dict[str, ActuatorMaster] = {}
    try:
        for text in settings:
            key, field, value = parse_setting(text)
            # a node on none of the buses goes to the first, whose plan names what it has
            values[bus_of.get(key[0], bus_names[0])].setdefault(key, {})[field] = value
        for b in bus_names:
            masters[b] = ActuatorMaster(plan_actuators(cfg, b, values[b]), b)
    except (ValueError, CodecError) as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    for d in drills:
        node = str(d.node)
        if node not in bus_of:
            where = f"bus '{bus_names[0]}'" if len(bus_names) == 1 else f"buses {', '.join(bus_names)}"
            print(f"netcfg: '{node}' is not an actuator of {where} ({', '.join(sorted(bus_of))})", file=sys.stderr)
            return 2
    for m in masters.values():  # stop_all: every actuator of the run
        m.on_stop_all = partial(_stop_others, list(masters.values()), m)
    plans: dict[str, ActuatorRunPlan] = {}
    for b, m in masters.items():
        period_s = m.period_ns / 1e9
        n = cycles if duration_s is None else max(1, math.ceil(duration_s / period_s - 1e-9))
        plans[b] = ActuatorRunPlan(cycles=n)
    benches: dict[str, Any] = {}
    opened: list[BusLog] = []
    shared = None
    several = len(bus_names) > 1
    try:
        if simulated:
            from netcfg.runtime.simulated_actuator import ActuatorBench

            for b in bus_names:
                benches[b] = ActuatorBench(cfg, b, channel=str(channels[b]), interface=interface).start()
        if log is not None and several:
            try:
                shared = LogFile(log)
            except (OSError, ValueError) as exc:
                print(f"netcfg: cannot write the log {log}: {exc}", file=sys.stderr)
                return 2
        buses: dict[str, BusLog] = {}
        for b in bus_names:
            try:
                raw = can.Bus(interface=interface, channel=channels[b], bitrate=cfg.bus(b).bitrate)
            except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as exc:
                print(f"netcfg: cannot open the CAN interface {interface!r} channel {channels[b]!r}: {exc}",
                      file=sys.stderr)
                return 2
            try:
                bus = BusLog(raw, None, log=shared, channel=b) if several else BusLog(raw, log)
            except (OSError, ValueError) as exc:
                raw.shutdown()
                print(f"netcfg: cannot write the log {log}: {exc}", file=sys.stderr)
                return 2
            opened.append(bus)
            buses[b] = bus
        for d in drills:  # a kill silences the simulated actuator, a fault sets its error fields
            b = bus_of[str(d.node)]
            if b in benches:
                actuator = benches[b][str(d.node)]
                action = {"kill": actuator.kill, "fault": actuator.fault}[d.kind]  # ACTUATOR_KINDS, as parsed
                plans[b].drills.append((d.at_s, d.description(), action))
        with stop_on_signals() as arm:
            arm(partial(_stop_others, list(masters.values()), None))
            results = _run_all(masters, buses, plans)
    finally:
        for bus in opened:
            bus.shutdown()
        if shared is not None:
            shared.close()
        for bench in benches.values():
            bench.stop()
    docs = []
    for b in bus_names:
        frames = {n: a.answered for n, a in benches[b].actuators.items()} if b in benches else None
        docs.append(result_document(results[b], cfg.system, frames))
    doc = docs[0] if not several else {"ok": all(d["ok"] for d in docs), "system": cfg.system, "buses": docs}
    if fmt == "json":
        print(jsontext.dumps(doc, indent=2))
    else:
        print("\n".join(result_text(d) for d in docs))
        if several:
            print(f"result, {len(docs)} buses: {'OK' if doc['ok'] else 'FAILED'}")
        if log is not None:
            print(f"bus log: {log}" + (" (each frame under its bus's name)" if several else ""))
    return 0 if doc["ok"] else 1


def _stop_others(masters: list[ActuatorMaster], me: ActuatorMaster | None, reason: str) -> None:
    for m in masters:
        if m is not me:
            m.stop(reason)


def _run_all(masters: dict[str, ActuatorMaster], buses: Mapping[str, Any],
             plans: Mapping[str, ActuatorRunPlan]) -> dict[str, ActuatorRun]:
    """Every bus's master at once, each in a thread of its own but the first, which runs in this one (where the
    signal handlers are); an exception in a bus's thread stops the others and is raised here."""
    results: dict[str, ActuatorRun] = {}
    failed: list[BaseException] = []

    def one(b: str) -> None:
        try:
            results[b] = masters[b].run(buses[b], plans[b])
        except BaseException as exc:  # re-raised in the calling thread
            failed.append(exc)
            for m in masters.values():
                m.stop(f"bus '{b}' failed")

    names = list(masters)
    threads = [threading.Thread(target=one, args=(b,), name=f"actuators-{b}", daemon=True) for b in names[1:]]
    for t in threads:
        t.start()
    one(names[0])
    for t in threads:
        t.join()
    if failed:
        raise failed[0]
    return results


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
        "ended_by": run.ended_by, "actuators": actuators, "sends": _sends(run),
        "events": [{"t_s": e.t_s, "node": e.node, "kind": e.kind, "detail": e.detail, "action": e.action}
                   for e in run.events],
        "drills": [{"t_s": t, "what": what} for t, what in run.drills],
        "unknown_frames": run.unknown_frames, "simulated": dict(simulated) if simulated is not None else None,
    }


def _sends(run: ActuatorRun) -> dict[str, Any]:
    most, total, n = run.send_late_us
    return {"late_max_us": round(most, 1) if n else None, "late_mean_us": round(total / n, 1) if n else None,
            "missed_releases": run.missed_releases}


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
    s = doc["sends"]
    if s["late_max_us"] is not None:
        lines.append(f"  commands sent after their release: mean {s['late_mean_us']:.0f} us, max "
                     f"{s['late_max_us']:.0f} us; releases missed (sent a period or more late): {s['missed_releases']}")
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
