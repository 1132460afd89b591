"""report.html: one self-contained page (no network), the report with its plots, a timeline per bus, the flows;
looked at as a user would, in headless Chromium where Debian's package is installed."""

from __future__ import annotations

import copy
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from netcfg.check import analyse_spec
from netcfg.emit.report_html import emit
from tests.conftest import SPECS, load_spec

BUSIEST_EC = (0xFF, 0xF2, 0xB3)  # report_md.BUSIEST_COLOUR: only the FTT-CAN macro-cycle PNG uses it
TIMELINE_FILL = (0x9F, 0xC5, 0xE8)  # the timeline's window bars (and the PNGs' synchronous windows)


def html_of(spec: Path) -> str:
    model, report = analyse_spec(spec)
    assert model is not None and report["ok"], report["errors"]
    return emit(model, report)["report.html"].decode("utf-8")


@pytest.fixture(scope="module")
def cambada_html() -> str:
    return html_of(SPECS / "cambada.yaml")


def test_the_page_needs_nothing_from_outside(cambada_html: str) -> None:
    """Every image is a data URI; no script, stylesheet, font or frame is loaded from anywhere."""
    assert cambada_html.startswith("<!DOCTYPE html>")
    sources = re.findall(r'(?:src|href)="([^"]*)"', cambada_html)
    assert sources and all(s.startswith(("data:image/png;base64,", "#")) for s in sources), sources
    for forbidden in ("<script", "<link", "<iframe", "@import", "url("):
        assert forbidden not in cambada_html
    # the only URL is the SVG namespace, which is a name, not a download
    assert set(re.findall(r"https?://[^\"' ]+", cambada_html)) == {"http://www.w3.org/2000/svg"}


def test_the_page_has_the_report_its_plots_a_timeline_per_bus_and_the_flows(cambada_html: str) -> None:
    """CAMBADA: one FTT-CAN bus with the Table 2 SRT plot, and the Motion and Odometry flows of Table 3."""
    assert cambada_html.count("<img") == 1 + cambada_html.count("sync_cycle")  # the macro-cycle PNG
    assert cambada_html.count('<svg class="timeline"') == 1
    assert "Bus lowlevel" in cambada_html
    for flow in ("motion", "odometry"):
        assert re.search(rf"<td[^>]*>{flow}</td>", cambada_html), flow
    # the periodic messages' periods (Table 1): 2, 6 and 10 ECs of 5 ms = 10, 30 and 50 ms, and battery_status's
    # 1000 ms: lcm(10, 30, 50, 1000) = 3000 ms
    assert "hyperperiod 3,000 ms, 9 periodic messages" in cambada_html


def test_descriptions_cannot_inject_markup(tmp_path: Path) -> None:
    data: dict[str, Any] = copy.deepcopy(load_spec("cambada.yaml"))
    data["description"] = "<script>alert(1)</script> & <img src=x onerror=alert(2)>"
    spec = tmp_path / "cambada.yaml"
    import yaml

    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    html = html_of(spec)
    assert "<script>" not in html and "<img src=x" not in html
    assert "&lt;script&gt;" in html


def test_the_same_spec_gives_the_same_bytes(cambada_html: str) -> None:
    assert html_of(SPECS / "cambada.yaml") == cambada_html


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


def test_chromium_renders_it_with_the_plots_loaded(cambada_html: str, tmp_path: Path) -> None:
    """A screenshot of the page, tall enough to hold the macro-cycle plot and the timeline: not blank, and the
    colour only the embedded PNG has is on screen, so the plot was decoded and drawn, offline."""
    browser = _chromium()
    if browser is None:
        pytest.skip("Chromium is not installed (Debian: apt-get install chromium)")
    page = tmp_path / "report.html"
    page.write_text(cambada_html)
    shot = tmp_path / "shot.png"
    proc = subprocess.run(
        [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--no-first-run",
         "--disable-background-networking", "--user-data-dir=" + str(tmp_path / "profile"),
         "--window-size=1300,9000", f"--screenshot={shot}", page.as_uri()],
        capture_output=True, text=True, timeout=120,
    )
    assert shot.is_file(), proc.stderr[-2000:]
    import matplotlib.image

    pixels = (matplotlib.image.imread(str(shot))[..., :3] * 255).round().astype(np.uint8)
    flat = pixels.reshape(-1, 3)
    not_white = np.any(flat < 250, axis=1).mean()
    assert not_white > 0.02, f"the screenshot is nearly blank ({not_white:.2%} not white)"
    colours = {tuple(c) for c in np.unique(flat, axis=0)}
    assert len(colours) > 50
    assert BUSIEST_EC in colours, "the macro-cycle PNG did not load"
    assert TIMELINE_FILL in colours


def test_the_timeline_axis_is_in_milliseconds_and_ends_inside_the_picture(cambada_html: str) -> None:
    """The page says 'Time in milliseconds': the axis' last label is the span its caption states in ms (the whole
    hyperperiod, or the first part shown), and it is anchored at its end so that it is not cut off at the edge."""
    svg = re.search(r'<svg class="timeline".*?</svg>', cambada_html, re.S)
    assert svg is not None
    caption = re.search(r'<p class="caption">hyperperiod ([\d,.]+) ms[^<]*?(?:the first ([\d,.]+) ms are shown)?',
                        cambada_html)
    assert caption is not None
    span = caption.group(2) or caption.group(1)
    labels = re.findall(r'<text x="[\d.]+" y="\d+" text-anchor="(\w+)">([\d,.]+)</text>', svg.group(0))
    assert labels[0] == ("middle", "0")
    assert labels[-1] == ("end", span)
