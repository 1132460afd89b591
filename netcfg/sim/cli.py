"""`netcfg simulate`: read a spec (compiled in memory) or a runtime.json, run, print, write the trace and plots."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

from netcfg import runtime
from netcfg.sim.faults import Fault, FaultError, parse_time
from netcfg.sim.montecarlo import progress_bar, run_batch, run_once
from netcfg.sim.results import histograms, summary, text
from netcfg.sim.scenario import SimOptions
from netcfg.sim.trace import SUPPORTED_SUFFIXES, TraceFrame, write_trace

MAX_DRIFT_PPM = 100_000.0  # 10 %: beyond any clock; the arithmetic stays meaningful below it


def load_document(source: Path) -> dict[str, Any] | None:
    """The runtime configuration as a JSON document: read, or compiled from a spec. None: errors were printed."""
    if source.suffix == ".json":
        doc = json.loads(source.read_text(encoding="utf-8"))
        runtime.parse(doc, str(source))  # refuses unknown formats and versions
        return dict(doc)
    from netcfg.check import analyse_spec
    from netcfg.emit.runtime_json import runtime_document

    model, report = analyse_spec(source)
    for d in report["errors"]:
        print(f"{d['file']}:{d['line']}:{d['column']}: error: {d['message']} [{d['code']}]", file=sys.stderr)
    if model is None or report["errors"]:
        print(f"netcfg: {source} has errors; nothing was simulated", file=sys.stderr)
        return None
    return json.loads(json.dumps(runtime_document(model, report)))


def simulate_command(args: argparse.Namespace) -> int:
    try:
        duration = parse_time(args.duration)
        faults = tuple(Fault.parse(f) for f in args.fault)
    except FaultError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    if args.runs < 1 or duration <= 0:
        print("netcfg: --runs and --duration must be positive", file=sys.stderr)
        return 2
    if not 0 <= args.drift <= MAX_DRIFT_PPM:  # also refuses nan
        print(f"netcfg: --drift {args.drift}: give a clock tolerance between 0 and {MAX_DRIFT_PPM:g} ppm "
              "(crystals are within about 100 ppm)", file=sys.stderr)
        return 2
    if args.seed < 0:
        print("netcfg: --seed must be 0 or more", file=sys.stderr)
        return 2
    if args.log is not None and args.log.suffix not in SUPPORTED_SUFFIXES:
        print(f"netcfg: --log {args.log}: the trace formats are {', '.join(SUPPORTED_SUFFIXES)}", file=sys.stderr)
        return 2
    try:
        doc = load_document(args.source)
    except json.JSONDecodeError as exc:
        print(f"{args.source}:{exc.lineno}:{exc.colno}: error: not valid JSON ({exc.msg}); rebuild it with "
              "'netcfg build'", file=sys.stderr)
        return 1
    except runtime.RuntimeConfigError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 1
    except UnicodeDecodeError:
        print(f"{args.source}: error: not a text file; give a spec (.yaml) or a runtime.json", file=sys.stderr)
        return 1
    if doc is None:
        return 1
    opts = SimOptions(
        duration_ns=duration, seed=args.seed, stuffing=args.stuffing, drift_ppm=args.drift, mode=args.mode,
        canopen=args.canopen, faults=faults, trace=args.log is not None,
    )
    cfg = runtime.parse(doc, str(args.source))
    try:
        sc, res = run_once(cfg, opts)
    except (FaultError, ValueError) as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 1
    if args.runs > 1:
        rest = run_batch(doc, SimOptions(**{**opts.__dict__, "seed": args.seed + 1}), args.runs - 1, args.jobs,
                         progress=lambda d, n: progress_bar(d + 1, n + 1))
        res = res.merge(rest)  # wall_s: the first run's plus the batch's elapsed time
    doc_out = summary(res)
    if args.plots is not None:
        try:
            doc_out["plots"] = histograms(res, str(args.plots))
        except OSError as exc:
            print(f"netcfg: cannot write plots to {args.plots}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    if args.log is not None:
        try:
            _write_atomically(args.log, trace_frames(sc))
        except OSError as exc:
            print(f"netcfg: cannot write the trace {args.log}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    if args.format == "json":
        print(json.dumps(doc_out, indent=2))
    else:
        print(text(doc_out))
    if not res.error_model:  # one line per measured range outside its analysed one
        for violation in doc_out["violations"]:
            print(f"netcfg: outside the analysis: {violation}", file=sys.stderr)
    bad = (
        doc_out["deadline_misses"]
        or doc_out["lost"]
        or doc_out.get("findings")
        or (doc_out["exceeds_analysis"] and not res.error_model)
    )
    return 1 if bad else 0


def _write_atomically(path: Path, frames: list[TraceFrame]) -> None:
    """The trace appears whole or not at all (a temporary file beside it, renamed)."""
    tmp = path.with_name(f".{path.name}.tmp{path.suffix}")
    try:
        write_trace(frames, tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def trace_frames(sc: Any) -> list[TraceFrame]:
    """Every frame of every CAN bus, in time order, with error frames where a bit error hit."""
    out: list[TraceFrame] = []
    for name, bus in sc.can.items():
        rec = bus.record
        for m, end, data in zip(rec.msg, rec.end, rec.data):
            src = bus.sources[m]
            payload = data if data is not None else bytes(src.size)
            out.append(TraceFrame(end, name, src.can_id, src.extended, payload))
        for t in bus.error_log:
            out.append(TraceFrame(t + bus.error_ns, name, 0, False, b"", True))
    out.sort(key=lambda f: (f.t_ns, f.channel))
    return out
