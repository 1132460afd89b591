"""`netcfg check SPEC...`: validate specs and analyse their timing, print the reports; writes nothing.

The specs are given as files or folders; `--werror CODE` turns warnings into errors (both netcfg.check's, which
the language server and --watch share). Its two modes have modules of their own: `--explain MESSAGE`
(netcfg.commands.explain) and `--watch` (netcfg.commands.watch). The check itself is netcfg.check's.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
from pathlib import Path
from typing import Any

from netcfg import jsontext
from netcfg.check import promote_warnings, spec_files
from netcfg.commands.base import Subcommands
from netcfg.commands.options import MAX_RUNS, add_dbc_options, import_options, int_option, io_problem
from netcfg.importers import ImportOptions

NAME = "check"
BATCH = True
def add_parser(sub: Subcommands) -> None:
    p = sub.add_parser(NAME, help="validate specs and analyse their timing; writes nothing")
    p.add_argument("specs", nargs="+", type=Path, metavar="SPEC", help="a spec, a DBC, or a folder of specs")
    p.add_argument("--format", choices=("text", "json"), default="text")
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors and warnings")
    add_dbc_options(p)
    p.add_argument("--lenient", action="store_true",
                   help="DBC input: accepted; what cannot be mapped is a warning anyway (see --default-period)")
    p.add_argument("--werror", action="append", default=[], metavar="CODE",
                   help="treat warnings with this code as errors (repeatable), e.g. dbc-no-receiver")
    p.add_argument("--explain", metavar="MESSAGE", help="derive one CAN message's bound and what would fix it")
    p.add_argument("--watch", action="store_true",
                   help="check again on every save of the spec or a file it names (Ctrl-C ends it)")
    p.add_argument("--watch-checks", type=int_option("--watch-checks", 1, MAX_RUNS), help=argparse.SUPPRESS)


def run(args: argparse.Namespace) -> int:
    if args.explain:
        from netcfg.commands.explain import explain_command

        return explain_command(args.specs, args.explain, args.format, import_options(args))
    if args.watch:
        from netcfg.commands.watch import watch

        return watch(args.specs, import_options(args), frozenset(args.werror), max_checks=args.watch_checks)
    return check_specs(args.specs, args.format, import_options(args), frozenset(args.werror), args.quiet)


def check_specs(
    paths: list[Path],
    fmt: str,
    options: ImportOptions | None = None,
    werror: frozenset[str] = frozenset(),
    quiet: bool = False,
) -> int:
    from netcfg.check import check
    from netcfg.report_text import render

    try:
        paths = spec_files(paths)
    except OSError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    reports: list[dict[str, Any]] = []
    for n, path in enumerate(paths):
        if n:
            gc.collect()  # the last spec's model (its cycles: the collector is off in a batch command, see main())
        try:
            reports.append(promote_warnings(check(path, options), werror))
        except OSError as exc:
            print(f"netcfg: {io_problem(exc, 'read', path)}", file=sys.stderr)
            return 2
        except Exception as exc:  # a bug in netcfg, not in the spec: say so, without a wall of traceback
            if os.environ.get("NETCFG_DEBUG"):
                raise
            print(
                f"netcfg: internal error while checking {path}: {type(exc).__name__}: {exc}\n"
                "This is a bug in netcfg, not in your spec; please report it with the spec "
                "(NETCFG_DEBUG=1 shows the traceback).",
                file=sys.stderr,
            )
            return 2
    if fmt == "json":
        doc = reports[0] if len(reports) == 1 else {"ok": all(r["ok"] for r in reports), "results": reports}
        print(jsontext.dumps(doc, indent=2))
    else:
        for report in reports:
            if quiet:  # the problems only: warnings, then errors below
                for d in report["warnings"]:
                    print(f"{d['file']}:{d['line']}:{d['column']}: warning: {d['message']} [{d['code']}]")
            else:
                print(render(report))
            for d in report["errors"]:
                print(f"{d['file']}:{d['line']}:{d['column']}: error: {d['message']} [{d['code']}]", file=sys.stderr)
    return 0 if all(r["ok"] for r in reports) else 1
