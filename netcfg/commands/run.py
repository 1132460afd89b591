"""`netcfg run`: the live master on any python-can interface, or on netcfg's simulated drives: a CANopen bus, or a
bus of actuators that speak their own protocols (netcfg.run_actuators, netcfg.runtime.actuator_master).

    netcfg run build/allex2/runtime.json --interface virtual --simulated-drives --cycles 100
    netcfg run specs/allex2.yaml --interface socketcan --channel can0 --duration 8s --log gait.log
    netcfg run examples/arm_damiao.yaml --simulated-drives --cycles 200 --set wrist.mit_command.kd=1

A spec is compiled in memory first; a runtime.json is read as a master reads it (netcfg.runtime.load). The work is
netcfg.runtime.operate's: set-up, CiA 402 to OPERATION ENABLED, the SYNC cycle with heartbeat and EMCY supervision,
the safe stop. This module parses the command line, builds the bus (and the simulated drives), shows a live view on
a terminal, and prints the result (netcfg.run_result) as text or as the JSON of the design notes.

Fault drills (README "Faults the live master survives"): --kill, --emcy, --reset and --sdo-abort act on the
simulated drives, --stall on the master's loop, --bus-off on the master's controller (netcfg's bus wrapper).

Exit codes: 0 every started node delivered every cycle, none was lost, rebooted or sent an EMCY, no SYNC was missed
and the bus never went off (an actuator bus: no actuator was lost or reported an error); 1 otherwise, or the spec
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
from netcfg.commands.base import Subcommands
from netcfg.commands.options import guarded, not_json
from netcfg.runtime.drills import DEFAULT_ABORT, DEFAULT_EMCY, KINDS, NODE_KINDS, Drill, parse_drill

NAME = "run"
BATCH = False
LOG_SUFFIXES = (".log", ".asc", ".blf", ".csv", ".trc")


def add_parser(sub: Subcommands) -> None:
    p = sub.add_parser(
        NAME, help="the live master: CANopen (set up, CiA 402 enable, SYNC cycle) or an actuator bus (enable, "
        "command cycle, replies); supervise, stop safely"
    )
    p.add_argument("source", type=Path, metavar="SPEC|RUNTIME_JSON")
    p.add_argument("--interface", default=None, help="python-can interface: socketcan, pcan, kvaser, virtual, ...")
    p.add_argument("--channel", default=None, help="python-can channel, e.g. can0 (virtual: any name); several "
                   "actuator buses: BUS=CHANNEL,BUS=CHANNEL,... (virtual: each bus a channel of its own by default)")
    p.add_argument(
        "--simulated-drives",
        action="store_true",
        help="bring up netcfg's simulated drives on the (virtual) bus: the quick start, no hardware",
    )
    p.add_argument("--bus", default=None, help="which CANopen or actuator bus of the configuration (default: its "
                   "only CANopen bus, else every actuator bus at once)")
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
        ("--fault", "NODE@T", "simulated actuators: from T, NODE reports an error in every frame (its profile's "
         "error fields)"),
        ("--set", "NODE.COMMAND.FIELD=VALUE", "actuator bus: a command field's value, in the profile's units "
         "(default 0, or its range's bound nearest 0)"),
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


def run(args: argparse.Namespace) -> int:
    try:  # on a bug in netcfg the safe stop has run already (operate's finally)
        return guarded(run_command, args, "run", "running", args.source)
    except KeyboardInterrupt:  # before the cycle's own handler was armed (set-up): what was started is stopped
        print(f"netcfg: {args.source}: interrupted; started nodes were brought to their safe state", file=sys.stderr)
        return 1


def run_command(args: argparse.Namespace) -> int:
    from netcfg import runtime

    try:
        # one grammar with `simulate --fault KIND:ARG` (netcfg.runtime.drills); --fault is an actuator's error
        drills = {kind: [parse_drill(kind, a) for a in getattr(args, kind.replace("-", "_"))] for kind in KINDS}
        faults = [parse_drill("fault", f) for f in args.fault]
        duration_s = _duration_s(args.duration, "--duration") if args.duration is not None else None
    except ValueError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    if args.cycles is not None and args.cycles < 1:
        print("netcfg: --cycles must be 1 or more", file=sys.stderr)
        return 2
    if (any(drills[k] for k in NODE_KINDS) or faults) and not args.simulated_drives:
        print(
            "netcfg: --kill, --emcy, --reset, --sdo-abort and --fault act on simulated drives; add --simulated-drives",
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
            actuators = _actuator_buses(args, cfg)
            if actuators is not None:
                return _run_actuators(args, cfg, actuators, drills, faults, duration_s)
            if faults or args.set:
                print("netcfg: --fault and --set act on an actuator bus; this run drives a CANopen bus",
                      file=sys.stderr)
                return 2
            return _run_master(args, cfg, drills, duration_s)
    except runtime.RuntimeConfigError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 1
    except json.JSONDecodeError as exc:
        return not_json(args.source, exc)


def _actuator_buses(args: argparse.Namespace, cfg: Any) -> list[str] | None:
    """The actuator buses this run drives: the one --bus names, or every one when the configuration has no CANopen
    bus to default to; None: a CANopen run."""
    from netcfg.runtime.actuator_plan import actuator_bus, actuator_buses
    from netcfg.runtime.canopen_master import canopen_bus

    try:
        canopen_bus(cfg, args.bus)
        return None
    except (ValueError, KeyError):
        pass
    if args.bus is None:
        return actuator_buses(cfg) or None  # none: the CANopen run says why
    try:
        return [actuator_bus(cfg, args.bus)]
    except ValueError:
        return None  # neither: the CANopen run says why


def _run_actuators(args: argparse.Namespace, cfg: Any, bus_names: list[str], drills: dict[str, list[Drill]],
                   faults: list[Drill], duration_s: float | None) -> int:
    from netcfg.run_actuators import run_actuator_buses

    canopen_only = any(drills[k] for k in KINDS if k != "kill")
    if canopen_only or args.samples or args.allow_missing:
        what = f"bus '{bus_names[0]}' is an actuator bus" if len(bus_names) == 1 else (
            f"buses {', '.join(bus_names)} are actuator buses")
        print("netcfg: --emcy, --reset, --sdo-abort, --stall, --bus-off, --samples and --allow-missing act on a "
              f"CANopen run; {what} (their drills: --kill, --fault)", file=sys.stderr)
        return 2
    interface = args.interface or "virtual"
    try:
        channels = _channels(interface, args.channel, bus_names)
    except ValueError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    return run_actuator_buses(
        cfg, bus_names, interface=interface, channels=channels, simulated=args.simulated_drives, cycles=args.cycles,
        duration_s=duration_s, settings=args.set,
        drills=[*drills["kill"], *faults],
        log=args.log, stop_on_signals=_stop_on_signals, fmt=args.format,
    )


def _channels(interface: str, given: str | None, bus_names: list[str]) -> dict[str, str | None]:
    """Each bus's python-can channel. One bus: --channel (virtual: a name of this process by default). Several:
    `--channel BUS=CHANNEL,BUS=CHANNEL,...` for each; on the virtual interface each bus gets a channel of its own
    by default, named after it (after --channel's name, when one is given)."""
    if len(bus_names) == 1:
        return {bus_names[0]: given or (f"netcfg-run-{os.getpid()}" if interface == "virtual" else None)}
    if given is not None and "=" in given:
        pairs = dict(part.split("=", 1) for part in given.split(",") if part)
        unknown, missing = sorted(set(pairs) - set(bus_names)), [b for b in bus_names if b not in pairs]
        if unknown or missing:
            raise ValueError(f"--channel {given!r}: give each actuator bus its channel, BUS=CHANNEL joined by ',' "
                             f"({', '.join(bus_names)})" + (f"; not a bus: {', '.join(unknown)}" if unknown else ""))
        return dict(pairs)
    if interface != "virtual":
        raise ValueError(f"this run drives {len(bus_names)} actuator buses ({', '.join(bus_names)}): give each its "
                         f"channel with --channel {','.join(f'{b}=CHANNEL' for b in bus_names)}, or one with --bus")
    base = given or f"netcfg-run-{os.getpid()}"
    return {b: f"{base}-{b}" for b in bus_names}


def _run_master(
    args: argparse.Namespace,
    cfg: Any,
    drills: dict[str, list[Drill]],
    duration_s: float | None,
) -> int:
    import can

    from netcfg.run_result import result_document, result_text
    from netcfg.runtime.canopen_master import canopen_bus, canopen_slaves
    from netcfg.runtime.operate import BusLog, Plan, operate

    try:
        co_bus = canopen_bus(cfg, args.bus)
    except (ValueError, KeyError) as exc:
        text = str(exc).replace("with bus_name", "with --bus NAME")
        print(f"netcfg: {args.source}: {text}; `netcfg run` drives a CANopen bus", file=sys.stderr)
        return 2
    assert co_bus.canopen is not None
    from netcfg import protocols

    if (not_driven := protocols.of(co_bus).run_refused(co_bus)) is not None:
        print(f"netcfg: {args.source}: {not_driven}", file=sys.stderr)
        return 1
    slaves = {n.name for n in canopen_slaves(cfg, co_bus)}
    for node in (d.node for k in NODE_KINDS for d in drills[k]):
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
        for d in drills["sdo-abort"]:
            refused.setdefault(str(d.node), {"abort_writes": {}})["abort_writes"][d.obj] = d.code
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
        actions: list[tuple[float, str, Callable[[], None]]] = []
        for d in drills["bus-off"]:
            actions.append((d.at_s, d.description(), partial(bus.bus_off, d.until_s - d.at_s)))
        if bench is not None:
            for d in drills["kill"]:
                actions.append((d.at_s, d.description(), bench[str(d.node)].kill))
            for d in drills["emcy"]:
                actions.append((d.at_s, d.description(), partial(bench[str(d.node)].emergency, d.code)))
            for d in drills["reset"]:
                actions.append((d.at_s, d.description(), partial(bench[str(d.node)].reboot, d.outage_s)))
        live = (
            _LiveView(sys.stdout, cycles, {m.name: m.producer for m in cfg.messages})
            if args.format == "text" and sys.stdout.isatty()
            else None
        )
        plan = Plan(
            cycles=cycles,
            bus_name=co_bus.name,
            allow_missing=args.allow_missing,
            drills=actions,
            stalls=[(d.at_s, d.until_s) for d in drills["stall"]],
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
