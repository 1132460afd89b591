"""`netcfg diff A B`: what changed between two specs or two build folders, in timing terms (netcfg.spec_diff).

Exit codes follow diff(1): 0 the same, 1 different, 2 unreadable.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from netcfg import jsontext
from netcfg.commands.base import Subcommands

NAME = "diff"
BATCH = False


def add_parser(sub: Subcommands) -> None:
    p = sub.add_parser(NAME, help="what changed between two specs or two build folders, in timing terms")
    p.add_argument("old", type=Path, metavar="A", help="a spec or a build folder")
    p.add_argument("new", type=Path, metavar="B", help="a spec or a build folder")
    p.add_argument("--format", choices=("text", "json"), default="text")


def run(args: argparse.Namespace) -> int:
    from netcfg.spec_diff import DiffInputError, compare, load_side, render_text

    try:
        a, b = load_side(args.old), load_side(args.new)
    except DiffInputError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    except (OSError, json.JSONDecodeError) as exc:
        print(f"netcfg: cannot read {getattr(exc, 'filename', None) or 'the input'}: {exc}", file=sys.stderr)
        return 2
    d = compare(a, b)
    if args.format == "json":
        print(jsontext.dumps({"a": a.name, "b": b.name, **d.as_json()}, indent=2))
    else:
        print(render_text(a, b, d))
    return 0 if d.empty() else 1
