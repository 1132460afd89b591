"""Command line: netcfg check | build | import | schema | lsp | init | diff | simulate | run | verify | tune.

One module per subcommand (its options beside what it does; the shape is netcfg.commands.base's), listed once in
COMMANDS in the order `netcfg --help` shows them. `check --explain` and `check --watch` are check's modes
(netcfg.commands.explain, netcfg.commands.watch); netcfg.commands.options holds what several commands share.

Exit codes: 0 ok, 1 spec errors or not schedulable (simulate: a miss, a loss or a result beyond the analysis),
2 usage or I/O problems.
"""

from __future__ import annotations

import argparse
import gc
import os

from netcfg import __version__
from netcfg.commands import build, check, diff, import_, init, lsp, run, schema, simulate, tune, verify
from netcfg.commands.base import Command
from netcfg.gc_pause import gc_paused

COMMANDS: tuple[Command, ...] = (check, build, import_, schema, lsp, init, diff, simulate, run, verify, tune)
BY_NAME = {c.NAME: c for c in COMMANDS}


def command() -> int:
    """The `netcfg` command (and `python -m netcfg`): main() in a process of its own, which sets two defaults for
    itself first. A program calling main() keeps its environment as it is. A user's own settings win.

    - netcfg's array work is element by element, never linear algebra: OpenBLAS's thread pool, started as numpy is
      imported, only burns CPU (0.08 s of a 0.4 s simulate process on 2 cores).
    - pydantic looks for plugins in the entry points of every installed distribution when it builds the first
      model; the spec's models are netcfg's own, no plugin is meant for them (1 % of a check, more where many
      packages are installed).
    - The process ends right after: Python's last collection, as it exits, would walk every object the command
      built only to free memory the exit frees anyway (0.27 s after a 126-drive build). Frozen, they are left
      to the exit; nothing netcfg relies on is finalised by that collection (files are closed as they are written)."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    try:
        return main()
    finally:
        gc.freeze()


def parser() -> argparse.ArgumentParser:
    """`netcfg` and every subcommand's options."""
    top = argparse.ArgumentParser(prog="netcfg", description="Control-network configuration compiler.")
    top.add_argument("--version", action="version", version=f"netcfg {__version__}")
    sub = top.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for c in COMMANDS:
        c.add_parser(sub)
    return top


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    chosen = BY_NAME[args.command]
    if not chosen.BATCH:
        return _run(chosen, args)
    # A batch command builds one large object graph (YAML nodes, spec, model, report, files) that lives until it
    # ends, and makes almost no cyclic garbage: every collection walks objects that all survive it. Off, then.
    # Measured (peak RSS, with the collector and without): 5,000-message check 107/108 MB as a spec, 112/113 MB as a
    # DBC; specs of 20,000 messages that are all errors 201/201 MB and 212/212 MB; a 126-drive build 140/143 MB.
    # The 126-drive import and build each spent about 0.08 s in 14 collections.
    with gc_paused():
        return _run(chosen, args)


def _run(chosen: Command, args: argparse.Namespace) -> int:
    try:
        return chosen.run(args)
    except BrokenPipeError:  # e.g. `netcfg check x | head`
        return 0
