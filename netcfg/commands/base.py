"""The shape every subcommand module has, so the registry (netcfg.commands.COMMANDS) can hold modules.

A subcommand is a module of netcfg.commands with:

    NAME = "check"                  # what a user types after `netcfg`
    BATCH = True                    # see below
    def add_parser(sub) -> None     # its sub-parser and options, added to `netcfg`'s
    def run(args) -> int            # the command, given the parsed arguments; returns the exit code

Only the parser side runs for every command line, so a module imports at its top only what parsing needs (argparse,
pathlib, netcfg.commands.options) and the rest inside run(): `netcfg check` never loads the simulator or pygls.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    Subcommands = argparse._SubParsersAction[argparse.ArgumentParser]
else:  # not subscriptable at run time
    Subcommands = argparse._SubParsersAction


class Command(Protocol):
    """A subcommand module (see the module docstring)."""

    NAME: str
    # A batch command builds one large object graph that lives until it ends and makes almost no cyclic garbage;
    # main() runs it with the cyclic collector off.
    BATCH: bool

    def add_parser(self, sub: Subcommands) -> None: ...

    def run(self, args: argparse.Namespace) -> int: ...
