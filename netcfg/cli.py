"""Command line: netcfg check | build | import | simulate | run | verify | schema | lsp.

Exit codes: 0 ok, 1 spec errors or not schedulable (simulate: a miss, a loss or a result beyond the analysis),
2 usage or I/O problems.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
from pathlib import Path
from typing import Any

from netcfg import __version__, jsontext
from netcfg.importers import ImportOptions


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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="netcfg", description="Control-network configuration compiler.")
    parser.add_argument("--version", action="version", version=f"netcfg {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p_check = sub.add_parser("check", help="validate specs and analyse their timing; writes nothing")
    p_check.add_argument("specs", nargs="+", type=Path, metavar="SPEC", help="a spec, a DBC, or a folder of specs")
    p_check.add_argument("--format", choices=("text", "json"), default="text")
    p_check.add_argument("-q", "--quiet", action="store_true", help="print only errors and warnings")
    _add_dbc_options(p_check)
    p_check.add_argument("--lenient", action="store_true",
                         help="DBC input: accepted; what cannot be mapped is a warning anyway (see --default-period)")
    p_check.add_argument("--werror", action="append", default=[], metavar="CODE",
                         help="treat warnings with this code as errors (repeatable), e.g. dbc-no-receiver")
    p_check.add_argument("--explain", metavar="MESSAGE", help="derive one CAN message's bound and what would fix it")
    p_check.add_argument("--watch", action="store_true",
                         help="check again on every save of the spec or a file it names (Ctrl-C ends it)")
    p_check.add_argument("--watch-checks", type=_int_option("--watch-checks", 1, MAX_RUNS), help=argparse.SUPPRESS)
    p_build = sub.add_parser("build", help="check a spec, then write every artifact (default: generated/<system>/)")
    p_build.add_argument("spec", type=Path, metavar="SPEC")
    p_build.add_argument("-o", "--output", type=Path, metavar="DIR", help="output folder")
    p_import = sub.add_parser("import", help="write a netcfg spec from a DBC file or a ros2_canopen/Lely bus.yml")
    p_import.add_argument("kind", choices=("dbc", "bus-yml"))
    p_import.add_argument("source", type=Path, metavar="FILE")
    p_import.add_argument("-o", "--output", type=Path, required=True, metavar="SPEC", help="the spec to write")
    _add_dbc_options(p_import)
    p_import.add_argument("--lenient", action="store_true", help="what cannot be mapped is a warning, not an error")
    sub.add_parser("schema", help="print the JSON Schema of the spec language (for editors)")
    sub.add_parser("lsp", help="a language server on stdin/stdout for editors: diagnostics, hover, completion")
    _add_init_and_diff(sub)
    p_sim = sub.add_parser("simulate", help="run the runtime configuration in the discrete-event simulator")
    p_sim.add_argument("source", type=Path, metavar="SPEC|RUNTIME_JSON")
    p_sim.add_argument("--duration", default="10s", help="simulated time per run, e.g. 8s, 500ms (default 10s)")
    p_sim.add_argument("--seed", type=_int_option("--seed", 0, MAX_SEED), default=0,
                       help="random seed of the (first) run")
    p_sim.add_argument("--runs", type=_int_option("--runs", 1, MAX_RUNS), default=1,
                       help="Monte Carlo: this many runs, seeds seed..seed+runs-1")
    p_sim.add_argument("--jobs", type=_int_option("--jobs", 1, MAX_JOBS),
                       help="worker processes for --runs (default: every core)")
    p_sim.add_argument("--max-events", type=_int_option("--max-events", 1, MAX_EVENTS_LIMIT), default=None,
                       metavar="N", help="refuse a run estimated to need more simulated frames and task jobs than N "
                       "(default 20,000,000: minutes of work)")
    p_sim.add_argument("--format", choices=("text", "json"), default="text")
    p_sim.add_argument("--log", type=Path, metavar="FILE", help="CAN trace of the first run: .log (candump -L) or .asc")
    p_sim.add_argument("--plots", type=Path, metavar="DIR", help="histogram PNGs of response times and flow latencies")
    p_sim.add_argument("--mode", choices=("auto", "unsync"), default="auto",
                       help="unsync: run FTT-CAN and CANopen buses as free-running CAN (the alternative)")
    p_sim.add_argument("--canopen", choices=("pdo", "sdo"), default="pdo",
                       help="CANopen master: the SYNC/PDO cycle, or the older SDO polling loops")
    p_sim.add_argument("--stuffing", choices=("exact", "worst", "none"), default="worst",
                       help="frame lengths: bits actually stuffed, the worst case, or no stuff bits")
    p_sim.add_argument("--drift", type=_number_option("--drift"), default=50.0, metavar="PPM",
                       help="clock drift bound per node")
    p_sim.add_argument("--force", action="store_true",
                       help="simulate a spec that check refuses (to see how it fails); the analysis does not hold")
    p_sim.add_argument("--fault", action="append", default=[], metavar="FAULT",
                       help="inject a fault (repeatable): ber=1e-6, bit-error@12ms, crash:NODE@2s, "
                       "babble:NODE@1s..2s, lose:MESSAGE@100ms, master-fail@2s")
    from netcfg.run_cli import add_parser as add_run_parser
    from netcfg.verify.cli import add_parser as add_verify_parser

    add_run_parser(sub)
    add_verify_parser(sub)
    p_tune = sub.add_parser("tune", help="identifiers and offsets that make a CAN spec schedulable with the most slack")
    p_tune.add_argument("spec", type=Path, metavar="SPEC")
    p_tune.add_argument("-o", "--output", type=Path, required=True, metavar="OUT.yaml", help="the tuned spec to write")
    p_tune.add_argument("--robust", action="store_true", help="Davis & Burns' robust assignment: most error frames")
    p_tune.add_argument("--force", action="store_true", help="replace OUT.yaml if it exists")
    p_tune.add_argument("--format", choices=("text", "json"), default="text")
    _add_dbc_options(p_tune)
    args = parser.parse_args(argv)
    if args.command not in BATCH_COMMANDS:
        return _dispatch(args)
    # A batch command builds one large object graph (YAML nodes, spec, model, report, files) that lives until it
    # ends, and makes almost no cyclic garbage: every collection walks objects that all survive it. Off, then.
    # Measured (peak RSS, with the collector and without): 5,000-message check 107/108 MB as a spec, 112/113 MB as a
    # DBC; specs of 20,000 messages that are all errors 201/201 MB and 212/212 MB; a 126-drive build 140/143 MB.
    # The 126-drive import and build each spent about 0.08 s in 14 collections.
    enabled = gc.isenabled()
    gc.disable()
    try:
        return _dispatch(args)
    finally:
        if enabled:
            gc.enable()


BATCH_COMMANDS = frozenset({"check", "build", "import"})


def _dispatch(args: argparse.Namespace) -> int:
    try:
        if args.command == "check" and args.explain:
            from netcfg.explain import command as explain_command

            return explain_command(args.specs, args.explain, args.format, _import_options(args))
        if args.command == "check" and args.watch:
            from netcfg.watch import watch

            return watch(args.specs, _import_options(args), frozenset(args.werror), max_checks=args.watch_checks)
        if args.command == "check":
            return cmd_check(args.specs, args.format, _import_options(args), frozenset(args.werror), args.quiet)
        if args.command == "import":
            return cmd_import(args.kind, args.source, args.output, _import_options(args, args.output))
        if args.command == "build":
            return cmd_build(args.spec, args.output)
        if args.command == "schema":
            return cmd_schema()
        if args.command == "lsp":
            from netcfg.lsp.server import serve  # pygls only here: `import netcfg` and `check` never load it

            return serve()
        if args.command == "simulate":
            return cmd_simulate(args)
        if args.command == "run":
            return cmd_run(args)
        if args.command == "verify":
            return cmd_verify(args)
        if args.command == "tune":
            from netcfg.tune import command

            try:
                return command(args.spec, args.output, args.robust, args.force, args.format, _import_options(args))
            except OSError as exc:  # the spec or DBC cannot be read (tune itself reports what it cannot write)
                print(f"netcfg: {_io_problem(exc, 'read', args.spec)}", file=sys.stderr)
                return 2
        if args.command == "init":
            from netcfg.init_spec import init_command

            return init_command(args.source, args.file or args.dbc, args.output, _import_options(args))
        if args.command == "diff":
            from netcfg.diff import diff_command

            return diff_command(args.old, args.new, args.format)
    except BrokenPipeError:  # e.g. `netcfg check x | head`
        return 0
    return 2  # pragma: no cover - argparse rejects unknown commands


def _add_dbc_options(parser: argparse.ArgumentParser) -> None:
    """What a DBC does not say, the same for every command that reads one (check F.dbc, import dbc, init --from
    dbc, tune F.dbc): the bit rates and the period of messages that give no cycle time."""
    parser.add_argument("--bitrate", type=_bitrate, help="DBC input: the bus bit rate (wins over the file's), e.g. 1M")
    parser.add_argument("--data-bitrate", type=_bitrate,
                        help="DBC input with CAN FD frames: the data-phase bit rate (wins over the file's)")
    parser.add_argument("--default-period", type=_duration_ns, metavar="T",
                        help="DBC input: messages that give no cycle time are periodic every T, e.g. 100ms")


def _import_options(args: argparse.Namespace, output: Path | None = None) -> ImportOptions:
    """The options _add_dbc_options defines (and --lenient, where the command has it) as the importer takes them."""
    return ImportOptions(args.bitrate, getattr(args, "lenient", False), output, args.default_period, args.data_bitrate)


def _add_init_and_diff(sub: Any) -> None:
    from netcfg.init_spec import SOURCES

    p_init = sub.add_parser("init", help="write a commented starting spec that check accepts")
    p_init.add_argument("--from", dest="source", choices=SOURCES, help="start from an example system or a DBC")
    p_init.add_argument("file", nargs="?", type=Path, metavar="FILE", help="with --from dbc: the DBC file")
    p_init.add_argument("--dbc", type=Path, metavar="FILE", help="the same as --from dbc FILE")
    p_init.add_argument("-o", "--output", type=Path, metavar="SPEC", help="the spec to write (default: stdout)")
    _add_dbc_options(p_init)
    p_diff = sub.add_parser("diff", help="what changed between two specs or two build folders, in timing terms")
    p_diff.add_argument("old", type=Path, metavar="A", help="a spec or a build folder")
    p_diff.add_argument("new", type=Path, metavar="B", help="a spec or a build folder")
    p_diff.add_argument("--format", choices=("text", "json"), default="text")


MAX_SEED = 2**63 - 1
MAX_RUNS = 1_000_000
MAX_JOBS = 1024
MAX_EVENTS_LIMIT = 10**15


def _int_option(what: str, low: int, high: int) -> Any:
    """An argparse type: a whole number in [low, high] written with ASCII digits (int() takes any script's)."""

    def parse(text: str) -> int:
        from netcfg.spec.units import parse_int_option

        try:
            return parse_int_option(text, what, low, high)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from exc

    return parse


def _number_option(what: str) -> Any:
    """An argparse type: a finite decimal number in the units module's grammar (float() takes 'nan', '1e400')."""

    def parse(text: str) -> float:
        from netcfg.spec.units import parse_number

        try:
            return float(parse_number(text, f"{what} {text!r}"))
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from exc

    return parse


def _bitrate(text: str) -> int:
    """'500k', '1M', '250000' or '500 kbit/s' -> bit/s (the units module's grammar and ranges)."""
    from netcfg.spec.units import parse_bitrate_option

    try:
        return parse_bitrate_option(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"{text!r} is not a bit rate ({exc}); write 500k, 1M or '500 kbit/s'") from exc


def _duration_ns(text: str) -> int:
    """'100ms', '100 ms', '2.5 ms' -> ns (the spec's duration grammar), positive."""
    from netcfg.spec.units import parse_duration

    try:
        ns = parse_duration(text).ns
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc
    if not ns:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive duration; write e.g. 100ms")
    return ns


def cmd_import(kind: str, source: Path, output: Path, options: ImportOptions) -> int:
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
        print(f"netcfg: {_io_problem(exc, 'read', source)}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug in netcfg, not in the file: nothing is written
        return _internal_error("importing", source, exc, nothing_written=True)
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


def cmd_check(
    paths: list[Path],
    fmt: str,
    options: ImportOptions | None = None,
    werror: frozenset[str] = frozenset(),
    quiet: bool = False,
) -> int:
    from netcfg.check import check, promote_warnings, spec_files
    from netcfg.report_text import render

    try:
        paths = spec_files(paths)
    except OSError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    reports: list[dict[str, Any]] = []
    for n, path in enumerate(paths):
        if n:
            gc.collect()  # the last spec's model (its cycles: the collector is off in a batch command, see main())
        try:
            reports.append(promote_warnings(check(path, options), werror))
        except OSError as exc:
            print(f"netcfg: {_io_problem(exc, 'read', path)}", file=sys.stderr)
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
        print(jsontext.dumps(doc, indent=2))
    else:
        for report in reports:
            if quiet:  # the problems only: warnings, then errors below
                for d in report["warnings"]:
                    print(f"{d['file']}:{d['line']}:{d['column']}: warning: {d['message']} [{d['code']}]")
            else:
                print(render(report))
            for d in report["errors"]:
                print(f"{d['file']}:{d['line']}:{d['column']}: error: {d['message']} [{d['code']}]", file=sys.stderr)
    return 0 if all(r["ok"] for r in reports) else 1


def cmd_build(spec: Path, output: Path | None) -> int:
    from netcfg.emit import Background

    worker = Background.start()  # first: it imports what the report needs while the rest loads and the spec is read
    from netcfg.build import build
    from netcfg.inputs import InputError
    from netcfg.outputs import OutputError

    try:
        report, target, files = build(spec, output, worker)
    except (OutputError, InputError) as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"netcfg: cannot build {spec}: {exc.strerror or exc} ({exc.filename or ''})", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug in netcfg: nothing was swapped in
        return _internal_error("building", spec, exc, nothing_written=True)
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


def cmd_simulate(args: argparse.Namespace) -> int:
    from netcfg.sim.cli import simulate_command

    try:
        return simulate_command(args)
    except OSError as exc:
        print(f"netcfg: {_io_problem(exc, 'simulate', args.source)}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug in netcfg
        return _internal_error("simulating", args.source, exc)


def _internal_error(doing: str, path: Path, exc: Exception, nothing_written: bool = False) -> int:
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


def _io_problem(exc: OSError, verb: str, path: Path) -> str:
    """One line for an I/O problem: the input and output guards' own messages name the file and what to do."""
    from netcfg.inputs import InputError
    from netcfg.outputs import OutputError

    if isinstance(exc, (InputError, OutputError)):
        return str(exc)
    where = f" ({exc.filename})" if exc.filename and str(exc.filename) != str(path) else ""
    return f"cannot {verb} {path}: {exc.strerror or exc}{where}"


def cmd_run(args: argparse.Namespace) -> int:
    from netcfg.run_cli import run_command

    try:
        return run_command(args)
    except KeyboardInterrupt:  # before the cycle's own handler was armed (set-up): what was started is stopped
        print(f"netcfg: {args.source}: interrupted; started nodes were brought to their safe state", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"netcfg: {_io_problem(exc, 'run', args.source)}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug in netcfg; the safe stop has run (operate's finally)
        return _internal_error("running", args.source, exc)


def cmd_verify(args: argparse.Namespace) -> int:
    from netcfg.verify.cli import verify_command

    try:
        return verify_command(args)
    except BrokenPipeError:
        raise  # main's: `netcfg verify ... | head` is not an error
    except OSError as exc:
        print(f"netcfg: {_io_problem(exc, 'verify', args.log)}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug in netcfg
        return _internal_error("verifying", args.log, exc)


def cmd_schema() -> int:
    from netcfg.spec.schema import Spec

    schema = Spec.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "netcfg spec"
    print(jsontext.dumps(schema, indent=2, sort_keys=True))
    return 0
