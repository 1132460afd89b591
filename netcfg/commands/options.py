"""What several subcommands share: option types, the DBC options, and how an I/O problem or a bug is reported."""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from netcfg.importers import ImportOptions

MAX_SEED = 2**63 - 1
MAX_RUNS = 1_000_000
MAX_JOBS = 1024
MAX_EVENTS_LIMIT = 10**15


def add_dbc_options(parser: argparse.ArgumentParser) -> None:
    """What a DBC does not say, the same for every command that reads one (check F.dbc, import dbc, init --from
    dbc, tune F.dbc): the bit rates and the period of messages that give no cycle time."""
    parser.add_argument("--bitrate", type=bitrate, help="DBC input: the bus bit rate (wins over the file's), e.g. 1M")
    parser.add_argument("--data-bitrate", type=bitrate,
                        help="DBC input with CAN FD frames: the data-phase bit rate (wins over the file's)")
    parser.add_argument("--default-period", type=duration_ns, metavar="T",
                        help="DBC input: messages that give no cycle time are periodic every T, e.g. 100ms")


def import_options(args: argparse.Namespace, output: Path | None = None) -> ImportOptions:
    """The options add_dbc_options defines (and --lenient, where the command has it) as the importer takes them."""
    return ImportOptions(args.bitrate, getattr(args, "lenient", False), output, args.default_period, args.data_bitrate)


def int_option(what: str, low: int, high: int) -> Any:
    """An argparse type: a whole number in [low, high] written with ASCII digits (int() takes any script's)."""

    def parse(text: str) -> int:
        from netcfg.spec.units import parse_int_option

        try:
            return parse_int_option(text, what, low, high)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from exc

    return parse


def number_option(what: str) -> Any:
    """An argparse type: a finite decimal number in the units module's grammar (float() takes 'nan', '1e400')."""

    def parse(text: str) -> float:
        from netcfg.spec.units import parse_number

        try:
            return float(parse_number(text, f"{what} {text!r}"))
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from exc

    return parse


def bitrate(text: str) -> int:
    """'500k', '1M', '250000' or '500 kbit/s' -> bit/s (the units module's grammar and ranges)."""
    from netcfg.spec.units import parse_bitrate_option

    try:
        return parse_bitrate_option(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"{text!r} is not a bit rate ({exc}); write 500k, 1M or '500 kbit/s'") from exc


def duration_ns(text: str) -> int:
    """'100ms', '100 ms', '2.5 ms' -> ns (the spec's duration grammar), positive."""
    from netcfg.spec.units import parse_duration

    try:
        ns = parse_duration(text).ns
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc
    if not ns:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive duration; write e.g. 100ms")
    return ns


def not_json(path: Path, exc: json.JSONDecodeError) -> int:
    """A runtime.json that does not parse: where, and how to get a good one (exit 1)."""
    print(f"{path}:{exc.lineno}:{exc.colno}: error: not valid JSON ({exc.msg}); rebuild it with 'netcfg build'",
          file=sys.stderr)
    return 1


def internal_error(doing: str, path: Path, exc: Exception, nothing_written: bool = False) -> int:
    """A bug in netcfg, not in the input: one message naming what it was doing (NETCFG_DEBUG=1 re-raises)."""
    if os.environ.get("NETCFG_DEBUG"):
        raise exc
    nothing = "Nothing was written. " if nothing_written else ""
    print(
        f"netcfg: internal error while {doing} {path}: {type(exc).__name__}: {exc}\n{nothing}"
        "This is a bug in netcfg; please report it (NETCFG_DEBUG=1 shows the traceback).",
        file=sys.stderr,
    )
    return 2


def guarded(
    command: Callable[[argparse.Namespace], int],
    args: argparse.Namespace,
    verb: str,
    doing: str,
    path: Path,
    passes: tuple[type[Exception], ...] = (),
) -> int:
    """command(args)'s exit code, where an OSError is a file that cannot be read or written (one line naming it,
    exit 2) and any other exception a bug in netcfg (`verb`, `doing`: what the command does, "simulate",
    "simulating"). `passes`: the exceptions left to the caller."""
    try:
        return command(args)
    except passes:
        raise
    except OSError as exc:
        print(f"netcfg: {io_problem(exc, verb, path)}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug in netcfg
        return internal_error(doing, path, exc)


def io_problem(exc: OSError, verb: str, path: Path) -> str:
    """One line for an I/O problem: the input and output guards' own messages name the file and what to do."""
    from netcfg.inputs import InputError
    from netcfg.outputs import OutputError

    if isinstance(exc, (InputError, OutputError)):
        return str(exc)
    where = f" ({exc.filename})" if exc.filename and str(exc.filename) != str(path) else ""
    return f"cannot {verb} {path}: {exc.strerror or exc}{where}"
