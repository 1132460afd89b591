"""The verify report as a user reads it: text, one line per violation, and the JSON document without the
per-window and histogram data that only the plots draw (`netcfg verify`, netcfg.commands.verify)."""

from __future__ import annotations

from typing import Any


def public_document(report: dict[str, Any]) -> dict[str, Any]:
    """The JSON document: histograms and the load of every window are left to --report (a long log has millions)."""
    out = dict(report)
    out["messages"] = [{k: v for k, v in m.items() if k != "histograms"} for m in report["messages"]]
    out["buses"] = [{k: v for k, v in b.items() if k != "load_per_window"} for b in report["buses"]]
    return out


def violation_lines(report: dict[str, Any], log: str) -> list[str]:
    """One line per violation: the log, the time in it, the kind, the message and by how much."""
    lines = [
        f"{log}: {v['time_us'] / 1e6:.6f} s: {v['kind']}: {v['message'] + ': ' if v['message'] else ''}{v['detail']}"
        for v in report["violations"]
    ]
    hidden = report["violation_count"] - len(report["violations"])
    if hidden > 0:
        kinds = ", ".join(f"{k} {n}" for k, n in report["violations_by_kind"].items())
        lines.append(f"{log}: and {hidden} more violations (all of them by kind: {kinds})")
    return lines


def text(report: dict[str, Any]) -> str:
    start = report["start_us"] or 0
    lines = [
        f"system {report['system']}: {report['frames']} frames over {report['duration_us'] / 1e6:.3f} s "
        f"(times below count from its first frame, at {start / 1e6:.6f} s in the log), {report['error_frames']} "
        "error frames, "
        f"{report['violation_count']} violations, {report['warning_count']} warnings",
        *_phase_lines(report.get("phases")),
        *_sequence_lines(report),
        "",
        f"  {'message':<24}{'id':>9}{'count':>10}{'period min/mean/max ms':>27}{'jitter us':>11}{'bound us':>10}"
        f"{'resp max us':>13}{'wcrt us':>9}{'missing':>9}  ok",
    ]
    for m in report["messages"]:
        p = m["period_us"]
        period = "-" if p is None else f"{p['min'] / 1000:.3f}/{p['mean'] / 1000:.3f}/{p['max'] / 1000:.3f}"
        r = m["response_us"]
        ok = {True: "yes", False: "NO", None: "-"}[m["within_analysis"]]
        if m["warnings"]:
            ok += f" ({m['warnings']} warnings)"
        lines.append(
            f"  {m['name']:<24}{m['id']:>9X}{m['count']:>10}{period:>27}{_f(m['jitter_us']):>11}"
            f"{_f(m['analysed_jitter_us']):>10}{_f(None if r is None else r['max']):>13}{_f(m['wcrt_us']):>9}"
            f"{m['missing']:>9}  {ok}"
        )
    for b in report["buses"]:
        load = b["load"]
        lines += [
            "",
            f"  bus {b['name']} ({b['protocol']}, {b['bitrate']} bit/s): load per {report['window_us'] / 1000:g} ms "
            + ("-" if load is None else f"{load['min']:.1%} min, {load['mean']:.1%} mean, {load['max']:.1%} max")
            + f"; analysed utilisation {b['utilization_analysed']:.1%}, at most {b['window_bound']:.1%} per window",
        ]
        co = b.get("canopen")
        if co:
            s = co["sync"]
            if s and s["period_us"]:
                p = s["period_us"]
                lines.append(
                    f"    SYNC: {s['count']} frames, period {p['min'] / 1000:.3f}/{p['mean'] / 1000:.3f}/"
                    f"{p['max'] / 1000:.3f} ms, jitter {s['jitter_us']} us"
                )
            if co["sync_window_us"] is not None and co["synchronous_pdos"]:
                worst = max((x["response_max_us"] or 0 for x in co["synchronous_pdos"]), default=0)
                inside = all(x["inside_window"] is not False for x in co["synchronous_pdos"])
                lines.append(
                    f"    synchronous PDOs: the last {worst} us after SYNC, window {co['sync_window_us']:g} us"
                    f" ({'inside' if inside else 'OUTSIDE'})"
                )
            for name, hb in co["heartbeats"].items():
                lines.append(f"    heartbeat {name}: {hb['count']} frames, state {hb['state']}")
            for st in co["nmt_states"]:
                lines.append(f"    {st['time_us'] / 1e6:.6f} s: {st['node']} -> {st['state']}")
            for c in co["nmt_commands"]:
                lines.append(f"    {c['time_us'] / 1e6:.6f} s: NMT {c['command']} to {c['node']}")
            for e in co["emcy"]:
                lines.append(f"    {e['time_us'] / 1e6:.6f} s: EMCY from {e['node']}: code {e['code']}")
            if co["sdo_frames"]:
                lines.append(f"    {co['sdo_frames']} SDO frames")
    if report["unknown_ids"]:
        lines += ["", "  unknown identifiers: " + ", ".join(
            f"0x{u['id']:X} ({u['count']})" for u in report["unknown_ids"])]
    if report["never_seen"]:
        lines += ["", "  never seen: " + ", ".join(report["never_seen"])]
    for w in report["warnings"][:20]:
        lines.append(f"  warning: {w['time_us'] / 1e6:.6f} s: {w['kind']}: {w['message']}: {w['detail']}")
    if report["warning_count"] > 20:
        lines.append(f"  ... {report['warning_count'] - 20} more warnings (--format json lists up to 1000)")
    if report["ok"]:
        verdict = "  inside the analysis"
    elif not report["violation_count"]:
        verdict = "  A FAULT: see its phases above (no violation outside them)"
    else:
        verdict = "  OUTSIDE THE ANALYSIS: see the violations below"
    lines += ["", verdict]
    return "\n".join(lines)


def _phase_lines(phases: dict[str, Any] | None) -> list[str]:
    """A master's log: what came before and after the cyclic phase, which alone is judged (verify.phases)."""
    if phases is None:
        return []
    c = phases["cyclic"]
    out = [f"  cyclic phase, judged below: {c['from_us'] / 1e6:.6f} .. {c['to_us'] / 1e6:.6f} s of the log"]
    for name in ("setup", "shutdown"):
        ph = phases[name]
        if not ph["frames"]:
            continue
        starts = sum(1 for n in ph["nmt_commands"] if n["command"] == "start")
        out.append(
            f"  {'set-up' if name == 'setup' else 'shut-down'}: {ph['frames']} frames ({ph['sdo_frames']} SDO, "
            f"{len(ph['nmt_commands'])} NMT commands, {starts} of them start, {len(ph['boot_ups'])} boot-ups), "
            f"{ph['from_us'] / 1e6:.6f} .. {ph['to_us'] / 1e6:.6f} s, not judged against the analysis"
        )
    return out


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.0f}"


def _sequence_lines(report: dict[str, Any]) -> list[str]:
    """The log as phases when it holds a fault (netcfg.verify.fault_phases), and whose clock stamped it."""
    out = []
    stamps = report.get("timestamps")
    if stamps is not None and stamps["clock"] == "host":
        out.append(
            f"  timestamps: a host's, not the wire's: {stamps['too_close']} of {stamps['pairs']} frames came sooner "
            f"after the one before than the bus can carry them (as close as {stamps['closest_us']} us, a frame needs "
            f"{stamps['needed_us']} us); responses beyond their bound are the host's lateness (host_late)"
        )
    if not report.get("fault_phases"):
        return out
    out.append(f"  phases ({report['fault_count']} faults):")
    for ph in report["phase_sequence"]:
        what = ph["phase"] if ph["phase"] != "normal" else "normal operation"
        detail = f": {ph['detail']}" if ph.get("detail") else ""
        out.append(f"    {ph['from_us'] / 1e6:9.6f} .. {ph['to_us'] / 1e6:9.6f} s  {what}{detail}")
    return out
