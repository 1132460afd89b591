"""`netcfg check SPEC --explain FLOW`: a flow's bounds beside the figures of every step they are made of.

The flow analysis (netcfg.timing.flows) composes each step's own bounds: a task's activation (its period or what
starts it, its offset) and its best and worst response, a message's release (period or minimum gap, offset, the
jitter its sending task adds) and its best and worst delivery. This lists them step by step, as check computed
them, with the flow's synchronised and unsynchronised latency bounds, the mode check judges it by, and its
deadline: what to look at first when a flow misses (the slowest reader's period, a long response), not a second
derivation of the bounds.
"""

from __future__ import annotations

from typing import Any

from netcfg import model, protocols
from netcfg.report_text import num


def cycle_name(m: model.Model, task: model.Task) -> str:
    """What a task on its bus's cycle runs on, as its protocol names it ("SYNC", "EtherCAT cycle", "SYNC0")."""
    bus = m.buses[task.sync_bus or ""]
    cycle = protocols.of(bus).task_cycle(bus, task.node)
    return cycle.name if cycle is not None else "the cycle"


def explain_flow(m: model.Model, report: dict[str, Any], name: str) -> dict[str, Any]:
    flow = m.flows[name]
    row = next(f for f in report["flows"] if f["name"] == name)
    messages = {x["name"]: (b["name"], x) for b in report["buses"] for x in b["messages"]}
    tasks = {f"{n['name']}.{t['name']}": t for n in report.get("nodes", ()) for t in n["tasks"]}
    steps = []
    for i, step in enumerate(flow.steps):
        items = []
        for ref in step.refs:
            if step.kind == "task":
                task = m.task(ref)
                figures = tasks.get(ref, {})
                started = (
                    f"on {cycle_name(m, task)} of {task.sync_bus}" if task.sync_bus
                    else f"every {num(task.period_ns / 1000)} us" if task.period_ns
                    else f"on {task.on_message}" if task.on_message
                    else f"on trigger {task.trigger}" if task.trigger
                    else "-"
                )
                items.append({
                    "kind": "task", "name": ref, "started": started, "offset_us": task.offset_ns / 1000,
                    "best_us": task.bcet_ns / 1000, "worst_us": figures.get("wcrt_us"),
                    "jitter_us": figures.get("jitter_us"),
                })
            else:
                bus, figures = messages[ref]
                msg = m.messages[ref]
                items.append({
                    "kind": "message", "name": ref, "bus": bus,
                    "started": f"every {num(msg.interval_ns / 1000)} us" if msg.interval_ns else msg.kind,
                    "offset_us": figures.get("offset_us"), "best_us": figures.get("frame_us_worst"),
                    "worst_us": figures.get("wcrt_us"), "jitter_us": figures.get("jitter_us"),
                })
        steps.append({"step": i + 1, "items": items})
    deadline = row.get("deadline_us")
    return {
        "flow": name,
        "mode": row.get("mode"),
        "latency_min_us": row["latency_min_us"],
        "latency_max_us": row["latency_max_us"],
        "synchronised": row.get("synchronised"),
        "unsynchronised": row.get("unsynchronised"),
        "deadline_us": deadline,
        "meets": row.get("meets_deadline"),
        "slack_us": None if deadline is None or row["latency_max_us"] is None else deadline - row["latency_max_us"],
        "steps": steps,
    }


def text(doc: dict[str, Any]) -> str:
    out = [
        f"flow {doc['flow']} ({doc['mode']}): latency {num(doc['latency_min_us'])} .. {num(doc['latency_max_us'])} us"
        + ("" if doc["deadline_us"] is None else
           f", deadline {num(doc['deadline_us'])} us ({'meets it' if doc['meets'] else 'MISSES it'}, slack "
           f"{num(doc['slack_us'])} us)")
    ]
    for label in ("synchronised", "unsynchronised"):
        b = doc.get(label)
        if b:
            out.append(f"  {label:<15} {num(b['latency_min_us'])} .. {num(b['latency_max_us'])} us")
    out.append("  steps, each with its own figures as check computed them (us):")
    out.append(f"    {'#':>2}  {'item':<28} {'started':<26} {'offset':>9} {'best':>9} {'worst':>9} {'jitter':>9}")
    for step in doc["steps"]:
        for item in step["items"]:
            name = item["name"] + (f" ({item['bus']})" if item["kind"] == "message" else "")
            out.append(
                f"    {step['step']:>2}  {name:<28} {item['started']:<26} {num(item['offset_us']):>9} "
                f"{num(item['best_us']):>9} {num(item['worst_us']):>9} {num(item['jitter_us']):>9}"
            )
    out.append("  (a task: its BCET .. worst-case response; a message: its worst-case frame time .. its worst-case "
               "response)")
    return "\n".join(out)
