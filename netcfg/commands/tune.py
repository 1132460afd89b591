"""`netcfg tune SPEC -o OUT.yaml` (or `F.dbc -o OUT.dbc`): write the spec with the identifiers and offsets
netcfg.tuning finds, once check accepts it. Exit 0 written, 1 no assignment or the spec has errors, 2 I/O or usage.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from netcfg import jsontext
from netcfg.commands.base import Subcommands
from netcfg.commands.options import add_dbc_options, import_options, io_problem
from netcfg.importers import ImportOptions

NAME = "tune"
BATCH = False


def add_parser(sub: Subcommands) -> None:
    p = sub.add_parser(NAME, help="identifiers and offsets that make a CAN spec schedulable with the most slack")
    p.add_argument("spec", type=Path, metavar="SPEC")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="OUT.yaml", help="the tuned spec to write")
    p.add_argument("--robust", action="store_true", help="Davis & Burns' robust assignment: most error frames")
    p.add_argument("--force", action="store_true", help="replace OUT.yaml if it exists")
    p.add_argument("--format", choices=("text", "json"), default="text")
    add_dbc_options(p)


def run(args: argparse.Namespace) -> int:
    try:
        return tune(args.spec, args.output, args.robust, args.force, args.format, import_options(args))
    except OSError as exc:  # the spec or DBC cannot be read (tune itself reports what it cannot write)
        print(f"netcfg: {io_problem(exc, 'read', args.spec)}", file=sys.stderr)
        return 2


def tune(
    source: Path, output: Path, robust: bool, force: bool, fmt: str, options: ImportOptions | None = None
) -> int:
    """`options`: a DBC's bit rates and --default-period, as `check F.dbc` takes them."""
    from netcfg.analyze import analyze
    from netcfg.check import analyse_spec
    from netcfg.diagnostics import Collector, sort_diagnostics
    from netcfg.tuning import NoAssignment, load_source, plan, result_document, result_text, tuned_source

    if (source.suffix.lower() == ".dbc") != (output.suffix.lower() == ".dbc"):
        print("netcfg: tune writes what it reads: SPEC.yaml -o OUT.yaml, or F.dbc -o OUT.dbc", file=sys.stderr)
        return 2
    if output.exists() and not force:
        print(f"netcfg: {output} exists; tune never replaces a file (choose another -o, or --force)", file=sys.stderr)
        return 2
    diags = Collector()
    is_dbc = source.suffix.lower() == ".dbc"
    dbc_options = options or ImportOptions()
    spec, m = load_source(source, diags, dbc_options)
    if m is None or spec is None or diags.errors:
        for d in sort_diagnostics(diags.items):
            print(d, file=sys.stderr)
        print(f"netcfg: {source} has errors; fix them before tuning; nothing was written", file=sys.stderr)
        return 1
    report = analyze(m, diags)
    before = {**report, "ok": not diags.errors}
    try:
        plans = plan(m, spec, robust, report)
    except NoAssignment as exc:
        print(f"netcfg: {source}: {exc}; nothing was written", file=sys.stderr)
        return 1
    data = tuned_source(source, m, plans)
    tmp = output.with_name(f".tmp.{output.name}")  # keeps the suffix: the check below reads it by its kind
    try:
        output.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_bytes(data)
        _, after = analyse_spec(tmp, dbc_options if is_dbc else None)
        if after["errors"]:
            tmp.unlink()
            print(
                f"netcfg: the tuned spec would still be refused, so nothing was written; its errors, at the lines "
                f"{output} would have (the search assumes priority transmit queues and no bit errors):",
                file=sys.stderr,
            )
            for d in after["errors"]:
                print(f"{output}:{d['line']}:{d['column']}: error: {d['message']} [{d['code']}]", file=sys.stderr)
            return 1
        os.replace(tmp, output)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        print(f"netcfg: cannot write {output}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    doc = result_document(m, plans, before, after, output)
    print(jsontext.dumps(doc, indent=2) if fmt == "json" else result_text(doc))
    return 0
