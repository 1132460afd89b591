"""`netcfg lsp`: the language server (netcfg.lsp.server) on stdin/stdout."""

from __future__ import annotations

import argparse

from netcfg.commands.base import Subcommands

NAME = "lsp"
BATCH = False


def add_parser(sub: Subcommands) -> None:
    sub.add_parser(NAME, help="a language server on stdin/stdout for editors: diagnostics, hover, completion")


def run(args: argparse.Namespace) -> int:
    from netcfg.lsp.server import serve  # pygls only here: `import netcfg` and `check` never load it

    return serve()
