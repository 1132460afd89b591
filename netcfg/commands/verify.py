"""`netcfg verify SPEC|RUNTIME_JSON LOG`: read the configuration, check the log (netcfg.verify), print, draw the
report (netcfg.verify.text, netcfg.verify.plots).

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
from netcfg.commands.base import Subcommands
from netcfg.commands.options import guarded

NAME = "verify"
BATCH = False


def add_parser(sub: Subcommands) -> None:
    p = sub.add_parser(NAME, help="hold a recorded CAN log against the spec and its analysis")
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


def run(args: argparse.Namespace) -> int:
    # a BrokenPipeError is main's: `netcfg verify ... | head` is not an error
    return guarded(verify_command, args, "verify", "verifying", args.log, passes=(BrokenPipeError,))


def verify_command(args: argparse.Namespace) -> int:
    from netcfg import runtime
    from netcfg.spec.units import parse_duration_option
    from netcfg.verify.api import verify_log
    from netcfg.verify.checker import VerifyError
    from netcfg.verify.logs import LogError
    from netcfg.verify.text import public_document, text, violation_lines

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
        print(jsontext.dumps(public_document(report), indent=2))
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
    from netcfg.commands.simulate import load_document

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
