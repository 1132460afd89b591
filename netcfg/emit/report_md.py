"""report.md and report/*.png: the build report an engineer reads, beside the artifacts it explains.

The numbers come from the analysis report (and names, roles and descriptions from the Model); nothing here
re-derives timing. The Python side formats a view, templates/report.md.j2 lays it out, and two plots are
drawn with matplotlib's Agg canvas: the FTT-CAN macro-cycle and the CANopen SYNC cycle.
"""

from __future__ import annotations

import io
from pathlib import PurePath
from typing import TYPE_CHECKING, Any

from netcfg.model import Bus, Described, Model, Node
from netcfg.report_text import errors_text, master_loop_text, num, rate
from netcfg.templating import environment, render

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

# Plot geometry, fixed so that generated/ stays byte-identical (pixels = inches x DPI).
DPI = 100
FTT_WIDTH_IN = 16.0
SYNC_WIDTH_IN = 12.0
SYNC_HEIGHT_IN = 3.8
MAX_SHOWN_ECS = 30  # a longer macro-cycle is shown as 30 consecutive ECs around the busiest one
MAX_PLOT_ENTRIES = 64  # SRT rows in the macro-cycle plot; beyond that it would be taller than a screen

PROTOCOLS = {
    "can": "CAN",
    "can-fd": "CAN FD",
    "canopen": "CANopen",
    "ftt-can": "FTT-CAN",
    "ethernet-udp": "switched Ethernet, UDP",
}
# matplotlib's tab10 colours, spelled out so that a user's style cannot change them
PALETTE = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)
TM_COLOUR, ASYNC_COLOUR, SYNC_COLOUR, BUSIEST_COLOUR = "#404040", "#e6e6e6", "#9fc5e8", "#fff2b3"
LSW_COLOUR, LATE_COLOUR = "#1f4e79", "#c00000"


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
        files.update(_draw(model, plots))
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
    """What the live master does when a CANopen slave is lost, sends an EMCY or reboots (spec: on_loss, ...)."""
    if node.role == "master" or node.node_id is None or not any(model.buses[b].canopen for b in node.buses):
        return "-"
    if node.heartbeat_timeout_ns:
        heard = f"lost after {node.heartbeat_timeout_ns / 1e6:g} ms without heartbeat: {node.on_loss}"
    else:
        heard = "no heartbeat consumed"
    return f"{heard}; EMCY: {node.on_emcy}; reboot: {node.on_reboot}"


def _tx_queue(model: Model, node: Node) -> str:
    if all(model.buses[b].protocol == "ethernet-udp" for b in node.buses):
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
        "ethernet": b["protocol"] == "ethernet-udp",
        "messages": _messages_table(model, b, ftt is not None),
        "ftt": _ftt_view(model, b) if ftt else None,
        "sync": _sync_view(model, bus, b) if "sync" in b else None,
        "links": _links_view(b) if "links" in b else None,
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


def shown_ecs(ftt: dict[str, Any]) -> tuple[int, int]:
    """ECs [first, last) that the plot and the EC table show: the whole macro-cycle when it has at most
    MAX_SHOWN_ECS, else MAX_SHOWN_ECS consecutive ones with the busiest EC in the middle."""
    n = len(ftt.get("ecs", []))
    if n <= MAX_SHOWN_ECS:
        return 0, n
    first = min(max(0, ftt["worst_ec"]["index"] - MAX_SHOWN_ECS // 2), n - MAX_SHOWN_ECS)
    return first, first + MAX_SHOWN_ECS


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


# ---------------------------------------------------------------------------------------------------------------
# plots


def warm_up() -> None:
    """Import what drawing needs (see report_html.warm_up).

    Only a build's worker calls this: a process that draws the report and exits. There, matplotlib's artist
    classes skip writing the property list into their set() docstrings (matplotlib.artist.kwdoc, about a quarter
    of matplotlib's import), which nothing in that process reads; the figures are the same bytes."""
    import matplotlib.artist

    matplotlib.artist.kwdoc = _no_property_list
    import matplotlib.style
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: F401
    from matplotlib.figure import Figure  # noqa: F401
    from matplotlib.lines import Line2D  # noqa: F401
    from matplotlib.patches import Patch  # noqa: F401

    environment().get_template("report.md.j2")


def _no_property_list(artist: object) -> str:
    return ""


def _draw(model: Model, plots: dict[str, tuple[str, dict[str, Any]]]) -> dict[str, bytes]:
    # imported here: `netcfg check` never draws, and matplotlib takes longer to import than a check takes
    import matplotlib.style

    out = {}
    # the library defaults, whatever a user's matplotlibrc says (restored on exit), and a bundled font
    rc = {"font.family": "DejaVu Sans", "font.size": 9.0, "axes.titlesize": 10.0}
    with matplotlib.style.context(["default", rc]):
        for path, (kind, b) in plots.items():
            fig = _macro_cycle_figure(b) if kind == "ftt" else _sync_cycle_figure(model.buses[b["name"]], b)
            out[path] = _png(fig)
    return out


def _figure(width_px: int, height_px: int) -> Figure:
    # a Figure with its own Agg canvas: no pyplot, no global backend switch
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_px / DPI, height_px / DPI), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _png(fig: Figure) -> bytes:
    buf = io.BytesIO()
    # no "Software" tEXt chunk (it names the matplotlib version) and no bbox="tight": the size stays as set
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    return buf.getvalue()


def _axes(fig: Figure, left: float, top: float, width: float, height: float, fig_w: float, fig_h: float) -> Axes:
    """Axes placed in pixels from the top-left corner, so the layout does not depend on text extents."""
    return fig.add_axes((left / fig_w, 1 - (top + height) / fig_h, width / fig_w, height / fig_h))


def _label(text: str, limit: int = 28) -> str:
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _macro_cycle_figure(b: dict[str, Any]) -> Figure:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    f = b["ftt"]
    ec, tm, lsw = f["ec_us"], f["tm_us"], f["lsw_us"]
    ecs = f["ecs"]
    first, last = shown_ecs(f)
    entries = f["srt"][:MAX_PLOT_ENTRIES]
    colour: dict[str, str] = {}
    for e in entries:
        if e["type"] == "message":
            colour[e["name"]] = PALETTE[len(colour) % len(PALETTE)]
    c_us = {e["name"]: e["c_us"] for e in f["srt"]}
    row_of = {e["name"]: 2 + i for i, e in enumerate(entries)}
    labels = ["TM", "windows"] + [_label(f"{e['id']}  {e['name']}") for e in entries]
    busiest = f["worst_ec"]["index"]

    row_px, left, right = 22, 230, 30
    top_h = row_px * len(labels)
    zoom_h = 70
    heights = (70, top_h, 85, zoom_h, 55)  # title+legend, timeline, its axis + zoom title, zoom, its axis
    w, h = round(FTT_WIDTH_IN * DPI), sum(heights)
    fig = _figure(w, h)
    title = f"bus {b['name']}: FTT-CAN macro-cycle of {f['macro_cycle_ec']} ECs"
    title += (
        "" if last - first == len(ecs) else f", ECs {first}-{last - 1} shown (the busiest, {busiest}, in the middle)"
    )
    fig.text(left / w, 1 - 18 / h, title, fontsize=11, fontweight="bold", va="center")
    handles = [
        Patch(facecolor=TM_COLOUR, label=f"trigger message ({num(tm)} us)"),
        Patch(facecolor=ASYNC_COLOUR, label="asynchronous window"),
        Patch(facecolor=SYNC_COLOUR, label=f"synchronous window (LSW {num(lsw)} us, dashed: its earliest start)"),
        Patch(facecolor=BUSIEST_COLOUR, label=f"busiest EC ({busiest})"),
        Line2D([], [], color="black", marker="v", linestyle="", label="trigger announced in the TM"),
    ]
    fig.legend(handles=handles, loc="center left", bbox_to_anchor=(left / w, 1 - 48 / h), ncol=5, frameon=False)

    ax = _axes(fig, left, heights[0], w - left - right, top_h, w, h)
    n = len(labels)
    ax.set_ylim(n - 0.5, -0.5)
    ax.set_xlim(first, last)
    ax.set_yticks(range(n), labels, fontsize=8)
    if first <= busiest < last:
        ax.axvspan(busiest, busiest + 1, color=BUSIEST_COLOUR, zorder=0)
    for k in range(first, last):
        slot = ecs[k]
        sync, t0 = slot["sync_us"], float(k)
        ax.broken_barh([(t0, tm / ec)], (-0.35, 0.7), facecolors=TM_COLOUR)
        ax.broken_barh([(t0 + tm / ec, slot["async_us"] / ec)], (0.65, 0.7), facecolors=ASYNC_COLOUR)
        if sync:
            ax.broken_barh([(t0 + (ec - sync) / ec, sync / ec)], (0.65, 0.7), facecolors=SYNC_COLOUR)
        ax.plot([t0 + (ec - lsw) / ec] * 2, [0.6, 1.4], color=LSW_COLOUR, linestyle="--", linewidth=0.8)
        # the window's frames go out back to back in the report's (identifier) order
        start = ec - sync
        for name in slot["messages"]:
            if name in row_of:
                r = row_of[name]
                ax.broken_barh([(t0 + start / ec, c_us[name] / ec)], (r - 0.35, 0.7), facecolors=colour[name])
            start += c_us[name]
        for name in slot["triggers"]:
            if name in row_of:
                ax.plot([t0 + tm / ec], [row_of[name]], marker="v", color="black", markersize=5)
    for k in range(first, last + 1):
        ax.axvline(k, color="#999999", linewidth=0.5, zorder=0.5)
    ax.set_xticks([k + 0.5 for k in range(first, last)], [str(k) for k in range(first, last)], fontsize=8)
    ax.tick_params(axis="x", length=0)
    ax.set_xlabel(f"elementary cycle ({num(ec)} us each)")
    ax.grid(axis="y", color="#eeeeee", linewidth=0.5)
    ax.set_axisbelow(True)

    # the busiest EC, to scale, with its frames named
    slot = ecs[busiest]
    top = heights[0] + top_h + heights[2]
    fig.text(
        left / w,
        1 - (top - 14) / h,
        f"EC {busiest}, the busiest: {num(slot['sync_us'])} us of synchronous traffic in an LSW of {num(lsw)} us",
        fontsize=10,
        fontweight="bold",
        va="center",
    )
    zx = _axes(fig, left, top, w - left - right, zoom_h, w, h)
    zx.set_xlim(0, ec)
    zx.set_ylim(-0.5, 1.0)
    zx.set_yticks([0], [f"EC {busiest}"], fontsize=8)
    zx.broken_barh([(0, tm)], (-0.3, 0.6), facecolors=TM_COLOUR)
    zx.text(tm / 2, 0, "TM", color="white", ha="center", va="center", fontsize=8)
    zx.broken_barh([(tm, slot["async_us"])], (-0.3, 0.6), facecolors=ASYNC_COLOUR)
    zx.text(tm + slot["async_us"] / 2, 0, f"asynchronous window {num(slot['async_us'])} us", ha="center", va="center")
    start = ec - slot["sync_us"]
    for name in slot["messages"]:
        zx.broken_barh([(start, c_us[name])], (-0.3, 0.6), facecolors=colour.get(name, PALETTE[0]), edgecolor="white")
        ident = next(e["id"] for e in f["srt"] if e["name"] == name)
        zx.text(start + c_us[name] / 2, 0, str(ident), color="white", ha="center", va="center", fontsize=8)
        start += c_us[name]
    zx.axvline(ec - lsw, color=LSW_COLOUR, linestyle="--", linewidth=1)
    zx.text(
        ec - lsw + ec * 0.004,
        0.55,
        f"earliest start of the synchronous window (LSW {num(lsw)} us)",
        va="center",
        fontsize=8,
        color=LSW_COLOUR,
    )
    if slot["triggers"]:
        ids = [str(next(e["id"] for e in f["srt"] if e["name"] == t)) for t in slot["triggers"]]
        zx.plot([tm], [0.55], marker="v", color="black", markersize=6)
        zx.text(tm + ec * 0.005, 0.55, "triggers " + ", ".join(ids), va="center", fontsize=8)
    zx.set_xlabel("time from the start of the EC (us); frames labelled with their FTT id, worst-case lengths")
    return fig


def _sync_cycle_figure(bus: Bus, b: dict[str, Any]) -> Figure:
    from matplotlib.patches import Patch

    s = b["sync"]
    period = s["period_us"]
    finished = [c for c in s["cycles"] if c["completion_us"] is not None]
    worst = max(finished, key=lambda c: (c["completion_us"], -c["cycle"])) if finished else None

    w, h = round(SYNC_WIDTH_IN * DPI), round(SYNC_HEIGHT_IN * DPI)
    left, right, top, bottom = 200, 30, 95, 50
    fig = _figure(w, h)
    fig.text(
        left / w,
        1 - 18 / h,
        f"bus {b['name']}: CANopen SYNC cycle of {num(period)} us, SYNC from {s['producer']}",
        fontsize=11,
        fontweight="bold",
        va="center",
    )
    ax = _axes(fig, left, top, w - left - right, h - top - bottom, w, h)
    # bottom to top: the cycle, the windows, then what the bus does after SYNC
    rows: list[tuple[str, float, str]] = [("communication cycle (0x1006)", period, "#d9d9d9")]
    if s["read_window_us"] is not None:
        rows.append(("master's read window", s["read_window_us"], "#b6d7a8"))
    if s["window_us"] is not None:
        rows.append(("synchronous window (0x1007)", s["window_us"], SYNC_COLOUR))
    y_bus = len(rows)
    labels = [r[0] for r in rows] + ["bus, worst case" + (f" (cycle {worst['cycle']})" if worst else "")]
    for y, (_, length, col) in enumerate(rows):
        ax.broken_barh([(0, length)], (y - 0.3, 0.6), facecolors=col)
        ax.text(length - period * 0.005, y, f"{num(length)} us", va="center", ha="right")

    handles = []
    if worst is not None:
        # W = blocking + SYNC + the drives' tx_delay + the cycle's synchronous TPDOs + other frames released
        # meanwhile (canopen_sync)
        done = worst["completion_us"]
        blocking, sync_tx, tpdos = worst["blocking_us"], worst["sync_us"], worst["tpdos_us"]
        delay = worst.get("tx_delay_us", 0.0)
        parts = [
            ("a frame already on the bus", blocking, "#bfbfbf"),
            ("SYNC", sync_tx, TM_COLOUR),
            ("the drives' tx_delay (the bus may idle)", delay, "#fff2cc"),
            (f"the {worst['tpdos']} synchronous TPDOs", tpdos, PALETTE[0]),
            ("other frames released meanwhile", round(done - blocking - sync_tx - delay - tpdos, 3), PALETTE[1]),
        ]
        start = 0.0
        for name, length, col in parts:
            if length > 0:
                ax.broken_barh([(start, length)], (y_bus - 0.3, 0.6), facecolors=col)
                handles.append(Patch(facecolor=col, label=f"{name}: {num(length)} us"))
                start += length
        ax.axvline(done, color=LATE_COLOUR, linestyle="--", linewidth=1)
        ax.text(
            done, y_bus + 0.5, f" last synchronous TPDO done {num(done)} us after SYNC", color=LATE_COLOUR, va="center"
        )
    for t, align in ((0, "left"), (period, "right")):
        ax.axvline(t, color="black", linewidth=1.2)
        ax.text(t, -0.75, " SYNC " if align == "left" else "next SYNC ", ha=align, va="center", fontweight="bold")
    ax.set_xlim(-period * 0.01, period * 1.01)
    ax.set_ylim(-1.1, y_bus + 0.8)
    ax.set_yticks(range(len(labels)), labels, fontsize=8)
    ax.set_xlabel("time after SYNC is queued (us)")
    ax.xaxis.set_major_formatter(lambda x, _pos: f"{x:,.0f}")
    if handles:
        fig.legend(handles=handles, loc="center left", bbox_to_anchor=(left / w, 1 - 58 / h), ncol=2, frameon=False)
    return fig
