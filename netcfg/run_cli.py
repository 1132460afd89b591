"""`netcfg run`: the live CANopen master on any python-can interface, or on netcfg's simulated drives.

    netcfg run build/allex2/runtime.json --interface virtual --simulated-drives --cycles 100
    netcfg run specs/allex2.yaml --interface socketcan --channel can0 --duration 8s --log gait.log

A spec is compiled in memory first; a runtime.json is read as a master reads it (netcfg.runtime.load). The work is
netcfg.runtime.operate's: set-up, CiA 402 to OPERATION ENABLED, the SYNC cycle with heartbeat and EMCY supervision,
the safe stop. This module parses the command line, builds the bus (and the simulated drives), shows a live view on
a terminal, and prints the result as text or as the JSON of the design notes: {"cycles", "nodes": [{"name",
"state", "samples", "missing", "lost", "emcy"}]} with more keys beside them.

Fault drills (README "Faults the live master survives"): --kill, --emcy, --reset and --sdo-abort act on the
simulated drives, --stall on the master's loop, --bus-off on the master's controller (netcfg's bus wrapper).

Exit codes: 0 every started node delivered every cycle, none was lost, rebooted or sent an EMCY, no SYNC was missed
and the bus never went off; 1 otherwise, or the spec
or runtime.json has errors, or the set-up failed; 2 usage or I/O (bad option, a bus that cannot be opened).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import Any, TextIO

from netcfg import jsontext

__all__ = ["add_parser", "run_command"]

LOG_SUFFIXES = (".log", ".asc", ".blf", ".csv", ".trc")
DEFAULT_EMCY = 0x2310  # CiA 402: "continuous over-current", a drive's typical fault
DEFAULT_ABORT = 0x08000020  # CiA 301: "data cannot be transferred or stored to the application"


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "run", help="the live CANopen master: set up, CiA 402 enable, SYNC cycle, supervise, stop safely"
    )
    p.add_argument("source", type=Path, metavar="SPEC|RUNTIME_JSON")
    p.add_argument("--interface", default=None, help="python-can interface: socketcan, pcan, kvaser, virtual, ...")
    p.add_argument("--channel", default=None, help="python-can channel, e.g. can0 (virtual: any name)")
    p.add_argument(
        "--simulated-drives",
        action="store_true",
        help="bring up netcfg's simulated drives on the (virtual) bus: the quick start, no hardware",
    )
    p.add_argument("--bus", default=None, help="which CANopen bus of the configuration (default: its only one)")
    length = p.add_mutually_exclusive_group()
    length.add_argument("--cycles", type=int, help="SYNC cycles to run (default: until Ctrl-C)")
    length.add_argument("--duration", help="how long to cycle, e.g. 8s or 500 ms (whole SYNC periods)")
    # the fault drills, each given as often as wanted
    drills = (
        ("--kill", "NODE@T", "simulated drives: NODE drops off the bus at T"),
        ("--emcy", "NODE@T[=CODE]", f"simulated drives: NODE sends an EMCY (default code 0x{DEFAULT_EMCY:04X}) and "
         "faults at T"),
        ("--reset", "NODE@T+OUTAGE", "simulated drives: NODE reboots at T, silent for OUTAGE, then boots with its "
         "default object dictionary"),
        ("--sdo-abort", "NODE:INDEX[:SUB][=CODE]", "simulated drives: NODE aborts every SDO write to that object "
         f"(default code 0x{DEFAULT_ABORT:08X})"),
        ("--stall", "T..T2", "the master's own loop pauses from T to T2 (no SYNC, no RxPDO), as a host that is "
         "held up"),
        ("--bus-off", "T..T2", "the master's CAN controller is bus-off from T to T2 (played by netcfg's bus wrapper)"),
    )
    for flag, metavar, text in drills:
        p.add_argument(flag, action="append", default=[], metavar=metavar, help=text)
    p.add_argument("--allow-missing", action="store_true", help="run the nodes that were set up even if others failed")
    p.add_argument("--log", type=Path, metavar="FILE", help="every frame: .log (candump -L), .asc, .blf, .csv, .trc")
    p.add_argument("--samples", type=Path, metavar="FILE.csv", help="the samples of every cycle, one row per cycle")
    p.add_argument("--format", choices=("text", "json"), default="text")


def _duration_s(text: str, what: str) -> float:
    from netcfg.spec.units import parse_duration

    d = parse_duration(text)
    if d.ns is None:
        raise ValueError(f"{what} {text!r}: give a time such as 1s or 500 ms")
    return d.ns / 1e9


def _span(text: str, kind: str) -> tuple[float, float]:
    """'T..T2' -> (seconds, seconds), T2 after T."""
    start, dots, end = text.partition("..")
    if not dots:
        raise ValueError(f"--{kind} {text!r}: write FROM..TO, e.g. 1s..1.2s")
    span = _duration_s(start.strip(), f"--{kind}"), _duration_s(end.strip(), f"--{kind}")
    if span[1] <= span[0]:
        raise ValueError(f"--{kind} {text!r}: the span ends before it begins")
    return span


def _reset_drill(text: str) -> tuple[str, float, float]:
    """'NODE@T+OUTAGE' -> (node, seconds, outage seconds)."""
    node, at, rest = text.partition("@")
    when, plus, outage = rest.partition("+")
    if not at or not node or not plus:
        raise ValueError(f"--reset {text!r}: write NODE@TIME+OUTAGE, e.g. knee_r@1s+50ms")
    return node, _duration_s(when.strip(), "--reset"), _duration_s(outage.strip(), "--reset outage")


def _abort_drill(text: str) -> tuple[str, int | tuple[int, int], int]:
    """'NODE:INDEX[:SUB][=CODE]' -> (node, index or (index, sub), abort code)."""
    where, eq, code = text.partition("=")
    node, *obj = where.split(":")
    try:
        if not node or len(obj) not in (1, 2):
            raise ValueError
        numbers = [int(o, 0) for o in obj]
        value = int(code, 0) if eq else DEFAULT_ABORT
    except ValueError:
        raise ValueError(
            f"--sdo-abort {text!r}: write NODE:INDEX[:SUB][=CODE], e.g. knee_r:0x1A00:0=0x06010002"
        ) from None
    if not 0 <= numbers[0] <= 0xFFFF or (len(numbers) == 2 and not 0 <= numbers[1] <= 0xFF) or not 0 <= value < 2**32:
        raise ValueError(f"--sdo-abort {text!r}: an index has 16 bits, a sub-index 8, an abort code 32")
    return node, numbers[0] if len(numbers) == 1 else (numbers[0], numbers[1]), value


def _drill(text: str, kind: str) -> tuple[str, float, int]:
    """'NODE@T' / 'NODE@T=CODE' -> (node, seconds, code)."""
    node, at, rest = text.partition("@")
    if not at or not node:
        raise ValueError(f"--{kind} {text!r}: write NODE@TIME, e.g. knee_r@1s")
    when, eq, code = rest.partition("=")
    if eq and kind != "emcy":
        raise ValueError(f"--{kind} {text!r}: only --emcy takes a code")
    try:
        value = int(code, 0) if eq else DEFAULT_EMCY
    except ValueError:
        raise ValueError(f"--emcy {text!r}: the code is a number such as 0x2310") from None
    if not 0 <= value <= 0xFFFF:
        raise ValueError(f"--emcy {text!r}: an EMCY error code has 16 bits")
    return node, _duration_s(when.strip(), f"--{kind}"), value


@contextmanager
def _config(source: Path) -> Iterator[Any]:
    """The runtime configuration; a spec is compiled in memory, its device files in a temporary folder for the
    simulated drives (removed afterwards). Yields None after printing errors."""
    from netcfg import runtime

    if source.suffix == ".json":
        yield runtime.load(source)
        return
    import importlib

    from netcfg.check import analyse_spec
    from netcfg.emit import EMITTERS, check_relative

    model, report = analyse_spec(source)
    for d in report["errors"]:
        print(f"{d['file']}:{d['line']}:{d['column']}: error: {d['message']} [{d['code']}]", file=sys.stderr)
    if model is None or not report["ok"]:
        print(f"netcfg: {source} has errors; nothing was run", file=sys.stderr)
        yield None
        return
    with tempfile.TemporaryDirectory(prefix="netcfg-run-") as tmp:
        for name in ("runtime", "canopen"):  # what a master and the simulated drives read; no report, no plots
            module, _, func = EMITTERS[name].partition(":")
            for rel, data in getattr(importlib.import_module(module), func)(model, report).items():
                check_relative(rel)
                path = Path(tmp) / rel
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_bytes(data)
        yield runtime.load(Path(tmp) / "runtime.json")


def run_command(args: argparse.Namespace) -> int:
    from netcfg import runtime

    try:
        kills = [_drill(k, "kill") for k in args.kill]
        emcys = [_drill(e, "emcy") for e in args.emcy]
        resets = [_reset_drill(r) for r in args.reset]
        aborts = [_abort_drill(a) for a in args.sdo_abort]
        for s in args.stall:
            _span(s, "stall")  # checked here, used by _run
        for s in args.bus_off:
            _span(s, "bus-off")
        duration_s = _duration_s(args.duration, "--duration") if args.duration is not None else None
    except ValueError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    if args.cycles is not None and args.cycles < 1:
        print("netcfg: --cycles must be 1 or more", file=sys.stderr)
        return 2
    if (kills or emcys or resets or aborts) and not args.simulated_drives:
        print(
            "netcfg: --kill, --emcy, --reset and --sdo-abort act on simulated drives; add --simulated-drives",
            file=sys.stderr,
        )
        return 2
    if args.simulated_drives and args.interface not in (None, "virtual"):
        print(
            "netcfg: --simulated-drives runs on python-can's virtual bus; drop --interface or give virtual",
            file=sys.stderr,
        )
        return 2
    if not args.simulated_drives and args.interface is None:
        print(
            "netcfg: say which bus: --interface I --channel C (e.g. socketcan can0), or --interface virtual "
            "--simulated-drives for netcfg's simulated drives",
            file=sys.stderr,
        )
        return 2
    if args.log is not None and args.log.suffix.lower() not in LOG_SUFFIXES:
        print(f"netcfg: --log {args.log}: the log formats are {', '.join(LOG_SUFFIXES)}", file=sys.stderr)
        return 2
    if not args.source.is_file():
        print(f"netcfg: cannot read {args.source}: no such file", file=sys.stderr)
        return 2
    try:
        with _config(args.source) as cfg:
            if cfg is None:
                return 1
            return _run(args, cfg, kills, emcys, resets, aborts, duration_s)
    except runtime.RuntimeConfigError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 1
    except json.JSONDecodeError as exc:
        print(
            f"{args.source}:{exc.lineno}:{exc.colno}: error: not valid JSON ({exc.msg}); rebuild it with "
            "'netcfg build'",
            file=sys.stderr,
        )
        return 1


def _run(
    args: argparse.Namespace,
    cfg: Any,
    kills: list[tuple[str, float, int]],
    emcys: list[tuple[str, float, int]],
    resets: list[tuple[str, float, float]],
    aborts: list[tuple[str, int | tuple[int, int], int]],
    duration_s: float | None,
) -> int:
    import can

    from netcfg.runtime.canopen_master import canopen_bus, canopen_slaves
    from netcfg.runtime.operate import BusLog, Plan, operate

    try:
        co_bus = canopen_bus(cfg, args.bus)
    except (ValueError, KeyError) as exc:
        text = str(exc).replace("with bus_name", "with --bus NAME")
        print(f"netcfg: {args.source}: {text}; `netcfg run` drives a CANopen bus", file=sys.stderr)
        return 2
    assert co_bus.canopen is not None
    slaves = {n.name for n in canopen_slaves(cfg, co_bus)}
    for node, _, _ in [*kills, *emcys, *resets, *aborts]:
        if node not in slaves:
            print(
                f"netcfg: '{node}' is not a CANopen slave of bus '{co_bus.name}' ({', '.join(sorted(slaves))})",
                file=sys.stderr,
            )
            return 2
    period_s = co_bus.canopen.sync_period_ns / 1e9
    cycles = args.cycles if duration_s is None else max(1, math.ceil(duration_s / period_s - 1e-9))
    interface = args.interface or "virtual"
    channel = args.channel or (f"netcfg-run-{os.getpid()}" if interface == "virtual" else None)

    bench = None
    if args.simulated_drives:
        from netcfg.runtime.drives import DriveBench

        refused: dict[str, dict[str, Any]] = {}
        for node, obj, code in aborts:
            refused.setdefault(node, {"abort_writes": {}})["abort_writes"][obj] = code
        bench = DriveBench(cfg, channel=str(channel), bus_name=co_bus.name, options=refused).start()
    try:
        try:
            raw = can.Bus(interface=interface, channel=channel, bitrate=co_bus.bitrate)
        except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as exc:
            print(f"netcfg: cannot open the CAN interface {interface!r} channel {channel!r}: {exc}", file=sys.stderr)
            return 2
        try:
            bus = BusLog(raw, args.log)
        except (OSError, ValueError) as exc:
            raw.shutdown()
            print(f"netcfg: cannot write the log {args.log}: {exc}", file=sys.stderr)
            return 2
        drills: list[tuple[float, str, Callable[[], None]]] = []
        for start, end in (_span(s, "bus-off") for s in args.bus_off):
            drills.append(
                (start, f"the master's CAN controller goes bus-off until {end:g} s", partial(bus.bus_off, end - start))
            )
        if bench is not None:
            for node, at, _ in kills:
                drills.append((at, f"{node} killed", bench[node].kill))
            for node, at, code in emcys:
                drills.append((at, f"{node} sends EMCY 0x{code:04X}", partial(bench[node].emergency, code)))
            for node, at, outage in resets:
                what = f"{node} reboots, silent for {1e3 * outage:g} ms"
                drills.append((at, what, partial(bench[node].reboot, outage)))
        live = (
            _LiveView(sys.stdout, cycles, {m.name: m.producer for m in cfg.messages})
            if args.format == "text" and sys.stdout.isatty()
            else None
        )
        plan = Plan(
            cycles=cycles,
            bus_name=co_bus.name,
            allow_missing=args.allow_missing,
            drills=drills,
            stalls=[_span(s, "stall") for s in args.stall],  # validated by run_command
            on_cycle=live.update if live is not None else None,
        )
        with bus, _stop_on_signals() as arm:
            outcome = operate(cfg, bus, plan, ready=arm)
        if live is not None:
            live.close()
    finally:
        if bench is not None:
            bench.stop()
    # what the simulated drives did on their own (a gap in the SYNCs, an RPDO deadline), as they would tell it
    drive_notes = {name: list(d.notes) for name, d in bench.drives.items() if d.notes} if bench is not None else {}
    if args.samples is not None and outcome.run is not None:
        try:
            outcome.run.write_csv(args.samples)
        except OSError as exc:
            print(f"netcfg: cannot write {args.samples}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    doc = result_document(outcome, cfg.system)
    doc["simulated_drives"] = drive_notes
    if args.format == "json":
        print(jsontext.dumps(doc, indent=2))
    else:
        print(result_text(outcome, doc))
        if args.log is not None:
            print(f"bus log: {args.log}")
    return 0 if doc["ok"] else 1


@contextmanager
def _stop_on_signals() -> Iterator[Callable[[Callable[[str], None]], None]]:
    """Ctrl-C (SIGINT) and SIGTERM end the cycle after the current iteration, then the safe stop runs; installed
    only once the cycle is about to start (`arm`), restored afterwards. A second Ctrl-C interrupts at once."""
    import signal  # here: the command line imports this module for its options on every command

    previous: dict[int, Any] = {}

    def arm(stop: Callable[[str], None]) -> None:
        def handler(signum: int, _frame: object) -> None:
            stop(f"signal {signal.Signals(signum).name}")
            signal.signal(signum, previous.get(signum, signal.default_int_handler))

        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                previous[sig] = signal.signal(sig, handler)
            except ValueError:  # not the main thread: Ctrl-C raises KeyboardInterrupt, the safe stop still runs
                return

    try:
        yield arm
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


class _LiveView:
    """One status line, rewritten every few cycles: cycle, period, read time, per node its state and missing."""

    def __init__(self, out: TextIO, cycles: int | None, producers: dict[str, str]) -> None:
        self.out, self.cycles, self.producers = out, cycles, producers
        self.missing: dict[str, int] = {}
        self.width = 0

    def update(self, record: Any, outcome: Any) -> None:
        for name in record.missing:
            node = self.producers.get(name, name)
            self.missing[node] = self.missing.get(node, 0) + 1
        if record.index % 5:
            return
        total = f"/{self.cycles}" if self.cycles else ""
        nodes = " ".join(
            f"{n.name}:{_short(n.state)}{'/' + str(self.missing[n.name]) if self.missing.get(n.name) else ''}"
            for n in outcome.nodes.values()
        )
        line = (
            f"cycle {record.index + 1}{total}  T {1e3 * record.period_s:6.3f} ms  read {1e3 * record.read_s:6.3f} ms"
            f"  {nodes}"
        )
        self.out.write("\r" + line.ljust(self.width))
        self.out.flush()
        self.width = len(line)

    def close(self) -> None:
        if self.width:
            self.out.write("\r" + " " * self.width + "\r")
            self.out.flush()


def _short(state: str) -> str:
    return {"OPERATION ENABLED": "OE", "LOST": "LOST", "FAULT": "FAULT"}.get(state, state.lower())


def result_document(outcome: Any, system: str | None = None) -> dict[str, Any]:
    """The JSON contract: {"cycles", "nodes": [{"name", "state", "samples", "missing", "lost", "emcy"}]}, plus the
    read times against the analysed bound, the events and what ended the run."""
    run = outcome.run
    cycles = run.cycles if run is not None else 0
    by_node: dict[str, dict[str, Any]] = {}
    for name, node in outcome.nodes.items():
        samples = run.complete_samples(name) if run is not None and name in run.nodes else 0
        due = sum(1 for rec in run.records if any(run.producers[m] == name for m in rec.due)) if run else 0
        by_node[name] = {
            "name": name,
            "node_id": node.node_id,
            "state": node.state,
            "samples": samples,
            "missing": due - samples if node.started else 0,
            "lost": node.lost_at_s is not None,
            "lost_at_s": None if node.lost_at_s is None else round(node.lost_at_s, 6),
            "silent_ms": None if node.lost_silent_ms is None else round(node.lost_silent_ms, 3),
            "heartbeat_timeout_ms": node.heartbeat_timeout_ms,
            "emcy": node.emcy,
            "set_up": node.setup_ok,
            "set_up_error": node.setup_error,
            "cia402": node.cia402_over,  # how the master drove its power state machine: "SDO", "PDO" or null
            "enable_path": node.enable_path,
            "stopped_at_s": None if node.stopped_at_s is None else round(node.stopped_at_s, 6),
            "safe_state": node.safe_state,
            "reboots": node.reboots,
            "errors": node.errors,
        }
    read: dict[str, Any] = {"analysed_bound_us": None, "window_us": None, "max_us": None, "overruns": 0}
    periods: dict[str, Any] = {
        "period_us": None,
        "min_us": None,
        "max_us": None,
        "analysed_jitter_us": 0,
        "overruns": 0,
    }
    if run is not None:
        complete = [rec.read_s for rec in run.records if rec.due and not rec.missing]
        read = {
            "analysed_bound_us": None if outcome.sync_completion_ns is None else outcome.sync_completion_ns / 1e3,
            "window_us": round(1e6 * run.read_window_s, 3),
            "max_us": round(1e6 * max(complete), 3) if complete else None,
            "mean_us": round(1e6 * sum(complete) / len(complete), 3) if complete else None,
            # a cycle whose due TPDOs were not all in when the read window closed, from nodes still in service
            "overruns": sum(
                1
                for rec in run.records
                if any(not outcome.out_of_service(run.producers[m], rec.sync_sent) for m in rec.missing)
            ),
            "beyond_analysis": sum(
                1
                for rec in run.records
                if rec.due
                and not rec.missing
                and outcome.sync_completion_ns is not None
                and round(rec.read_s * 1e9) > outcome.sync_completion_ns
            ),
        }
        spans = [rec.period_s for rec in run.records]
        periods = {
            "period_us": round(1e6 * run.period_s, 3),
            "min_us": round(1e6 * min(spans), 3) if spans else None,
            "max_us": round(1e6 * max(spans), 3) if spans else None,
            "analysed_jitter_us": outcome.master_jitter_ns / 1e3,
            # a cycle longer than T + the master's analysed wake-up latency: its SYNC came later than analysed
            "overruns": sum(
                1
                for rec in run.records
                if round(rec.period_s * 1e9) > round(run.period_s * 1e9) + outcome.master_jitter_ns
            ),
        }
    started = [n for n in by_node.values() if outcome.nodes[n["name"]].started]
    ok = (
        outcome.started
        and run is not None
        and all(n["missing"] == 0 and not n["lost"] and not n["emcy"] and not n["errors"] for n in started)
        and not read["overruns"]
        and not any(e.kind in ("tpdo-silent", "boot-up", "missed-sync", "bus-off") for _, e in outcome.events)
    )
    return {
        "system": system,
        "bus": outcome.bus,
        "ok": bool(ok),
        "cycles": cycles,
        "ended_by": outcome.ended_by,
        "read": read,
        "cycle": periods,
        "nodes": list(by_node.values()),
        "events": [
            {"time_s": round(t, 6), "node": e.node, "kind": e.kind, "action": e.action, "text": e.text}
            for t, e in outcome.events
        ],
        "drills": [{"time_s": round(t, 6), "what": text} for t, text in outcome.drills],
        "sync_gaps": outcome.sync_gaps,
        "bus_offs": outcome.bus_offs,
    }


def result_text(outcome: Any, doc: dict[str, Any]) -> str:
    lines = []
    if outcome.setup is not None:
        lines.append(str(outcome.setup))
    if not outcome.started:
        lines.append("nothing was started: fix the set-up (or run the others with --allow-missing)")
        return "\n".join(lines)
    for t, what in outcome.drills:
        lines.append(f"  {t:8.3f} s  drill: {what}")
    for e in doc["events"]:
        lines.append(f"  {e['time_s']:8.3f} s  {e['text']} -> {e['action']}")
    for name, notes in doc.get("simulated_drives", {}).items():
        lines += [f"  simulated {name}: {note}" for note in notes]
    lines.append(f"{doc['cycles']} cycles on {doc['bus']}, ended by {doc['ended_by']}")
    r, c = doc["read"], doc["cycle"]
    if r["max_us"] is not None:
        bound = "not analysed" if r["analysed_bound_us"] is None else f"{r['analysed_bound_us'] / 1e3:.3f} ms"
        lines.append(
            f"read (SYNC -> last TPDO): mean {r['mean_us'] / 1e3:.3f} ms, max {r['max_us'] / 1e3:.3f} ms; analysed "
            f"bound {bound} (cycles beyond it: {r['beyond_analysis']}), read window {r['window_us'] / 1e3:.3f} ms; "
            f"window overruns {r['overruns']}"
        )
    if c["min_us"] is not None:
        lines.append(
            f"period {c['period_us'] / 1e3:.3f} ms: min {c['min_us'] / 1e3:.3f} ms, max {c['max_us'] / 1e3:.3f} ms; "
            f"longer than T + the analysed {c['analysed_jitter_us']:g} us jitter: {c['overruns']}"
        )
    lines.append(f"{'node':10} {'state':20} {'samples':>7} {'missing':>7}  supervision")
    for n in doc["nodes"]:
        notes = []
        if n["lost"]:
            notes.append(
                f"lost at {n['lost_at_s']:.3f} s after {n['silent_ms']:.1f} ms silent "
                f"(heartbeat timeout {n['heartbeat_timeout_ms']:.0f} ms)"
            )
        notes += [e["text"] for e in n["emcy"]]
        for r in n["reboots"]:
            back = r.get("recovered_at_s") is not None
            result = f"recovered in {r['recovery_ms']:.1f} ms" if back else r.get("result", "")
            notes.append(f"rebooted at {r['at_s']:.3f} s ({r['action']}): {result}")
        notes += n["errors"]
        if n["safe_state"]:
            notes.append(f"safe stop -> {n['safe_state']}")
        lines.append(f"{n['name']:10} {n['state']:20} {n['samples']:>7} {n['missing']:>7}  {'; '.join(notes)}")
    lines.append("ok" if doc["ok"] else "NOT ok: see above")
    return "\n".join(lines)
