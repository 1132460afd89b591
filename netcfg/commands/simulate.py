"""`netcfg simulate SPEC|RUNTIME_JSON`: run the runtime configuration in the discrete-event simulator (netcfg.sim).

It reads a runtime.json or compiles a spec in memory, refuses a run netcfg.sim.limits says is too long or
meaningless, runs it (and a Monte Carlo batch with --runs), prints the summary, and writes the trace and plots.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from netcfg.commands.base import Subcommands
from netcfg.commands.options import (
    MAX_EVENTS_LIMIT,
    MAX_JOBS,
    MAX_RUNS,
    MAX_SEED,
    guarded,
    int_option,
    not_json,
    number_option,
)
from netcfg.records import same_named

if TYPE_CHECKING:
    from netcfg import runtime
    from netcfg.sim.scenario import SimOptions
    from netcfg.sim.trace import TraceFrame

NAME = "simulate"
BATCH = False
MAX_DRIFT_PPM = 100_000.0  # 10 %: beyond any clock; the arithmetic stays meaningful below it


def add_parser(sub: Subcommands) -> None:
    p = sub.add_parser(NAME, help="run the runtime configuration in the discrete-event simulator")
    p.add_argument("source", type=Path, metavar="SPEC|RUNTIME_JSON")
    p.add_argument("--duration", default="10s", help="simulated time per run, e.g. 8s, 500ms (default 10s)")
    p.add_argument("--seed", type=int_option("--seed", 0, MAX_SEED), default=0,
                   help="random seed of the (first) run")
    p.add_argument("--runs", type=int_option("--runs", 1, MAX_RUNS), default=1,
                   help="Monte Carlo: this many runs, seeds seed..seed+runs-1")
    p.add_argument("--jobs", type=int_option("--jobs", 1, MAX_JOBS),
                   help="worker processes for --runs (default: every core)")
    p.add_argument("--max-events", type=int_option("--max-events", 1, MAX_EVENTS_LIMIT), default=None,
                   metavar="N", help="refuse a run estimated to need more simulated frames and task jobs than N "
                   "(default 20,000,000: minutes of work)")
    p.add_argument("--format", choices=("text", "json"), default="text")
    p.add_argument("--log", type=Path, metavar="FILE", help="CAN trace of the first run: .log (candump -L) or .asc")
    p.add_argument("--plots", type=Path, metavar="DIR", help="histogram PNGs of response times and flow latencies")
    p.add_argument("--mode", choices=("auto", "unsync"), default="auto",
                   help="unsync: run FTT-CAN and CANopen buses as free-running CAN (the alternative)")
    p.add_argument("--canopen", choices=("pdo", "sdo"), default="pdo",
                   help="CANopen master: the SYNC/PDO cycle, or the older SDO polling loops")
    p.add_argument("--stuffing", choices=("exact", "worst", "none"), default="worst",
                   help="frame lengths: bits actually stuffed, the worst case, or no stuff bits")
    p.add_argument("--drift", type=number_option("--drift"), default=50.0, metavar="PPM",
                   help="clock drift bound per node")
    p.add_argument("--force", action="store_true",
                   help="simulate a spec that check refuses (to see how it fails); the analysis does not hold")
    p.add_argument("--fault", action="append", default=[], metavar="FAULT",
                   help="inject a fault (repeatable): ber=1e-6, bit-error@12ms, crash:NODE@2s, "
                   "babble:NODE@1s..2s, lose:MESSAGE@100ms, master-fail@2s; or a drill of netcfg run, "
                   "KIND:ARG for run's --KIND ARG: kill:NODE@1s, emcy:NODE@1s[=CODE], reset:NODE@1s+50ms, "
                   "stall:1s..1.2s, bus-off:1s..1.2s")


def run(args: argparse.Namespace) -> int:
    return guarded(simulate_command, args, "simulate", "simulating", args.source)


def simulate_command(args: argparse.Namespace) -> int:
    from netcfg import runtime
    from netcfg.sim.faults import Fault, FaultError
    from netcfg.sim.limits import DEFAULT_MAX_EVENTS, fault_problem, work_problem
    from netcfg.sim.scenario import SimOptions
    from netcfg.spec.units import parse_duration_option

    try:
        duration = parse_duration_option(args.duration)
    except ValueError as exc:
        print(f"netcfg: --duration {exc}", file=sys.stderr)
        return 2
    try:
        faults = tuple(Fault.parse(f) for f in args.fault)
    except FaultError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    if args.runs < 1 or duration <= 0:
        print("netcfg: --runs and --duration must be positive", file=sys.stderr)
        return 2
    if not 0 <= args.drift <= MAX_DRIFT_PPM:  # also refuses nan
        print(
            f"netcfg: --drift {args.drift}: give a clock tolerance between 0 and {MAX_DRIFT_PPM:g} ppm "
            "(crystals are within about 100 ppm)",
            file=sys.stderr,
        )
        return 2
    if args.seed < 0:
        print("netcfg: --seed must be 0 or more", file=sys.stderr)
        return 2
    if args.log is not None:  # the trace's writers (python-can) are imported only for a trace
        from netcfg.sim.trace import SUPPORTED_SUFFIXES
    if args.log is not None and args.log.suffix not in SUPPORTED_SUFFIXES:
        print(f"netcfg: --log {args.log}: the trace formats are {', '.join(SUPPORTED_SUFFIXES)}", file=sys.stderr)
        return 2
    try:
        doc = load_document(args.source, getattr(args, "force", False))
    except json.JSONDecodeError as exc:
        return not_json(args.source, exc)
    except runtime.RuntimeConfigError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 1
    except UnicodeDecodeError:
        print(f"{args.source}: error: not a text file; give a spec (.yaml) or a runtime.json", file=sys.stderr)
        return 1
    if doc is None:
        return 1
    opts = SimOptions(
        **same_named(args, "seed stuffing mode canopen"),  # the options named as SimOptions names them
        duration_ns=duration,
        drift_ppm=args.drift,
        faults=faults,
        trace=args.log is not None,
    )
    cfg = runtime.parse(doc, str(args.source))
    if args.canopen == "sdo":  # SDO mode runs the live master's SDO set-up and reads
        from netcfg import protocols

        for b in cfg.buses:
            if (refused := protocols.of(b).run_refused(b)) is not None:
                print(f"netcfg: {args.source}: --canopen sdo: {refused}", file=sys.stderr)
                return 2
    max_events = getattr(args, "max_events", None) or DEFAULT_MAX_EVENTS
    problem = work_problem(cfg, duration, max_events) or fault_problem(cfg, faults)
    if problem:
        print(f"netcfg: {problem}", file=sys.stderr)
        return 2
    # The first run's objects (a live master's record of every cycle, ...) live until the report is out: the cyclic
    # collector's walks over them free nothing, and a live master's run would end with a full collection (0.3 s
    # after 600 s of ALLEX-2). Paused until the report is printed, unless a batch follows in this process.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        return _simulate(args, cfg, opts, doc)
    finally:
        if gc_was_enabled:
            _resume_gc()


def _resume_gc() -> None:
    """Collect again, with what was made meanwhile counted as old: freeze() then unfreeze() moves every tracked
    object to the oldest generation, lists merged, none walked; the next young collection would walk them all."""
    gc.freeze()
    gc.unfreeze()
    gc.enable()


def _simulate(args: argparse.Namespace, cfg: runtime.RuntimeConfig, opts: SimOptions, doc: dict[str, Any]) -> int:
    """simulate_command from the first run on."""
    from netcfg import jsontext
    from netcfg.sim.can_trace import trace_frames
    from netcfg.sim.faults import FaultError
    from netcfg.sim.montecarlo import progress_bar, run_batch, run_once
    from netcfg.sim.results import histograms, log_check, outside_error_assumption, summary, text
    from netcfg.sim.scenario import SimOptions

    try:
        sc, res = run_once(cfg, opts)
    except FaultError as exc:  # a --fault naming what the system does not have: a usage error
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 1
    if args.runs > 1:
        _resume_gc()  # every run of the batch leaves garbage behind
        rest = run_batch(
            doc,
            SimOptions(**{**opts.__dict__, "seed": args.seed + 1}),
            args.runs - 1,
            args.jobs,
            progress=lambda d, n: progress_bar(d + 1, n + 1),
        )
        res = res.merge(rest)  # wall_s: the first run's plus the batch's elapsed time
    doc_out = summary(res)
    if args.plots is not None:
        try:
            doc_out["plots"] = histograms(res, str(args.plots))
        except OSError as exc:
            print(f"netcfg: cannot write plots to {args.plots}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    if args.log is not None:
        frames = trace_frames(sc)
        doc_out["log_check"] = log_check(cfg, frames)
        try:
            _write_atomically(args.log, frames)
        except OSError as exc:
            print(f"netcfg: cannot write the trace {args.log}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    if args.format == "json":
        print(jsontext.dumps(doc_out, indent=2))
    else:
        print(text(doc_out))
    excused = outside_error_assumption(res)  # the analysis does not claim to bound this run
    if not excused:  # one line per measured range outside its analysed one
        for violation in doc_out["violations"]:
            print(f"netcfg: outside the analysis: {violation}", file=sys.stderr)
    bad = (
        doc_out["deadline_misses"]
        or doc_out["lost"]
        or doc_out.get("findings")
        # a node lost, an EMCY, a reboot, missed SYNC instants: what the live master's supervision reported (as run)
        or any(rep.get("supervision") for reps in doc_out.get("protocols", {}).values() for rep in reps)
        or (doc_out["exceeds_analysis"] and not excused)
        or (not doc_out.get("log_check", {"ok": True})["ok"] and not excused)
    )
    return 1 if bad else 0


def _write_atomically(path: Path, frames: list[TraceFrame]) -> None:
    """The trace appears whole or not at all (a temporary file beside it, renamed)."""
    import secrets

    from netcfg.outputs import TMP_TAG

    # a name no user file has (netcfg's temporary tag and a random part); the suffix picks the trace format
    tmp = path.with_name(f".{path.name}{TMP_TAG}{secrets.token_hex(4)}{path.suffix}")
    try:
        from netcfg.sim.trace import write_trace

        write_trace(frames, tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def load_document(source: Path, force: bool = False) -> dict[str, Any] | None:
    """The runtime configuration as a JSON document: read, or compiled from a spec. None: errors were printed.

    With `force`, a spec whose model resolves but which check refuses (a missed deadline, an overloaded bus, a
    window too short...) is simulated anyway, with a warning: that is how a user sees how it fails.
    """
    from netcfg import runtime

    if source.suffix == ".json":
        doc = runtime.read_document(source)  # the input guard: size, depth, number length
        runtime.parse(doc, str(source))  # the runtime schema, with ranges
        return dict(doc)
    from netcfg.check import analyse_spec
    from netcfg.emit.runtime_json import runtime_document

    model, report = analyse_spec(source)
    for d in report["errors"]:
        print(f"{d['file']}:{d['line']}:{d['column']}: error: {d['message']} [{d['code']}]", file=sys.stderr)
    if model is None or (report["errors"] and not force):
        hint = "" if model is None else " (--force simulates it anyway)"
        print(f"netcfg: {source} has errors; nothing was simulated{hint}", file=sys.stderr)
        return None
    if report["errors"]:
        print(
            f"netcfg: warning: {source} has {len(report['errors'])} errors and check refuses it; simulating it "
            "anyway (--force): the analysed bounds below are not guarantees",
            file=sys.stderr,
        )
    return json.loads(json.dumps(runtime_document(model, report)))
