"""Command line: netcfg check | schema. Exit codes: 0 ok, 1 spec errors or not schedulable, 2 usage or I/O."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

from netcfg import __version__


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="netcfg", description="Control-network configuration compiler.")
    parser.add_argument("--version", action="version", version=f"netcfg {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p_check = sub.add_parser("check", help="validate specs and analyse their timing; writes nothing")
    p_check.add_argument("specs", nargs="+", type=Path, metavar="SPEC")
    p_check.add_argument("--format", choices=("text", "json"), default="text")
    p_build = sub.add_parser("build", help="check a spec, then write every artifact (default: generated/<system>/)")
    p_build.add_argument("spec", type=Path, metavar="SPEC")
    p_build.add_argument("-o", "--output", type=Path, metavar="DIR", help="output folder")
    sub.add_parser("schema", help="print the JSON Schema of the spec language (for editors)")
    args = parser.parse_args(argv)
    try:
        if args.command == "check":
            return cmd_check(args.specs, args.format)
        if args.command == "build":
            return cmd_build(args.spec, args.output)
        if args.command == "schema":
            return cmd_schema()
    except BrokenPipeError:  # e.g. `netcfg check x | head`
        return 0
    return 2  # pragma: no cover - argparse rejects unknown commands


def cmd_check(paths: list[Path], fmt: str) -> int:
    from netcfg.check import check
    from netcfg.report_text import render

    reports: list[dict[str, Any]] = []
    for path in paths:
        try:
            reports.append(check(path))
        except OSError as exc:
            print(f"netcfg: cannot read {path}: {exc.strerror or exc}", file=sys.stderr)
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
        print(json.dumps(doc, indent=2))
    else:
        for report in reports:
            print(render(report))
            for d in report["errors"]:
                print(f"{d['file']}:{d['line']}:{d['column']}: error: {d['message']} [{d['code']}]", file=sys.stderr)
    return 0 if all(r["ok"] for r in reports) else 1


def cmd_build(spec: Path, output: Path | None) -> int:
    from netcfg.build import build

    try:
        report, target, files = build(spec, output)
    except OSError as exc:
        print(f"netcfg: cannot build {spec}: {exc.strerror or exc} ({exc.filename or ''})", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug in netcfg: nothing was swapped in
        if os.environ.get("NETCFG_DEBUG"):
            raise
        print(
            f"netcfg: internal error while building {spec}: {type(exc).__name__}: {exc}\n"
            "Nothing was written. This is a bug in netcfg; please report it (NETCFG_DEBUG=1 shows the traceback).",
            file=sys.stderr,
        )
        return 2
    for d in report["errors"] + report["warnings"]:
        kind = "error" if d in report["errors"] else "warning"
        print(f"{d['file']}:{d['line']}:{d['column']}: {kind}: {d['message']} [{d['code']}]", file=sys.stderr)
    if target is None:
        print(f"netcfg: {spec} has errors; nothing was written", file=sys.stderr)
        return 1
    print(f"wrote {len(files)} files to {target}")
    return 0


def cmd_schema() -> int:
    from netcfg.spec.schema import Spec

    schema = Spec.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "netcfg spec"
    print(json.dumps(schema, indent=2, sort_keys=True))
    return 0
