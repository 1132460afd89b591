"""`netcfg verify SPEC|RUNTIME_JSON LOG`: read the configuration, check the log, print, draw the report.

Exit codes (DESIGN.md): 0 the log stays inside the analysis, 1 a violation (one line each on stderr) or a spec with
errors, 2 an unreadable log or a usage problem.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from netcfg import jsontext

__all__ = ["add_parser", "verify_command"]


def add_parser(sub: Any) -> None:
    p = sub.add_parser("verify", help="hold a recorded CAN log against the spec and its analysis")
    p.add_argument("source", type=Path, metavar="SPEC|RUNTIME_JSON")
    p.add_argument("log", type=Path, metavar="LOG", help="candump .log, .asc, .blf, .trc, .csv, .db (SQLite), .mf4")
    p.add_argument("--bus", action="append", default=[], metavar="[CHANNEL=]BUS",
                   help="the bus the log was recorded on, when its channel names are not bus names; "
                   "CHANNEL=BUS for each channel of a multi-bus log (repeatable)")
    p.add_argument("--log-format", help="the log's format when its suffix does not say (candump, asc, blf, ...)")
    p.add_argument("--format", choices=("text", "json"), default="text")
    p.add_argument("--report", type=Path, metavar="DIR", help="write period, latency and bus-load plots (PNG) here")
    p.add_argument("--window", default="100ms", help="bus-load window, e.g. 100ms, 1s (default 100ms)")
    p.add_argument("--strict", action="store_true", help="periods outside the analysed jitter are violations")
    p.add_argument("--reference-reader", action="store_true",
                   help="read candump logs with python-can's reader instead of the vectorised one (slower)")


def verify_command(args: argparse.Namespace) -> int:
    from netcfg import runtime
    from netcfg.spec.units import parse_duration_option
    from netcfg.verify.api import verify_log
    from netcfg.verify.checker import VerifyError
    from netcfg.verify.logs import LogError

    try:
        window_ns = parse_duration_option(args.window)  # the one unit grammar of specs and command lines
    except ValueError as exc:
        print(f"netcfg: --window {exc}", file=sys.stderr)
        return 2
    if window_ns < 1000:
        print(f"netcfg: --window {args.window}: give at least 1 us, e.g. 100ms", file=sys.stderr)
        return 2
    try:
        doc = _configuration(args.source)
    except json.JSONDecodeError as exc:
        print(f"{args.source}:{exc.lineno}:{exc.colno}: error: not valid JSON ({exc.msg}); rebuild it with "
              "'netcfg build'", file=sys.stderr)
        return 1
    except runtime.RuntimeConfigError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 1
    if doc is None:
        return 1
    cfg = runtime.parse(doc, str(args.source))
    plain = [b for b in args.bus if "=" not in b]
    if len(plain) > 1:
        print("netcfg: --bus: give one BUS for every channel, or CHANNEL=BUS per channel", file=sys.stderr)
        return 2
    buses: dict[str, str] = {"": plain[0]} if plain else {}
    buses.update(b.split("=", 1) for b in args.bus if "=" in b)  # type: ignore[misc]
    started = time.perf_counter()
    try:
        report = verify_log(
            cfg, args.log, bus=buses, log_format=args.log_format, window_us=window_ns // 1000,
            strict=args.strict, fast=not args.reference_reader, progress=_progress,
        )
    except LogError as exc:
        _progress_done()
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    except (VerifyError, runtime.UnknownNameError) as exc:
        _progress_done()
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    _progress_done()
    wall = time.perf_counter() - started
    if args.report is not None:
        from netcfg.verify.plots import draw

        try:
            report["plots"] = draw(report, args.report)
        except OSError as exc:
            print(f"netcfg: cannot write the report to {args.report}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    if args.format == "json":
        print(jsontext.dumps(_public(report), indent=2))
    else:
        print(text(report))
        if sys.stderr.isatty() and wall > 0:
            print(f"  ({report['frames'] / wall:,.0f} frames/s)", file=sys.stderr)
    for line in violation_lines(report, str(args.log)):
        print(line, file=sys.stderr)
    return 0 if report["ok"] else 1


def _configuration(source: Path) -> dict[str, Any] | None:
    """The runtime configuration as a JSON document: read, or compiled from a spec (as `simulate` does). None:
    errors were printed."""
    from netcfg.sim.cli import load_document

    if source.suffix == ".json":
        return load_document(source)
    from netcfg.check import analyse_spec
    from netcfg.emit.runtime_json import runtime_document

    model, report = analyse_spec(source)
    for d in report["errors"]:
        print(f"{d['file']}:{d['line']}:{d['column']}: error: {d['message']} [{d['code']}]", file=sys.stderr)
    if model is None or report["errors"]:
        print(f"netcfg: {source} has errors; no log was checked", file=sys.stderr)
        return None
    return dict(json.loads(json.dumps(runtime_document(model, report))))


def _public(report: dict[str, Any]) -> dict[str, Any]:
    """The JSON document: histograms and the load of every window are left to --report (a long log has millions)."""
    out = dict(report)
    out["messages"] = [{k: v for k, v in m.items() if k != "histograms"} for m in report["messages"]]
    out["buses"] = [{k: v for k, v in b.items() if k != "load_per_window"} for b in report["buses"]]
    return out


def violation_lines(report: dict[str, Any], log: str) -> list[str]:
    """One line per violation: the log, the time in it, the kind, the message and by how much."""
    lines = [
        f"{log}: {v['time_us'] / 1e6:.6f} s: {v['kind']}: {v['message'] + ': ' if v['message'] else ''}{v['detail']}"
        for v in report["violations"]
    ]
    hidden = report["violation_count"] - len(report["violations"])
    if hidden > 0:
        kinds = ", ".join(f"{k} {n}" for k, n in report["violations_by_kind"].items())
        lines.append(f"{log}: and {hidden} more violations (all of them by kind: {kinds})")
    return lines


def text(report: dict[str, Any]) -> str:
    start = report["start_us"] or 0
    lines = [
        f"system {report['system']}: {report['frames']} frames over {report['duration_us'] / 1e6:.3f} s "
        f"(times below count from its first frame, at {start / 1e6:.6f} s in the log), {report['error_frames']} "
        "error frames, "
        f"{report['violation_count']} violations, {report['warning_count']} warnings",
        *_phase_lines(report.get("phases")),
        "",
        f"  {'message':<24}{'id':>9}{'count':>10}{'period min/mean/max ms':>27}{'jitter us':>11}{'bound us':>10}"
        f"{'resp max us':>13}{'wcrt us':>9}{'missing':>9}  ok",
    ]
    for m in report["messages"]:
        p = m["period_us"]
        period = "-" if p is None else f"{p['min'] / 1000:.3f}/{p['mean'] / 1000:.3f}/{p['max'] / 1000:.3f}"
        r = m["response_us"]
        ok = {True: "yes", False: "NO", None: "-"}[m["within_analysis"]]
        if m["warnings"]:
            ok += f" ({m['warnings']} warnings)"
        lines.append(
            f"  {m['name']:<24}{m['id']:>9X}{m['count']:>10}{period:>27}{_f(m['jitter_us']):>11}"
            f"{_f(m['analysed_jitter_us']):>10}{_f(None if r is None else r['max']):>13}{_f(m['wcrt_us']):>9}"
            f"{m['missing']:>9}  {ok}"
        )
    for b in report["buses"]:
        load = b["load"]
        lines += [
            "",
            f"  bus {b['name']} ({b['protocol']}, {b['bitrate']} bit/s): load per {report['window_us'] / 1000:g} ms "
            + ("-" if load is None else f"{load['min']:.1%} min, {load['mean']:.1%} mean, {load['max']:.1%} max")
            + f"; analysed utilisation {b['utilization_analysed']:.1%}, at most {b['window_bound']:.1%} per window",
        ]
        co = b.get("canopen")
        if co:
            s = co["sync"]
            if s and s["period_us"]:
                p = s["period_us"]
                lines.append(
                    f"    SYNC: {s['count']} frames, period {p['min'] / 1000:.3f}/{p['mean'] / 1000:.3f}/"
                    f"{p['max'] / 1000:.3f} ms, jitter {s['jitter_us']} us"
                )
            if co["sync_window_us"] is not None and co["synchronous_pdos"]:
                worst = max((x["response_max_us"] or 0 for x in co["synchronous_pdos"]), default=0)
                inside = all(x["inside_window"] is not False for x in co["synchronous_pdos"])
                lines.append(
                    f"    synchronous PDOs: the last {worst} us after SYNC, window {co['sync_window_us']:g} us"
                    f" ({'inside' if inside else 'OUTSIDE'})"
                )
            for name, hb in co["heartbeats"].items():
                lines.append(f"    heartbeat {name}: {hb['count']} frames, state {hb['state']}")
            for st in co["nmt_states"]:
                lines.append(f"    {st['time_us'] / 1e6:.6f} s: {st['node']} -> {st['state']}")
            for c in co["nmt_commands"]:
                lines.append(f"    {c['time_us'] / 1e6:.6f} s: NMT {c['command']} to {c['node']}")
            for e in co["emcy"]:
                lines.append(f"    {e['time_us'] / 1e6:.6f} s: EMCY from {e['node']}: code {e['code']}")
            if co["sdo_frames"]:
                lines.append(f"    {co['sdo_frames']} SDO frames")
    if report["unknown_ids"]:
        lines += ["", "  unknown identifiers: " + ", ".join(
            f"0x{u['id']:X} ({u['count']})" for u in report["unknown_ids"])]
    if report["never_seen"]:
        lines += ["", "  never seen: " + ", ".join(report["never_seen"])]
    for w in report["warnings"][:20]:
        lines.append(f"  warning: {w['time_us'] / 1e6:.6f} s: {w['kind']}: {w['message']}: {w['detail']}")
    if report["warning_count"] > 20:
        lines.append(f"  ... {report['warning_count'] - 20} more warnings (--format json lists up to 1000)")
    lines += ["", "  inside the analysis" if report["ok"] else "  OUTSIDE THE ANALYSIS: see the violations below"]
    return "\n".join(lines)


def _phase_lines(phases: dict[str, Any] | None) -> list[str]:
    """A master's log: what came before and after the cyclic phase, which alone is judged (verify.phases)."""
    if phases is None:
        return []
    c = phases["cyclic"]
    out = [f"  cyclic phase, judged below: {c['from_us'] / 1e6:.6f} .. {c['to_us'] / 1e6:.6f} s of the log"]
    for name in ("setup", "shutdown"):
        ph = phases[name]
        if not ph["frames"]:
            continue
        starts = sum(1 for n in ph["nmt_commands"] if n["command"] == "start")
        out.append(
            f"  {'set-up' if name == 'setup' else 'shut-down'}: {ph['frames']} frames ({ph['sdo_frames']} SDO, "
            f"{len(ph['nmt_commands'])} NMT commands, {starts} of them start, {len(ph['boot_ups'])} boot-ups), "
            f"{ph['from_us'] / 1e6:.6f} .. {ph['to_us'] / 1e6:.6f} s, not judged against the analysis"
        )
    return out


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.0f}"


_shown = [False]


def _progress(fraction: float) -> None:
    """A one-line bar on stderr, only on a terminal."""
    if not sys.stderr.isatty():
        return
    width = 30
    fill = int(width * max(0.0, min(1.0, fraction)))
    sys.stderr.write(f"\r  [{'#' * fill}{'.' * (width - fill)}] {fraction:4.0%} of the log")
    sys.stderr.flush()
    _shown[0] = True


def _progress_done() -> None:
    if _shown[0]:
        sys.stderr.write("\n")
        _shown[0] = False
