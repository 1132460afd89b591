"""`netcfg simulate`: read a spec (compiled in memory) or a runtime.json, run, print, write the trace and plots."""

from __future__ import annotations

import argparse
import gc
import json
import os
import secrets
import sys
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

from netcfg import jsontext, runtime
from netcfg.outputs import TMP_TAG
from netcfg.sim.faults import Fault, FaultError
from netcfg.sim.montecarlo import progress_bar, run_batch, run_once
from netcfg.sim.results import histograms, log_check, outside_error_assumption, summary, text
from netcfg.sim.scenario import SimOptions
from netcfg.spec.units import format_ns, parse_duration_option
from netcfg.timing.frames import CANFD_PADDING, canfd_padded_size, frame_bits

if TYPE_CHECKING:
    from netcfg.sim.trace import TraceFrame

MAX_DRIFT_PPM = 100_000.0  # 10 %: beyond any clock; the arithmetic stays meaningful below it
# The work one run may take, in events (message releases, task jobs, SYNCs, FTT-CAN elementary cycles), estimated
# from the configuration before it runs; --max-events raises it. Measured: large_plant's 20 s (231,400 estimated
# events) took 5 s on a 2-core machine under load, about 50,000 events/s, so 20 million is minutes of work.
DEFAULT_MAX_EVENTS = 20_000_000
# ISO 11898-1 fault confinement: a transmitter's error counter rises by 8 per failed frame and falls by 1 per good
# one, so where more than one frame in 9 fails it climbs without bound to bus-off, which the simulator does not
# model; bit error rates that fail more frames than that are refused.
MAX_FRAME_ERROR_RATE = 1 / 9


def events_per_second(cfg: runtime.RuntimeConfig) -> dict[str, Fraction]:
    """What generates simulation events, and how many per simulated second: every periodic or sporadic message
    (at its period or minimum inter-arrival), every task job (at its period, or at the rate of what activates it),
    every SYNC and FTT-CAN elementary cycle. A sporadic source counts at its fastest rate: an upper bound."""
    second = 10**9
    rates: dict[str, Fraction] = {}
    msg_rate: dict[str, Fraction] = {}
    for m in cfg.messages:
        every = m.period_ns or m.interval_ns
        msg_rate[m.name] = Fraction(second, every) if every else Fraction(0)
        rates[f"message '{m.name}'"] = msg_rate[m.name]
    trig_rate = {t.name: Fraction(second, t.interval_ns or t.period_ns) for t in cfg.triggers}
    rates.update({f"trigger '{name}'": r for name, r in trig_rate.items()})
    sync_rate: dict[str, Fraction] = {}
    for b in cfg.buses:
        if b.canopen is not None:
            sync_rate[b.name] = Fraction(second, b.canopen.sync_period_ns)
            rates[f"SYNC of bus '{b.name}'"] = sync_rate[b.name]
        if b.ftt is not None:
            rates[f"elementary cycle of bus '{b.name}'"] = Fraction(second, b.ftt.ec_ns)
    for n in cfg.nodes:
        for t in n.tasks:
            if t.period_ns:
                rate = Fraction(second, t.period_ns)
            elif t.trigger is not None:
                rate = trig_rate.get(t.trigger, Fraction(0))
            elif t.on_message is not None:
                rate = msg_rate.get(t.on_message, Fraction(0))
            else:
                rate = sync_rate.get(t.sync_bus or "", Fraction(0))
            rates[f"task '{t.ref}'"] = rate
    return rates


def work_problem(cfg: runtime.RuntimeConfig, duration_ns: int, max_events: int) -> str | None:
    """Why one run would take too long to simulate (more than max_events estimated events), or None."""
    rates = events_per_second(cfg)
    total = sum(rates.values(), Fraction(0)) * duration_ns / 10**9
    if total <= max_events:
        return None
    worst = max(rates, key=lambda k: rates[k])
    return (
        f"simulating {format_ns(duration_ns)} of this configuration takes about {int(total):,} events, more than "
        f"the limit of {max_events:,} (the most: {worst}, {float(rates[worst]):,.0f} per simulated second); "
        "shorten --duration, or raise --max-events if that much work is meant"
    )


def _frame_bits(m: runtime.Message) -> int:
    """Bits of one frame in the worst case (both phases of a CAN FD frame): what a bit error can hit."""
    return frame_bits(m.size, m.extended, m.fd, m.brs).total


def fault_problem(cfg: runtime.RuntimeConfig, faults: tuple[Fault, ...]) -> str | None:
    """Why a --fault would make the run meaningless (a bit error rate that sends CAN nodes bus-off), or None."""
    for f in faults:
        if f.kind != "ber" or f.value <= 0:
            continue
        frames = [_frame_bits(m) for m in cfg.messages if m.is_can and (f.target is None or m.bus == f.target)]
        if not frames:
            continue
        longest = max(frames)
        fail = 1 - (1 - f.value) ** longest
        if fail > MAX_FRAME_ERROR_RATE:
            limit = 1 - (1 - MAX_FRAME_ERROR_RATE) ** (1 / longest)
            return (
                f"--fault ber={f.value:g}: {fail:.0%} of the {longest}-bit frames would fail, and beyond 1 in 9 a "
                f"CAN transmitter goes bus-off (ISO 11898-1 fault confinement), which the simulator does not model; "
                f"give a rate of at most {limit:.2g} for these frames"
            )
    return None


def load_document(source: Path, force: bool = False) -> dict[str, Any] | None:
    """The runtime configuration as a JSON document: read, or compiled from a spec. None: errors were printed.

    With `force`, a spec whose model resolves but which check refuses (a missed deadline, an overloaded bus, a
    window too short...) is simulated anyway, with a warning: that is how a user sees how it fails.
    """
    if source.suffix == ".json":
        doc = runtime.read_document(source)  # the input guard: size, depth, number length
        runtime.parse(doc, str(source))  # the runtime schema, with ranges
        return dict(doc)
    from netcfg.check import analyse_spec
    from netcfg.emit.runtime_json import runtime_document

    model, report = analyse_spec(source)
    for d in report["errors"]:
        print(f"{d['file']}:{d['line']}:{d['column']}: error: {d['message']} [{d['code']}]", file=sys.stderr)
    if model is None or (report["errors"] and not force):
        hint = "" if model is None else " (--force simulates it anyway)"
        print(f"netcfg: {source} has errors; nothing was simulated{hint}", file=sys.stderr)
        return None
    if report["errors"]:
        print(
            f"netcfg: warning: {source} has {len(report['errors'])} errors and check refuses it; simulating it "
            "anyway (--force): the analysed bounds below are not guarantees",
            file=sys.stderr,
        )
    return json.loads(json.dumps(runtime_document(model, report)))


def simulate_command(args: argparse.Namespace) -> int:
    try:
        duration = parse_duration_option(args.duration)
    except ValueError as exc:
        print(f"netcfg: --duration {exc}", file=sys.stderr)
        return 2
    try:
        faults = tuple(Fault.parse(f) for f in args.fault)
    except FaultError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    if args.runs < 1 or duration <= 0:
        print("netcfg: --runs and --duration must be positive", file=sys.stderr)
        return 2
    if not 0 <= args.drift <= MAX_DRIFT_PPM:  # also refuses nan
        print(
            f"netcfg: --drift {args.drift}: give a clock tolerance between 0 and {MAX_DRIFT_PPM:g} ppm "
            "(crystals are within about 100 ppm)",
            file=sys.stderr,
        )
        return 2
    if args.seed < 0:
        print("netcfg: --seed must be 0 or more", file=sys.stderr)
        return 2
    if args.log is not None:  # the trace's writers (python-can) are imported only for a trace
        from netcfg.sim.trace import SUPPORTED_SUFFIXES
    if args.log is not None and args.log.suffix not in SUPPORTED_SUFFIXES:
        print(f"netcfg: --log {args.log}: the trace formats are {', '.join(SUPPORTED_SUFFIXES)}", file=sys.stderr)
        return 2
    try:
        doc = load_document(args.source, getattr(args, "force", False))
    except json.JSONDecodeError as exc:
        print(
            f"{args.source}:{exc.lineno}:{exc.colno}: error: not valid JSON ({exc.msg}); rebuild it with "
            "'netcfg build'",
            file=sys.stderr,
        )
        return 1
    except runtime.RuntimeConfigError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 1
    except UnicodeDecodeError:
        print(f"{args.source}: error: not a text file; give a spec (.yaml) or a runtime.json", file=sys.stderr)
        return 1
    if doc is None:
        return 1
    opts = SimOptions(
        duration_ns=duration,
        seed=args.seed,
        stuffing=args.stuffing,
        drift_ppm=args.drift,
        mode=args.mode,
        canopen=args.canopen,
        faults=faults,
        trace=args.log is not None,
    )
    cfg = runtime.parse(doc, str(args.source))
    max_events = getattr(args, "max_events", None) or DEFAULT_MAX_EVENTS
    problem = work_problem(cfg, duration, max_events) or fault_problem(cfg, faults)
    if problem:
        print(f"netcfg: {problem}", file=sys.stderr)
        return 2
    # The first run's objects (a live master's record of every cycle, ...) live until the report is out: the cyclic
    # collector's walks over them free nothing, and a live master's run would end with a full collection (0.3 s
    # after 600 s of ALLEX-2). Paused until the report is printed, unless a batch follows in this process.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        return _simulate(args, cfg, opts, doc)
    finally:
        if gc_was_enabled:
            _resume_gc()


def _resume_gc() -> None:
    """Collect again, with what was made meanwhile counted as old: freeze() then unfreeze() moves every tracked
    object to the oldest generation, lists merged, none walked; the next young collection would walk them all."""
    gc.freeze()
    gc.unfreeze()
    gc.enable()


def _simulate(args: argparse.Namespace, cfg: runtime.RuntimeConfig, opts: SimOptions, doc: dict[str, Any]) -> int:
    """simulate_command from the first run on."""
    try:
        sc, res = run_once(cfg, opts)
    except FaultError as exc:  # a --fault naming what the system does not have: a usage error
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 1
    if args.runs > 1:
        _resume_gc()  # every run of the batch leaves garbage behind
        rest = run_batch(
            doc,
            SimOptions(**{**opts.__dict__, "seed": args.seed + 1}),
            args.runs - 1,
            args.jobs,
            progress=lambda d, n: progress_bar(d + 1, n + 1),
        )
        res = res.merge(rest)  # wall_s: the first run's plus the batch's elapsed time
    doc_out = summary(res)
    if args.plots is not None:
        try:
            doc_out["plots"] = histograms(res, str(args.plots))
        except OSError as exc:
            print(f"netcfg: cannot write plots to {args.plots}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    if args.log is not None:
        frames = trace_frames(sc)
        doc_out["log_check"] = log_check(cfg, frames)
        try:
            _write_atomically(args.log, frames)
        except OSError as exc:
            print(f"netcfg: cannot write the trace {args.log}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    if args.format == "json":
        print(jsontext.dumps(doc_out, indent=2))
    else:
        print(text(doc_out))
    excused = outside_error_assumption(res)  # the analysis does not claim to bound this run
    if not excused:  # one line per measured range outside its analysed one
        for violation in doc_out["violations"]:
            print(f"netcfg: outside the analysis: {violation}", file=sys.stderr)
    bad = (
        doc_out["deadline_misses"]
        or doc_out["lost"]
        or doc_out.get("findings")
        or (doc_out["exceeds_analysis"] and not excused)
        or (not doc_out.get("log_check", {"ok": True})["ok"] and not excused)
    )
    return 1 if bad else 0


def _write_atomically(path: Path, frames: list[TraceFrame]) -> None:
    """The trace appears whole or not at all (a temporary file beside it, renamed)."""
    # a name no user file has (netcfg's temporary tag and a random part); the suffix picks the trace format
    tmp = path.with_name(f".{path.name}{TMP_TAG}{secrets.token_hex(4)}{path.suffix}")
    try:
        from netcfg.sim.trace import write_trace

        write_trace(frames, tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def trace_frames(sc: Any) -> list[TraceFrame]:
    """Every frame of every CAN bus, in time order, with error frames where a bit error hit."""
    from netcfg.sim.trace import TraceFrame

    out: list[TraceFrame] = []
    for name, bus in sc.can.items():
        rec = bus.record
        for m, end, data in zip(rec.msg, rec.end, rec.data):
            src = bus.sources[m]
            payload = data if data is not None else src.rest  # every field at rest, inside its range
            if src.fd:  # sent padded to its CAN FD length, as netcfg.runtime does
                payload += bytes([CANFD_PADDING]) * (canfd_padded_size(src.size) - src.size)
            out.append(TraceFrame(end, name, src.can_id, src.extended, payload, fd=src.fd, brs=src.brs))
        for t in bus.error_log:
            out.append(TraceFrame(t + bus.error_ns, name, 0, False, b"", True))
    out.sort(key=lambda f: (f.t_ns, f.channel))
    return out
