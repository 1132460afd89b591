"""`netcfg build SPEC`: check a spec, then write every artifact (netcfg.build), and say what was written."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from netcfg.commands.base import Subcommands
from netcfg.commands.options import internal_error

NAME = "build"
BATCH = True


def add_parser(sub: Subcommands) -> None:
    p = sub.add_parser(NAME, help="check a spec, then write every artifact (default: generated/<system>/)")
    p.add_argument("spec", type=Path, metavar="SPEC")
    p.add_argument("-o", "--output", type=Path, metavar="DIR", help="output folder")


def run(args: argparse.Namespace) -> int:
    from netcfg.emit import Background

    worker = Background.start()  # first: it imports what the report needs while the rest loads and the spec is read
    from netcfg.build import build
    from netcfg.inputs import InputError
    from netcfg.outputs import OutputError

    spec, output = args.spec, args.output
    try:
        report, target, files = build(spec, output, worker)
    except (OutputError, InputError) as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"netcfg: cannot build {spec}: {exc.strerror or exc} ({exc.filename or ''})", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug in netcfg: nothing was swapped in
        return internal_error("building", spec, exc, nothing_written=True)
    for d in report["errors"] + report["warnings"]:
        kind = "error" if d in report["errors"] else "warning"
        print(f"{d['file']}:{d['line']}:{d['column']}: {kind}: {d['message']} [{d['code']}]", file=sys.stderr)
    if target is None:
        print(f"netcfg: {spec} has errors; nothing was written", file=sys.stderr)
        return 1
    kept = report.get("kept") or []
    if kept:
        names = ", ".join(kept[:5]) + (f" (+{len(kept) - 5} more)" if len(kept) > 5 else "")
        print(f"netcfg: warning: {target} holds {len(kept)} file(s) netcfg did not write; kept: {names}",
              file=sys.stderr)
    for note in report.get("notes") or []:
        print(f"netcfg: note: {target / note}", file=sys.stderr)
    print(f"wrote {len(files)} files to {target}")
    return 0
