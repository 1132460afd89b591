"""`netcfg import dbc|bus-yml FILE -o SPEC`: write a netcfg spec from a DBC file or a ros2_canopen/Lely bus.yml.

The module is import_ (import is Python's keyword); the importers are netcfg.importers'.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from netcfg.commands.base import Subcommands
from netcfg.commands.options import add_dbc_options, import_options, internal_error, io_problem
from netcfg.importers import ImportOptions

NAME = "import"
BATCH = True


def add_parser(sub: Subcommands) -> None:
    p = sub.add_parser(NAME, help="write a netcfg spec from a DBC file or a ros2_canopen/Lely bus.yml")
    p.add_argument("kind", choices=("dbc", "bus-yml"))
    p.add_argument("source", type=Path, metavar="FILE")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="SPEC", help="the spec to write")
    add_dbc_options(p)
    p.add_argument("--lenient", action="store_true", help="what cannot be mapped is a warning, not an error")


def run(args: argparse.Namespace) -> int:
    return import_spec(args.kind, args.source, args.output, import_options(args, args.output))


def import_spec(kind: str, source: Path, output: Path, options: ImportOptions) -> int:
    """Import `source`, write the spec to `output` (whole or not at all), print what happened; the exit code."""
    from netcfg.diagnostics import Collector, sort_diagnostics
    from netcfg.importers import write_spec
    from netcfg.outputs import check_import_output, write_file

    diags = Collector()
    try:
        check_import_output(output, [source])  # before the import, which may take a while
    except OSError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    try:
        if kind == "dbc":
            from netcfg.importers.dbc import import_dbc

            imported = import_dbc(source, options, diags)
        else:
            from netcfg.importers.bus_yml import import_bus_yml

            imported = import_bus_yml(source, options, diags)
    except OSError as exc:
        print(f"netcfg: {io_problem(exc, 'read', source)}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug in netcfg, not in the file: nothing is written
        return internal_error("importing", source, exc, nothing_written=True)
    for d in sort_diagnostics(diags.items):
        print(d, file=sys.stderr)
    if imported is None or diags.errors:
        print(f"netcfg: {source} could not be imported; nothing was written", file=sys.stderr)
        return 1
    data, comments = imported
    header = f"netcfg spec imported from {source.name} ({kind}) by `netcfg import`; edit freely."
    text = write_spec(data, comments, header)
    try:
        write_file(output, text.encode("utf-8"), [source])  # whole or not at all, never over the source
    except OSError as exc:
        print(f"netcfg: cannot write {output}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(f"wrote {output}; check it with: netcfg check {output}")
    return 0
