"""report.md and report/*.png: the build report an engineer reads, beside the artifacts it explains.

The numbers come from the analysis report (and names, roles and descriptions from the Model); nothing here
re-derives timing. The Python side formats a view, templates/report.md.j2 lays it out, and two plots are
drawn with matplotlib's Agg canvas: the FTT-CAN macro-cycle and the CANopen SYNC cycle (netcfg.emit.report_plots).
"""

from __future__ import annotations

from pathlib import PurePath
from typing import Any

from netcfg.emit.report_plots import DPI, FTT_WIDTH_IN, SYNC_HEIGHT_IN, SYNC_WIDTH_IN, draw, shown_ecs, warm_up
from netcfg.model import Bus, Described, Model, Node
from netcfg.report_text import errors_text, master_loop_text, num, rate
from netcfg.runtime.actuator_plan import loss_timeout_ns
from netcfg.templating import render

# the emitter, and what report_html and the tests read of the plots through it
__all__ = ["DPI", "FTT_WIDTH_IN", "SYNC_HEIGHT_IN", "SYNC_WIDTH_IN", "cell", "emit", "shown_ecs", "warm_up"]

PROTOCOLS = {
    "can": "CAN",
    "can-fd": "CAN FD",
    "canopen": "CANopen",
    "ftt-can": "FTT-CAN",
    "ethernet-udp": "switched Ethernet, UDP",
    "ethercat": "EtherCAT",
}


def emit(model: Model, report: dict[str, Any]) -> dict[str, bytes]:
    buses = [_bus_view(model, b) for b in report["buses"]]
    files = {
        "report.md": render(
            "report.md.j2",
            system=report.get("system") or model.system,
            description=one_line(_description(model)),
            spec_file=PurePath(model.file).name,  # the name only: no machine paths in generated files
            ok=report["ok"],
            nodes=_nodes_table(model),
            buses=buses,
            flows=_flows_view(report["flows"], model),
            errors=[_diagnostic(d) for d in report["errors"]],
            warnings=[_diagnostic(d) for d in report["warnings"]],
        )
    }
    # the views name the plots the report links: draw exactly those
    plots = {
        view[kind]["png"]: (kind, b)
        for view, b in zip(buses, report["buses"])
        for kind in ("ftt", "sync")
        if view[kind] and view[kind]["png"]
    }
    if plots:
        files.update(draw(model, plots))
    return files


# ---------------------------------------------------------------------------------------------------------------
# text helpers


def pct(value: float | None, digits: int = 1) -> str:
    return "-" if value is None else f"{value * 100:.{digits}f} %"


def one_line(text: object) -> str:
    """Free text from the spec on one line: newlines would end a paragraph, list item or table row."""
    return "" if text is None else " ".join(str(text).split())


def cell(text: object) -> str:
    """Free text as one Markdown table cell: one line, '|' escaped (and '\\', so that a trailing backslash
    cannot escape the escape)."""
    return one_line(text).replace("\\", "\\\\").replace("|", "\\|")


def _sentence(text: str) -> str:
    return text[:1].upper() + text[1:] + "."


def _description(obj: Described | None) -> str | None:
    # free text from the spec; implicit messages (SYNC, heartbeats) are not in Model.messages and have none
    value = obj.description if obj is not None else None
    return value if value and value.strip() else None


def _table(headers: list[str], align: str, rows: list[list[str]]) -> dict[str, Any]:
    rule = "|" + "|".join("---:" if a == "r" else ":---" for a in align) + "|"
    return {
        "header": "| " + " | ".join(headers) + " |",
        "rule": rule,
        "rows": ["| " + " | ".join(r) + " |" for r in rows],
    }


def _verdict(ok: bool | None) -> str:
    return "-" if ok is None else ("ok" if ok else "**MISSED**")


def _diagnostic(d: dict[str, Any]) -> str:
    return f"`{PurePath(d['file']).name}:{d['line']}:{d['column']}` {one_line(d['message'])} [{d['code']}]"


def _hex(ident: int, extended: bool = False) -> str:
    if ident < 0:
        return "-"
    return f"0x{ident:08X}" if extended else f"0x{ident:X}"


# ---------------------------------------------------------------------------------------------------------------
# the view


def _nodes_table(model: Model) -> dict[str, Any]:
    rows = []
    for node in model.nodes.values():
        address = node.ip or (str(node.node_id) if node.node_id is not None else "-")
        rows.append(
            [
                node.name,
                node.role,
                address,
                ", ".join(node.buses),
                ", ".join(node.tasks) or "-",
                _tx_queue(model, node),
                _supervision(model, node),
                cell(_description(node)) or "-",
            ]
        )
    headers = [
        "node",
        "role",
        "node id / IP",
        "buses",
        "tasks",
        "CAN transmit queue",
        "supervision (netcfg run)",
        "description",
    ]
    return _table(headers, "llllllll", rows)


def _supervision(model: Model, node: Node) -> str:
    """What the live master does when a CANopen slave is lost, sends an EMCY or reboots, or an actuator stops
    answering or reports an error (spec: on_loss, ...)."""
    if node.actuator is not None:
        periods = [m.period_ns for m in model.messages.values() if m.producer == node.name and m.period_ns]
        timeout = loss_timeout_ns(node.heartbeat_timeout_ns, periods)
        heard = f"lost after {timeout / 1e6:g} ms silent: {node.on_loss}" if timeout else "nothing to supervise"
        return f"{heard}; error flags: {node.on_emcy}"
    if node.role == "master" or node.node_id is None or not any(model.buses[b].canopen for b in node.buses):
        return "-"
    if node.heartbeat_timeout_ns:
        heard = f"lost after {node.heartbeat_timeout_ns / 1e6:g} ms without heartbeat: {node.on_loss}"
    else:
        heard = "no heartbeat consumed"
    return f"{heard}; EMCY: {node.on_emcy}; reboot: {node.on_reboot}"


def _tx_queue(model: Model, node: Node) -> str:
    if not any(model.buses[b].is_can for b in node.buses):
        return "-"
    q = node.tx_queue
    return f"FIFO, depth {q.depth}, {q.on_full} when full" if q.fifo else "priority"


def _tx_queues_view(b: dict[str, Any]) -> list[str]:
    """One sentence per FIFO transmit queue on the bus: its shared bound and the terms that make it up."""
    out = []
    for q in b.get("tx_queues", ()):
        apart = q.get("by_offsets", False)
        bound = (
            f"**{num(q['queue_us'])} us** from queuing to the end of the frame (blocking {num(q['blocking_us'])} + "
            + (
                f"the frames that can be queued together ({len(q['together'])}) {num(q['queued_us'])}"
                if apart
                else f"every frame of the queue {num(q['queued_us'])}"
            )
            + f" + other nodes' frames above {cell(q['lowest'])}, its "
            f"lowest-priority message, {num(q['interference_us'])}"
            + (f" + bit errors {num(q['error_us'])}" if q.get("error_us") else "")
            + "), plus each message's own release jitter; at most "
            f"{q['backlog_max']} frame{'s' if q['backlog_max'] != 1 else ''} queued at once"
            + (f"; {', '.join(cell(n) for n in q['dropped'])} can be dropped" if q.get("dropped") else "")
            if q["queue_us"] is not None
            else "**no bound** (" + cell(q.get("unbounded")) + ")"
        )
        share = "kept apart by their offsets, the longest bound" if apart else "share one bound"
        out.append(
            f"{cell(q['node'])}: FIFO, depth {q['depth']}, {q['on_full']} when full; its {len(q['messages'])} "
            f"messages {share}: {bound}"
        )
    return out


def _bus_view(model: Model, b: dict[str, Any]) -> dict[str, Any]:
    bus = model.buses[b["name"]]
    ftt = b.get("ftt")
    view: dict[str, Any] = {
        "name": b["name"],
        "protocol": PROTOCOLS.get(b["protocol"], b["protocol"]),
        "rate": rate(b["bitrate"]) + (f", data phase {rate(b['data_bitrate'])}" if b.get("data_bitrate") else ""),
        "description": one_line(_description(bus)),
        "utilization": pct(b["utilization"]),
        "utilization_nominal": pct(b["utilization_nominal"]) if "utilization_nominal" in b else None,
        "utilization_with_tm": pct(b["utilization_with_tm"]) if "utilization_with_tm" in b else None,
        "errors": _sentence(errors_text(b["errors"])) if "errors" in b else None,
        "ethernet": "links" in b,  # an Ethernet bus's row carries its links' loads
        "messages": _messages_table(model, b, ftt is not None),
        "ftt": _ftt_view(model, b) if ftt else None,
        "sync": _sync_view(model, bus, b) if "sync" in b else None,
        "links": _links_view(b) if "links" in b else None,
        "cycle": _cycle_view(b) if "cycle" in b else None,
        "tx_queues": _tx_queues_view(b),
    }
    return view


def _messages_table(model: Model, b: dict[str, Any], ftt: bool) -> dict[str, Any]:
    descriptions = {m["name"]: _description(model.messages.get(m["name"])) for m in b["messages"]}
    with_text = any(descriptions.values())
    headers = [
        "message",
        "id",
        "bytes",
        "period / min. gap (us)",
        "frame bits",
        "load",
        "WCRT (us)",
        "deadline (us)",
        "slack (us)",
        "verdict",
    ]
    align = "lrrrrrrrrl"
    if ftt:
        headers.insert(2, "window")
        align = align[:2] + "l" + align[2:]
    if with_text:
        headers.append("description")
        align += "l"
    rows = []
    for m in b["messages"]:
        if m["kind"] == "on-demand":
            every = "on demand"
        elif m["kind"] == "sporadic":
            every = f"≥ {num(m['interval_us'])}"
        elif m["interval_us"] is not None and m["interval_us"] != m["period_us"]:
            every = f"{num(m['period_us'])} (fastest {num(m['interval_us'])})"  # period_range: load at the fastest
        else:
            every = num(m["period_us"])
        wcrt = num(m["wcrt_us"])
        if m["wcrt_us"] is None and m["schedulable"] is False:
            wcrt = "unbounded"
        row = [
            m["name"],
            _hex(m["id"], m.get("extended", False)),
            str(m["size"]),
            every,
            str(m["frame_bits_worst"]),
            pct(m["utilization"], 2),
            wcrt,
            num(m["deadline_us"]),
            num(m["slack_us"]),
            _verdict(m["schedulable"]),
        ]
        if ftt:
            window = m.get("window", "-")
            row.insert(2, f"sync, id {m['ftt_id']}" if window == "sync" else window)
        if with_text:
            row.append(cell(descriptions[m["name"]]) or "-")
        rows.append(row)
    return _table(headers, align, rows)


def _ftt_view(model: Model, b: dict[str, Any]) -> dict[str, Any]:
    f = b["ftt"]
    srt_rows = []
    for e in f["srt"]:
        period = str(e["period_ec"])
        if e["fastest_period_ec"] != e["period_ec"]:
            period += f" (fastest {e['fastest_period_ec']})"
        obj = model.messages.get(e["name"]) if e["type"] == "message" else model.triggers.get(e["name"])
        srt_rows.append(
            [
                str(e["id"]),
                e["name"],
                e["type"],
                e["producer"] or "-",
                ", ".join(e["targets"]),
                period,
                str(e["init_ec"]),
                _hex(e["can_id"]) if e["can_id"] is not None else "-",
                num(e["c_us"]) if e["type"] == "message" else "-",
                cell(_description(obj)) or "-",
            ]
        )
    view: dict[str, Any] = {
        "ec": num(f["ec_us"]),
        "tm": num(f["tm_us"]),
        "tm_bits": f.get("tm_bits"),
        "overhead": pct(f["tm_overhead"]),
        "lsw": num(f["lsw_us"]),
        "master": f.get("master"),
        "macro_cycle": num(f["macro_cycle_ec"]),
        "macro_cycle_ms": num(f["macro_cycle_ec"] * f["ec_us"] / 1000),
        "srt": _table(
            [
                "FTT id",
                "entry",
                "type",
                "source",
                "destination",
                "period (ECs)",
                "init time (ECs)",
                "CAN id",
                "C (us)",
                "short description",
            ],
            "rllllrrrrl",
            srt_rows,
        ),
        "worst": None,
        "worst_fastest": None,
        "ecs": None,
        "png": None,
    }
    if "worst_ec" not in f:  # the macro-cycle was too long to build: there is no schedule to show
        return view
    lsw = f["lsw_us"]
    view["worst"] = _worst_ec(f["worst_ec"], lsw)
    wf = f["worst_ec_fastest"]
    if wf["sync_us"] != f["worst_ec"]["sync_us"] or wf["fits"] != f["worst_ec"]["fits"]:
        view["worst_fastest"] = _worst_ec(wf, lsw)
    first, last = shown_ecs(f)
    rows = [
        [
            str(ec["index"]) + (" (busiest)" if ec["index"] == f["worst_ec"]["index"] else ""),
            ", ".join(map(str, ec["ids"])) or "-",
            f"0x{ec['ec_schedule']:X}",
            ", ".join(ec["messages"]) or "-",
            ", ".join(ec["triggers"]) or "-",
            num(ec["sync_us"]),
            num(ec["async_us"]),
        ]
        for ec in f["ecs"][first:last]
    ]
    view["ecs"] = _table(
        [
            "EC",
            "ids in the TM",
            "EC-schedule",
            "synchronous messages",
            "triggers",
            "sync window (us)",
            "async window (us)",
        ],
        "lllllrr",
        rows,
    )
    view["ecs_first"], view["ecs_last"] = first, last - 1
    view["ecs_all"] = last - first == len(f["ecs"])
    view["png"] = f"report/{b['name']}_macro_cycle.png"
    return view


def _worst_ec(w: dict[str, Any], lsw_us: float) -> dict[str, Any]:
    return {
        "index": w["index"],
        "sync": num(w["sync_us"]),
        "messages": ", ".join(w["messages"]) or "none",
        "fits": w["fits"],
        "spare": num(lsw_us - w["sync_us"]),
        "over": num(w["sync_us"] - lsw_us),
    }


def _sync_view(model: Model, bus: Bus, b: dict[str, Any]) -> dict[str, Any]:
    s = b["sync"]
    assert bus.canopen is not None
    worst = s["worst_completion_us"]
    limits = [
        {"name": lim["name"], "value": num(lim["limit_us"]), "fits": lim["fits"], "margin": num(lim["margin_us"])}
        for lim in s["limits"]
    ]
    rows = [
        [
            str(c["cycle"]),
            str(c["tpdos"]),
            num(c["completion_us"]) if c["completion_us"] is not None else "never",
            num(c["limit_us"]),
            num(c["slack_us"]),
            _verdict(c["fits"]),
        ]
        for c in s["cycles"]
    ]
    return {
        "period": num(s["period_us"]),
        "window": num(s["window_us"]),
        "read_window": num(s["read_window_us"]),
        "producer": s["producer"],
        "sync_id": _hex(bus.canopen.sync_id),
        "master": master_loop_text(s["master"]),
        "max_tpdos": s["max_tpdos_per_cycle"],
        "worst": num(worst) if worst is not None else None,
        "limits": limits,
        "cycles_analysed": s["cycles_analysed"],
        "cycles": _table(
            ["cycle", "sync TPDOs", "last done (us)", "limit (us)", "slack (us)", "verdict"], "rrrrrl", rows
        ),
        "cycles_cut": s["cycles_analysed"] > len(s["cycles"]),
        "png": f"report/{b['name']}_sync_cycle.png" if s["cycles"] else None,
    }


def _cycle_view(b: dict[str, Any]) -> dict[str, Any]:
    """An EtherCAT segment's cycle: its protocol's view, its slaves as a table."""
    from netcfg.protocols.ethercat.report import cycle_view

    view = cycle_view(b, num)
    head, align, rows = view["slaves"]
    return {**view, "slaves": _table(head, align, rows)}


def _links_view(b: dict[str, Any]) -> dict[str, Any]:
    rows = []
    for ll in b["links"]:
        f_transm = ll["f_transm_hz"]  # the analysis' figure: one definition for the report and the checks
        rows.append(
            [
                f"{ll['from']} -> {ll['to']}",
                ", ".join(ll["messages"]),
                str(ll["senders"]),
                f"{f_transm / 1000:.2f}",
                f"{ll['f_max_per_sender_hz'] / 1000:.2f}",
                "yes" if f_transm < ll["f_max_per_sender_hz"] else "**NO**",
                f"{ll['frames_per_s'] / 1000:.2f}",
                pct(ll["utilization"], 2),
                _verdict(ll["ok"]),
            ]
        )
    return {
        "min_frame": num(b["min_frame_us"]),
        "f_max": f"{b['f_max_hz'] / 1000:.2f}",
        "table": _table(
            [
                "link",
                "messages",
                "senders n",
                "f_transm (kHz)",
                "f_max/n (kHz)",
                "f_transm < f_max/n",
                "frames (kHz)",
                "load",
                "verdict",
            ],
            "llrrrlrrl",
            rows,
        ),
    }


def _flows_view(flows: list[dict[str, Any]], model: Model) -> dict[str, Any]:
    def span(d: dict[str, Any] | None, lo: str = "latency_min_us", hi: str = "latency_max_us") -> str:
        if not d or lo not in d:
            return "-"
        return f"{num(d[lo])} .. {num(d[hi])}" if d[hi] is not None else f"{num(d[lo])} .. unbounded"

    rows, details = [], []
    for f in flows:
        sync = f.get("synchronised")
        unsync = f["unsynchronised"]
        rows.append(
            [
                f["name"],
                f["mode"],
                span(sync),
                span(unsync),
                num(f["jitter_us"]),
                num(f["deadline_us"]),
                _verdict(f["meets_deadline"]),
            ]
        )
        chain = " -> ".join(" + ".join(s) if isinstance(s, list) else s for s in f["steps"])
        deliveries = []
        if sync and "delivery_min_us" in sync:
            deliveries.append(f"synchronised {span(sync, 'delivery_min_us', 'delivery_max_us')} us")
        if "delivery_min_us" in unsync:
            deliveries.append(f"unsynchronised {span(unsync, 'delivery_min_us', 'delivery_max_us')} us")
        details.append(
            {
                "name": f["name"],
                "description": one_line(_description(model.flows.get(f["name"]))),
                "chain": chain,
                "delivery": ", ".join(deliveries),
            }
        )
    table = _table(
        ["flow", "mode", "synchronised (us)", "unsynchronised (us)", "jitter (us)", "deadline (us)", "verdict"],
        "llrrrrl",
        rows,
    )
    return {"table": table, "details": details}
