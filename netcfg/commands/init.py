"""`netcfg init`: write a commented starting spec that check accepts (the texts are netcfg.init_spec's), or the
spec imported from a DBC (`--from dbc FILE`, as `netcfg import dbc` writes it)."""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path

from netcfg.commands.base import Subcommands
from netcfg.commands.options import add_dbc_options, import_options
from netcfg.importers import ImportOptions
from netcfg.init_spec import SOURCES, starting_spec

NAME = "init"
BATCH = False


def add_parser(sub: Subcommands) -> None:
    p = sub.add_parser(NAME, help="write a commented starting spec that check accepts")
    p.add_argument("--from", dest="source", choices=SOURCES, help="start from an example system or a DBC")
    p.add_argument("file", nargs="?", type=Path, metavar="FILE", help="with --from dbc: the DBC file")
    p.add_argument("--dbc", type=Path, metavar="FILE", help="the same as --from dbc FILE")
    p.add_argument("-o", "--output", type=Path, metavar="SPEC", help="the spec to write (default: stdout)")
    add_dbc_options(p)


def run(args: argparse.Namespace) -> int:
    return init_command(args.source, args.file or args.dbc, args.output, import_options(args))


def init_command(source: str | None, dbc: Path | None, output: Path | None, options: ImportOptions) -> int:
    if output is not None and output.exists():  # never overwrite what a user wrote
        print(f"netcfg: {output} exists; choose another name or remove it first", file=sys.stderr)
        return 2
    if source == "dbc" or dbc is not None:
        if dbc is None:
            print("netcfg: --from dbc needs the DBC file: netcfg init --from dbc vehicle.dbc -o vehicle.yaml",
                  file=sys.stderr)
            return 2
        if output is None:
            print("netcfg: a spec from a DBC needs -o SPEC", file=sys.stderr)
            return 2
        from netcfg.commands.import_ import import_spec

        return import_spec("dbc", dbc, output, replace(options, output=output))
    text = starting_spec(source, output)
    if output is None:
        sys.stdout.write(text)
        return 0
    try:
        output.parent.mkdir(parents=True, exist_ok=True)
        tmp = output.with_name(f".{output.name}.tmp")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, output)
    except OSError as exc:
        print(f"netcfg: cannot write {output}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(f"wrote {output}; check it with: netcfg check {output}")
    return 0
