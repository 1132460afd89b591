"""report.md and report/*.png (netcfg build, item 5): the seeds' key figures in the report an engineer reads,
valid and reproducible PNGs, and free text from the spec that cannot break a Markdown table."""

from __future__ import annotations

import hashlib
import io
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import ROOT, SPECS, load_spec
from test_seeds import TABLE_2

from netcfg.build import build
from netcfg.check import analyse_spec
from netcfg.emit import report_md
from netcfg.model import Model

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"  # ISO/IEC 15948, section 5.2
SEEDS = ("cambada", "allex2", "ntua_sahr")
# one macro-cycle plot per FTT-CAN bus, one SYNC-cycle plot per CANopen bus, nothing for Ethernet (the specs' buses)
PLOTS = {
    "cambada": {"report/lowlevel_macro_cycle.png"},
    "allex2": {"report/can0_sync_cycle.png"},
    "ntua_sahr": set(),
}


@pytest.fixture(scope="module")
def seeds() -> dict[str, tuple[Model, dict[str, Any], dict[str, bytes]]]:
    out = {}
    for name in SEEDS:
        model, report = analyse_spec(SPECS / f"{name}.yaml")
        assert model is not None and report["ok"], report["errors"]
        out[name] = (model, report, report_md.emit(model, report))
    return out


def markdown(files: dict[str, bytes]) -> str:
    return files["report.md"].decode("utf-8")


def split_row(line: str) -> list[str]:
    """Cells of a GFM table row: '|' separates cells unless a backslash escapes it."""
    assert line.startswith("|") and line.endswith("|"), line
    cells, cur, i = [], "", 1
    while i < len(line):
        ch = line[i]
        if ch == "\\" and i + 1 < len(line):
            cur += line[i : i + 2]
            i += 2
            continue
        if ch == "|":
            cells.append(cur.strip())
            cur = ""
        else:
            cur += ch
        i += 1
    return cells


def tables(md: str) -> list[list[list[str]]]:
    """Every table of the document as rows of cells, header first (the rule line dropped)."""
    out: list[list[list[str]]] = []
    block: list[str] = []
    for line in [*md.splitlines(), ""]:
        if line.startswith("|"):
            block.append(line)
        elif block:
            out.append([split_row(block[0]), *(split_row(x) for x in block[2:])])
            block = []
    return out


def table(md: str, first_header: str) -> list[list[str]]:
    return next(t for t in tables(md) if t[0][0] == first_header)


def row(rows: list[list[str]], first_cell: str) -> dict[str, str]:
    return next(dict(zip(rows[0], r)) for r in rows[1:] if r[0] == first_cell)


def assert_well_formed(md: str) -> None:
    for t in tables(md):
        assert all(len(r) == len(t[0]) for r in t), t[0]


# ---------------------------------------------------------------------------------------------------------------
# the seeds' figures


def test_cambada_report_has_the_papers_figures(seeds: dict[str, Any]) -> None:
    """Seed 002, section 5.2: load "close to 27%" (hand calculation 0.27009 in test_seeds), TM overhead "lower
    than 8.4% (420us/5ms)"; Table 2's periods and init times; the busiest EC is 24, where messages 1-3 (even
    ECs from 2), 4-5 (ECs 4, 14, 24) and 6-7 (multiples of 6) meet: 3 x 340 + 500 + 380 + 500 + 380 = 2780 us
    of the 3000 us LSW, 220 us to spare."""
    md = markdown(seeds["cambada"][2])
    assert "Worst-case utilisation: **27.0 %**" in md
    assert "Trigger message (TM): 420 us" in md and "an overhead of 8.4 % of every EC" in md
    srt = table(md, "FTT id")
    assert srt[0][:7] == ["FTT id", "entry", "type", "source", "destination", "period (ECs)", "init time (ECs)"]
    # "2 (fastest 1)": Table 2 writes the encoders' period as "2 (0-4)"; the leading number is the period
    found = {int(r[0]): (int(r[5].split()[0]), int(r[6])) for r in srt[1:]}
    assert found == TABLE_2
    assert row(srt, "6")["source"] == "gateway" and row(srt, "6")["destination"] == "holonomic"  # Table 2, id 6
    assert "EC 24 needs 2,780 us of synchronous window" in md and "with 220 us to spare" in md
    ecs = table(md, "EC")
    assert len(ecs) - 1 == 30  # the whole macro-cycle: LCM(6, 2, 10, 1) ECs
    assert row(ecs, "24 (busiest)")["sync window (us)"] == "2,780"
    assert "![Macro-cycle of bus lowlevel](report/lowlevel_macro_cycle.png)" in md


def test_cambada_message_rows(seeds: dict[str, Any]) -> None:
    """Table 1, M3.1: 3 bytes, 5-20 ms (the spec's period 2 EC = 10 ms, fastest 1 EC = 5 ms); worst-case frame
    of 55 + 10 x 3 = 85 bits (the stuffing formula of test_seeds' load calculation), 340 us / 5 ms = 6.80 %."""
    rows = table(markdown(seeds["cambada"][2]), "message")
    enc = row(rows, "encoder1")
    assert enc["bytes"] == "3" and enc["frame bits"] == "85" and enc["load"] == "6.80 %"
    assert enc["period / min. gap (us)"] == "10,000 (fastest 5,000)"
    assert enc["window"] == "sync, id 1" and enc["verdict"] == "ok"
    assert row(rows, "kick")["period / min. gap (us)"] == "≥ 1,000,000"  # M7: min_interarrival 1000 ms


def test_allex2_report_has_the_sync_cycle(seeds: dict[str, Any]) -> None:
    """Seed 000: 12 TxPDOs within the 10 ms read window; hand calculation (test_seeds, with the drives'
    heartbeats): the last is done 3340 us after SYNC, 10,000 - 3,340 = 6,660 us before the windows close and
    20,000 - 3,340 = 16,660 us before the next SYNC."""
    md = markdown(seeds["allex2"][2])
    assert "Up to 12 synchronous TPDOs answer one SYNC" in md
    assert "the last of them is done **3,340 us after SYNC**" in md
    assert "- within the master's read window of 10,000 us, 6,660 us to spare" in md
    assert "- within the synchronous window (0x1007) of 10,000 us, 6,660 us to spare" in md
    assert "- within the communication cycle (0x1006) of 20,000 us, 16,660 us to spare" in md
    cycles = table(md, "cycle")
    assert cycles[1] == ["0", "12", "3,340", "10,000", "6,660", "ok"]
    assert "![SYNC cycle of bus can0](report/can0_sync_cycle.png)" in md
    msgs = table(md, "message")
    assert row(msgs, "hip_l_interp")["period / min. gap (us)"] == "on demand"  # RxPDO2: start and stop only


def test_sahr_report_has_the_pc_link(seeds: dict[str, Any]) -> None:
    """Seed 001, section 6.2.2.12: two MCUs at 15 kHz share the switch -> PC link: 30,000 frames/s x 6.72 us =
    20.16 % of it, and 15 kHz < f_max / 2 = 148.81 / 2 = 74.40 kHz."""
    md = markdown(seeds["ntua_sahr"][2])
    assert "A minimum frame takes 6.72 us, so a link carries at most f_max = 148.81 kHz" in md
    pc = row(table(md, "link"), "sw1 -> pc")
    assert pc["senders n"] == "2" and pc["f_transm (kHz)"] == "15.00" and pc["f_max/n (kHz)"] == "74.40"
    assert pc["f_transm < f_max/n"] == "yes" and pc["frames (kHz)"] == "30.00" and pc["load"] == "20.16 %"
    assert "Worst-case utilisation: **20.2 %** of the busiest link" in md
    hip = row(table(md, "message"), "hip_encoder")
    assert hip["WCRT (us)"] == "20.16"  # eq. 6.3 with store-and-forward, hand calculation in test_seeds


def test_flows_show_both_latency_ranges(seeds: dict[str, Any]) -> None:
    """Every flow of the spec has a row; CAMBADA's are synchronised (an FTT-CAN schedule sets the offsets, Table 3)
    and show the unsynchronised range beside it, SAHR's is unsynchronised only."""
    flows = table(markdown(seeds["cambada"][2]), "flow")
    assert [r[0] for r in flows[1:]] == ["motion", "odometry", "odometry_integration"]
    motion = row(flows, "motion")
    assert motion["mode"] == "synchronised"
    # the report renders the analysis' figures (test_seeds.py derives them): the same numbers, grouped
    flow = next(f for f in seeds["cambada"][1]["flows"] if f["name"] == "motion")
    sync, unsync = flow["synchronised"], flow["unsynchronised"]
    assert motion["synchronised (us)"] == f"{sync['latency_min_us']:,.0f} .. {sync['latency_max_us']:,.0f}"
    assert motion["unsynchronised (us)"] == f"{unsync['latency_min_us']:,.0f} .. {unsync['latency_max_us']:,.0f}"
    hip = row(table(markdown(seeds["ntua_sahr"][2]), "flow"), "hip_loop")
    assert hip["mode"] == "unsynchronised" and hip["synchronised (us)"] == "-"


# ---------------------------------------------------------------------------------------------------------------
# the plots


def test_one_valid_png_per_ftt_and_canopen_bus(seeds: dict[str, Any]) -> None:
    for name in SEEDS:
        files = seeds[name][2]
        pngs = {p for p in files if p.endswith(".png")}
        assert pngs == PLOTS[name], name
        md = markdown(files)
        for path in pngs:
            assert f"]({path})" in md  # linked from the report
            data = files[path]
            assert data.startswith(PNG_SIGNATURE)
            assert b"Software" not in data and b"tIME" not in data  # no version or time stamp


def test_png_sizes_are_the_fixed_figure_sizes(seeds: dict[str, Any]) -> None:
    """Pixel sizes are the module's figure sizes at its DPI (no tight bounding box that depends on text)."""
    image = pytest.importorskip("PIL.Image")
    ftt = image.open(io.BytesIO(seeds["cambada"][2]["report/lowlevel_macro_cycle.png"]))
    sync = image.open(io.BytesIO(seeds["allex2"][2]["report/can0_sync_cycle.png"]))
    assert ftt.size[0] == round(report_md.FTT_WIDTH_IN * report_md.DPI)
    assert ftt.size[1] > 0
    assert sync.size == (
        round(report_md.SYNC_WIDTH_IN * report_md.DPI),
        round(report_md.SYNC_HEIGHT_IN * report_md.DPI),
    )


def test_long_macro_cycles_show_thirty_ecs_around_the_busiest() -> None:
    """A macro-cycle longer than 30 ECs is shown as 30 consecutive ECs with the busiest in the middle (15 before
    it), shifted to stay inside the macro-cycle: busiest 500 of 1000 -> ECs 485-514; 0 -> 0-29; 999 -> 970-999."""
    ecs = [{"index": i} for i in range(1000)]
    assert report_md.shown_ecs({"ecs": ecs, "worst_ec": {"index": 0}}) == (0, 30)
    assert report_md.shown_ecs({"ecs": ecs, "worst_ec": {"index": 500}}) == (485, 515)
    assert report_md.shown_ecs({"ecs": ecs, "worst_ec": {"index": 999}}) == (970, 1000)
    assert report_md.shown_ecs({"ecs": ecs[:30], "worst_ec": {"index": 29}}) == (0, 30)


# ---------------------------------------------------------------------------------------------------------------
# reproducible output


def test_two_emits_give_identical_bytes(seeds: dict[str, Any]) -> None:
    for name in SEEDS:
        model, report, first = seeds[name]
        assert report_md.emit(model, report) == first, name


def test_plots_ignore_the_users_matplotlibrc(seeds: dict[str, Any], tmp_path: Path) -> None:
    """A matplotlibrc that changes fonts, colours, DPI and transparency must not change generated/ (DESIGN.md:
    byte-identical builds)."""
    (tmp_path / "matplotlibrc").write_text(
        "font.family: serif\nfont.size: 20\naxes.facecolor: red\nlines.linewidth: 5\nsavefig.dpi: 300\n"
        "savefig.transparent: True\naxes.grid: True\n"
    )
    script = (
        "import hashlib, json, sys\n"
        "from pathlib import Path\n"
        "from netcfg.check import analyse_spec\n"
        "from netcfg.emit import report_md\n"
        "m, r = analyse_spec(Path(sys.argv[1]))\n"
        "files = report_md.emit(m, r)\n"
        "print(json.dumps({p: hashlib.sha256(d).hexdigest() for p, d in files.items()}))\n"
    )
    env = {"MPLCONFIGDIR": str(tmp_path), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    proc = subprocess.run(
        [sys.executable, "-c", script, str(SPECS / "cambada.yaml")], capture_output=True, text=True, cwd=ROOT, env=env
    )
    assert proc.returncode == 0, proc.stderr
    theirs = json.loads(proc.stdout)
    ours = {p: hashlib.sha256(d).hexdigest() for p, d in seeds["cambada"][2].items()}
    assert theirs == ours


def test_check_does_not_import_matplotlib() -> None:
    """`netcfg check` must not pay for matplotlib: the emitter imports it only when it draws."""
    script = (
        "import sys\n"
        "from pathlib import Path\n"
        "from netcfg.check import check\n"
        "import netcfg.emit.report_md\n"
        "check(Path(sys.argv[1]))\n"
        "assert 'matplotlib' not in sys.modules\n"
    )
    proc = subprocess.run([sys.executable, "-c", script, str(SPECS / "cambada.yaml")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_build_writes_the_report(tmp_path: Path) -> None:
    """The emitter is registered: `netcfg build` writes report.md and the plot it links."""
    report, out, files = build(SPECS / "allex2.yaml", tmp_path / "out")
    assert out is not None, report["errors"]
    assert (out / "report.md").read_bytes() == files["report.md"]
    assert (out / "report" / "can0_sync_cycle.png").read_bytes().startswith(PNG_SIGNATURE)
    assert str(tmp_path) not in files["report.md"].decode()  # no machine paths


# ---------------------------------------------------------------------------------------------------------------
# free text


def test_cell_escapes_pipes_backslashes_and_newlines() -> None:
    assert report_md.cell("a | b\nc\\") == "a \\| b c\\\\"
    assert report_md.cell("  spaced\r\n\tout  ") == "spaced out"
    assert split_row("| " + report_md.cell("x|y\\") + " | z |") == ["x\\|y\\\\", "z"]


def test_descriptions_with_pipes_and_newlines_keep_tables_well_formed(tmp_path: Path) -> None:
    """Names are checked identifiers, descriptions free text: '|' would split a cell and a newline end the row."""
    nasty = "M1 | set-points\nfor motors 1|2|3 \\"
    data = load_spec("cambada.yaml")
    data["description"] = "first line | still first\n\nsecond paragraph?"
    next(m for m in data["messages"] if m["name"] == "motor_setpoints")["description"] = nasty
    next(n for n in data["nodes"] if n["name"] == "gateway")["description"] = "serial | 115 kbaud\nto the PC"
    next(f for f in data["flows"] if f["name"] == "motion")["description"] = "Table 3\n| Motion |"
    path = tmp_path / "nasty.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    model, report = analyse_spec(path)
    assert model is not None and report["ok"], report["errors"]
    md = markdown(report_md.emit(model, report))
    assert_well_formed(md)
    # the same text as the resolver hands it over on the Model (set here so the test holds whether or not
    # this checkout's resolver carries descriptions yet)
    model.description = data["description"]
    model.messages["motor_setpoints"].description = nasty
    model.nodes["gateway"].description = "serial | 115 kbaud\nto the PC"
    object.__setattr__(model.flows["motion"], "description", "Table 3\n| Motion |")  # Flow is a frozen dataclass
    md = markdown(report_md.emit(model, report))
    assert_well_formed(md)
    escaped = "M1 \\| set-points for motors 1\\|2\\|3 \\\\"
    assert row(table(md, "message"), "motor_setpoints")["description"] == escaped
    assert row(table(md, "FTT id"), "0")["short description"] == escaped
    assert row(table(md, "node"), "gateway")["description"] == "serial \\| 115 kbaud to the PC"
    assert "\nfirst line | still first second paragraph?\n" in md  # one paragraph, not a table row
    assert "- **motion**: Table 3 | Motion |\n" in md  # one list item
    assert not any(line.startswith("| Motion") for line in md.splitlines())
