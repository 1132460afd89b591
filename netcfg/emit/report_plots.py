"""The build report's plots (report/*.png): the FTT-CAN macro-cycle and the CANopen SYNC cycle, drawn with
matplotlib's Agg canvas at a fixed geometry, in fixed colours and with the library's default style, so generated/
stays byte-identical whatever a user's matplotlibrc says. netcfg.emit.report_md decides which to draw.
"""

from __future__ import annotations

import io
from typing import TYPE_CHECKING, Any

from netcfg.model import Bus, Model
from netcfg.report_text import num
from netcfg.templating import environment

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


def shown_ecs(ftt: dict[str, Any]) -> tuple[int, int]:
    """ECs [first, last) that the plot and the EC table show: the whole macro-cycle when it has at most
    MAX_SHOWN_ECS, else MAX_SHOWN_ECS consecutive ones with the busiest EC in the middle."""
    n = len(ftt.get("ecs", []))
    if n <= MAX_SHOWN_ECS:
        return 0, n
    first = min(max(0, ftt["worst_ec"]["index"] - MAX_SHOWN_ECS // 2), n - MAX_SHOWN_ECS)
    return first, first + MAX_SHOWN_ECS


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


def draw(model: Model, plots: dict[str, tuple[str, dict[str, Any]]]) -> dict[str, bytes]:
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
