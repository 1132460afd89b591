"""What a live run of `netcfg run` did (netcfg.runtime.operate's outcome), as the JSON document of the design notes,
{"cycles", "nodes": [{"name", "state", "samples", "missing", "lost", "emcy"}]} with more keys beside them, and as
text; and the verdict: ok when every started node delivered every cycle, none was lost, rebooted or sent an EMCY,
no SYNC was missed and the bus never went off."""

from __future__ import annotations

from typing import Any


def result_document(outcome: Any, system: str | None = None) -> dict[str, Any]:
    """The JSON contract: {"cycles", "nodes": [{"name", "state", "samples", "missing", "lost", "emcy"}]}, plus the
    read times against the analysed bound, the events and what ended the run."""
    run = outcome.run
    cycles = run.cycles if run is not None else 0
    by_node: dict[str, dict[str, Any]] = {}
    for name, node in outcome.nodes.items():
        samples = run.complete_samples(name) if run is not None and name in run.nodes else 0
        due = sum(1 for rec in run.records if any(run.producers[m] == name for m in rec.due)) if run else 0
        by_node[name] = {
            "name": name,
            "node_id": node.node_id,
            "state": node.state,
            "samples": samples,
            "missing": due - samples if node.started else 0,
            "lost": node.lost_at_s is not None,
            "lost_at_s": None if node.lost_at_s is None else round(node.lost_at_s, 6),
            "silent_ms": None if node.lost_silent_ms is None else round(node.lost_silent_ms, 3),
            "heartbeat_timeout_ms": node.heartbeat_timeout_ms,
            "emcy": node.emcy,
            "set_up": node.setup_ok,
            "set_up_error": node.setup_error,
            "cia402": node.cia402_over,  # how the master drove its power state machine: "SDO", "PDO" or null
            "enable_path": node.enable_path,
            "stopped_at_s": None if node.stopped_at_s is None else round(node.stopped_at_s, 6),
            "safe_state": node.safe_state,
            "reboots": node.reboots,
            "errors": node.errors,
        }
    read: dict[str, Any] = {"analysed_bound_us": None, "window_us": None, "max_us": None, "overruns": 0}
    periods: dict[str, Any] = {
        "period_us": None,
        "min_us": None,
        "max_us": None,
        "analysed_jitter_us": 0,
        "overruns": 0,
    }
    if run is not None:
        complete = [rec.read_s for rec in run.records if rec.due and not rec.missing]
        read = {
            "analysed_bound_us": None if outcome.sync_completion_ns is None else outcome.sync_completion_ns / 1e3,
            "window_us": round(1e6 * run.read_window_s, 3),
            "max_us": round(1e6 * max(complete), 3) if complete else None,
            "mean_us": round(1e6 * sum(complete) / len(complete), 3) if complete else None,
            # a cycle whose due TPDOs were not all in when the read window closed, from nodes still in service
            "overruns": sum(
                1
                for rec in run.records
                if any(not outcome.out_of_service(run.producers[m], rec.sync_sent) for m in rec.missing)
            ),
            "beyond_analysis": sum(
                1
                for rec in run.records
                if rec.due
                and not rec.missing
                and outcome.sync_completion_ns is not None
                and round(rec.read_s * 1e9) > outcome.sync_completion_ns
            ),
        }
        spans = [rec.period_s for rec in run.records]
        periods = {
            "period_us": round(1e6 * run.period_s, 3),
            "min_us": round(1e6 * min(spans), 3) if spans else None,
            "max_us": round(1e6 * max(spans), 3) if spans else None,
            "analysed_jitter_us": outcome.master_jitter_ns / 1e3,
            # a cycle longer than T + the master's analysed wake-up latency: its SYNC came later than analysed
            "overruns": sum(
                1
                for rec in run.records
                if round(rec.period_s * 1e9) > round(run.period_s * 1e9) + outcome.master_jitter_ns
            ),
        }
    started = [n for n in by_node.values() if outcome.nodes[n["name"]].started]
    ok = (
        outcome.started
        and run is not None
        and all(n["missing"] == 0 and not n["lost"] and not n["emcy"] and not n["errors"] for n in started)
        and not read["overruns"]
        and not any(e.kind in ("tpdo-silent", "boot-up", "missed-sync", "bus-off") for _, e in outcome.events)
    )
    return {
        "system": system,
        "bus": outcome.bus,
        "ok": bool(ok),
        "cycles": cycles,
        "ended_by": outcome.ended_by,
        "read": read,
        "cycle": periods,
        "nodes": list(by_node.values()),
        "events": [
            {"time_s": round(t, 6), "node": e.node, "kind": e.kind, "action": e.action, "text": e.text}
            for t, e in outcome.events
        ],
        "drills": [{"time_s": round(t, 6), "what": text} for t, text in outcome.drills],
        "sync_gaps": outcome.sync_gaps,
        "bus_offs": outcome.bus_offs,
    }


def result_text(outcome: Any, doc: dict[str, Any]) -> str:
    lines = []
    if outcome.setup is not None:
        lines.append(str(outcome.setup))
    if not outcome.started:
        lines.append("nothing was started: fix the set-up (or run the others with --allow-missing)")
        return "\n".join(lines)
    for t, what in outcome.drills:
        lines.append(f"  {t:8.3f} s  drill: {what}")
    for e in doc["events"]:
        lines.append(f"  {e['time_s']:8.3f} s  {e['text']} -> {e['action']}")
    for name, notes in doc.get("simulated_drives", {}).items():
        lines += [f"  simulated {name}: {note}" for note in notes]
    lines.append(f"{doc['cycles']} cycles on {doc['bus']}, ended by {doc['ended_by']}")
    r, c = doc["read"], doc["cycle"]
    if r["max_us"] is not None:
        bound = "not analysed" if r["analysed_bound_us"] is None else f"{r['analysed_bound_us'] / 1e3:.3f} ms"
        lines.append(
            f"read (SYNC -> last TPDO): mean {r['mean_us'] / 1e3:.3f} ms, max {r['max_us'] / 1e3:.3f} ms; analysed "
            f"bound {bound} (cycles beyond it: {r['beyond_analysis']}), read window {r['window_us'] / 1e3:.3f} ms; "
            f"window overruns {r['overruns']}"
        )
    if c["min_us"] is not None:
        lines.append(
            f"period {c['period_us'] / 1e3:.3f} ms: min {c['min_us'] / 1e3:.3f} ms, max {c['max_us'] / 1e3:.3f} ms; "
            f"longer than T + the analysed {c['analysed_jitter_us']:g} us jitter: {c['overruns']}"
        )
    lines.append(f"{'node':10} {'state':20} {'samples':>7} {'missing':>7}  supervision")
    for n in doc["nodes"]:
        notes = []
        if n["lost"]:
            notes.append(
                f"lost at {n['lost_at_s']:.3f} s after {n['silent_ms']:.1f} ms silent "
                f"(heartbeat timeout {n['heartbeat_timeout_ms']:.0f} ms)"
            )
        notes += [e["text"] for e in n["emcy"]]
        for r in n["reboots"]:
            back = r.get("recovered_at_s") is not None
            result = f"recovered in {r['recovery_ms']:.1f} ms" if back else r.get("result", "")
            notes.append(f"rebooted at {r['at_s']:.3f} s ({r['action']}): {result}")
        notes += n["errors"]
        if n["safe_state"]:
            notes.append(f"safe stop -> {n['safe_state']}")
        lines.append(f"{n['name']:10} {n['state']:20} {n['samples']:>7} {n['missing']:>7}  {'; '.join(notes)}")
    lines.append("ok" if doc["ok"] else "NOT ok: see above")
    return "\n".join(lines)
