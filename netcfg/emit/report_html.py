"""report.html: the build report as one self-contained page, readable offline.

The text is report.md's (converted with Python-Markdown, raw HTML in it disabled so that a description from the
spec cannot inject markup); its PNG plots are embedded as data URIs; and each bus gets a timeline of one
hyperperiod as inline SVG: every periodic message's releases and, after each, the window up to its analysed
worst-case completion. No script, no font, no stylesheet from the network: the file is all there is.
"""

from __future__ import annotations

import base64
import math
import re
from typing import Any

from netcfg.emit import report_md
from netcfg.model import Model
from netcfg.report_text import num
from netcfg.templating import environment, render

# Timeline geometry, fixed so that generated/ stays byte-identical.
WIDTH = 1000  # px of the time axis
LABEL = 170  # px for the message names left of it
ROW = 16  # px per message
MAX_ROWS = 48  # beyond that, the highest-priority messages are shown and the caption says how many are not
MAX_BARS = 3000  # releases drawn per bus; a longer hyperperiod is shown from its start, as the caption says
TICKS = 10


def warm_up() -> None:
    """What a report needs before there is a model: imported by a build's worker while the spec is analysed."""
    import markdown.extensions.tables  # noqa: F401

    report_md.warm_up()
    environment().get_template("report.html.j2")


def emit(model: Model, report: dict[str, Any]) -> dict[str, bytes]:
    """report.md and its PNGs (report_md), and report.html made from the same text and plots."""
    files = report_md.emit(model, report)
    files["report.html"] = page(model, report, files)
    return files


def page(model: Model, report: dict[str, Any], files: dict[str, bytes]) -> bytes:
    import markdown
    from markdown.extensions.tables import TableExtension

    # the extension itself, not its name: a name is looked up among every installed package's entry points (30 ms
    # of importlib.metadata in a build's worker), where another package could register a 'tables' of its own
    md = markdown.Markdown(extensions=[TableExtension()], output_format="html")
    md.preprocessors.deregister("html_block")  # raw HTML in the Markdown is shown as text, never interpreted
    md.inlinePatterns.deregister("html")
    body = md.convert(files["report.md"].decode("utf-8"))

    def inline(match: re.Match[str]) -> str:
        data = files.get(match.group(1))
        if data is None:
            return match.group(0)
        return f'src="data:image/png;base64,{base64.b64encode(data).decode("ascii")}"'

    body = re.sub(r'src="(report/[A-Za-z0-9_.-]+\.png)"', inline, body)
    system = str(report.get("system") or model.system)
    timelines = [t for t in (_timeline(model, b) for b in report["buses"]) if t is not None]
    return render("report.html.j2", title=_html(f"{system}: network report"), body=body, timelines=timelines)


def _html(text: object) -> str:
    return str(text).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")


def _timeline(model: Model, b: dict[str, Any]) -> dict[str, Any] | None:
    """One hyperperiod of a bus: the periodic messages' releases and worst-case completion windows."""
    rows = []
    for m in b["messages"]:
        msg = model.messages.get(m["name"])
        period = msg.period_ns if msg is not None else (round(m["period_us"] * 1000) if m["period_us"] else None)
        if not period or m["kind"] != "periodic":
            continue
        offset = (msg.offset_ns or 0) if msg is not None else 0
        rows.append((m["name"], period, offset % period, m["wcrt_us"], m["schedulable"]))
    if not rows:
        return None
    hidden = max(0, len(rows) - MAX_ROWS)
    rows = rows[:MAX_ROWS]
    hyper = math.lcm(*(r[1] for r in rows))
    per_hyper = sum(hyper // r[1] for r in rows)
    shown = hyper if per_hyper <= MAX_BARS else max(max(r[1] for r in rows), hyper * MAX_BARS // per_hyper)
    scale = WIDTH / shown
    bars = []
    names = []
    for i, (name, period, offset, wcrt_us, ok) in enumerate(rows):
        y = i * ROW
        names.append({"y": y + ROW - 4, "text": _html(name)})
        window = None if wcrt_us is None else round(wcrt_us * 1000)
        for k in range(-(-(shown - offset) // period)):
            t = offset + k * period
            end = shown if window is None else min(shown, t + window)
            bars.append({
                "x": f"{LABEL + t * scale:.2f}",
                "y": y + 2,
                "w": f"{max(0.8, (end - t) * scale):.2f}",
                "cls": "late" if ok is False or window is None else "window",
            })
    step = shown / TICKS
    # labels in ms, as the page says; the last one ends at the axis' end rather than past the picture's edge
    ticks = [
        {
            "x": f"{LABEL + k * step * scale:.2f}",
            "label": num(round(k * step / 1e6, 3)),
            "anchor": "end" if k == TICKS else "middle",
        }
        for k in range(TICKS + 1)
    ]
    caption = f"hyperperiod {num(hyper / 1e6)} ms, {len(rows)} periodic messages"
    if shown < hyper:
        caption += f"; the first {num(shown / 1e6)} ms are shown ({MAX_BARS} releases at most)"
    if hidden:
        caption += f"; {hidden} more messages of lower priority are not drawn"
    height = len(rows) * ROW
    return {
        "bus": _html(b["name"]),
        "caption": caption,
        "width": LABEL + WIDTH + 10,
        "height": height + 30,
        "axis_y": height + 4,
        "names": names,
        "bars": bars,
        "ticks": ticks,
    }
