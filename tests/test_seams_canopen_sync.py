"""Where CANopen's SYNC cycle meets the other features: a drive's tx_delay, a sending task's release jitter, the
synchronised flow analysis and the simulator's verdict.

The specs in tests/data/seams keep their headers: what netcfg printed, what the simulator or a hand derivation
shows, and the derivation. Every figure asserted here is derived there or in the test's docstring.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml
from conftest import bus, check, check_data, cli

from netcfg.check import analyse_spec
from netcfg.emit.runtime_json import runtime_document

DATA = Path(__file__).parent / "data" / "seams"


def seam(name: str) -> Path:
    return next(DATA.glob(f"{name}-*.yaml"))


def seam_data(name: str) -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(seam(name).read_text(encoding="utf-8"))
    return data


def codes(report: dict[str, Any]) -> list[str]:
    return [e["code"] for e in report["errors"]]


def flow(report: dict[str, Any], name: str) -> dict[str, Any]:
    return next(f for f in report["flows"] if f["name"] == name)


def simulate(source: Path, *args: str) -> tuple[int, dict[str, Any], str]:
    proc = cli("simulate", str(source), "--format", "json", *args)
    assert proc.returncode in (0, 1), proc.stderr
    return proc.returncode, json.loads(proc.stdout), proc.stderr


def runtime_file(spec: Path, out: Path, bound_ns: int | None = None) -> Path:
    """The runtime configuration netcfg writes for the spec (refused or not); `bound_ns` replaces its analysed
    SYNC-cycle bound, to hold a run against another figure."""
    model, report = analyse_spec(spec)
    assert model is not None
    doc = json.loads(json.dumps(runtime_document(model, report)))
    if bound_ns is not None:
        doc["buses"][0]["canopen"]["sync_completion_ns"] = bound_ns
    out.write_text(json.dumps(doc), encoding="utf-8")
    return out


# -- 01: the drive's tx_delay --------------------------------------------------------------------------------


def test_01_sync_cycle_waits_for_the_drives_tx_delay() -> None:
    """Seam 01: d1 queues its TPDO tx_delay = 3 ms after SYNC's reception. W = B 135 + SYNC 55 + D 3000 + TPDO
    135 = 3,325 us (the header's >= 55 + 3000 + 135 plus one frame already on the bus), past the 2 ms windows."""
    report = check(seam("01"))
    sync = bus(report, "can0")["sync"]
    assert sync["worst_completion_us"] == 3325.0
    assert sync["worst_completion_us"] >= 55 + 3000 + 135
    assert sync["cycles"][0]["tx_delay_us"] == 3000.0
    assert codes(report) == ["sync-cycle"]
    assert "3325 us after SYNC, 1325 us too late" in report["errors"][0]["message"]
    assert "tx_delay of 3 ms" in report["errors"][0]["message"]


def test_01_without_tx_delay_the_cycle_is_what_it_was(tmp_path: Path) -> None:
    """The same bus without tx_delay: W = 135 + 55 + 135 = 325 us (the header's figure from before), within 2 ms:
    the delay term is the drive's, not a constant."""
    data = seam_data("01")
    del data["nodes"][1]["tx_delay"]
    report = check_data(tmp_path, data)
    assert report["ok"] and bus(report, "can0")["sync"]["worst_completion_us"] == 325.0


def test_01_forced_simulation_shows_every_cycle_incomplete() -> None:
    """Simulated anyway, every cycle is incomplete (header: 100 of 100 in 1 s): as the analysis now says, so a
    finding (exit 1), not a violation of the analysis."""
    rc, doc, _ = simulate(seam("01"), "--duration", "1s", "--force")
    assert rc == 1 and doc["exceeds_analysis"] == []
    assert doc["protocols"]["can0"][0]["incomplete_cycles"] == 100
    assert any("100 of 100 SYNC cycles incomplete" in f and "as analysed" in f for f in doc["findings"])


# -- 04: the sending task's release jitter -------------------------------------------------------------------


def test_04_sync_cycle_counts_the_sending_tasks_jitter() -> None:
    """Seam 04: fast (1 ms, BCET 10, WCRT 900 us) sends fm1..fm3 (135 us each) as it ends, so the CAN RTA gives
    each a release jitter of 900 - 10 = 890 us; the SYNC cycle takes the same: W = B 135 + SYNC 55 + TPDO 135 +
    3 x ceil((W + 890) / 1000) x 135: 730 -> 1135 -> 1540 -> 1540 us. Sound against the header's 900 us worst case
    (pessimistic: the blocking frame is one of the fm instances counted again), and past the 800 us windows."""
    report = check(seam("04"))
    fast = next(t for n in report["nodes"] if n["name"] == "master" for t in n["tasks"] if t["name"] == "fast")
    assert fast["wcrt_us"] == 900
    sync = bus(report, "can0")["sync"]
    assert sync["worst_completion_us"] == 1540.0 and sync["worst_completion_us"] >= 900
    assert codes(report) == ["sync-cycle"]


def test_04_a_task_without_response_variation_adds_no_jitter(tmp_path: Path) -> None:
    """With fast's BCET = WCET = 900 us it always ends 900 us after its release: the RTA's jitter is 0 and the SYNC
    cycle is the header's old 730 us = 135 + 55 + 135 + 3 x 135, within 800 us. The term is the RTA's jitter."""
    data = seam_data("04")
    data["nodes"][0]["tasks"][0]["bcet"] = "900 us"
    report = check_data(tmp_path, data)
    assert bus(report, "can0")["sync"]["worst_completion_us"] == 730.0
    assert "sync-cycle" not in codes(report)


def widened(tmp_path: Path) -> Path:
    """Seam 04 with both windows at 2 ms (the header's second run): accepted, same traffic."""
    data = seam_data("04")
    data["buses"][0]["canopen"].update(read_window="2 ms", sync_window="2 ms")
    path = tmp_path / "co_jit_wide.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def test_04_measured_cycles_stay_within_the_bound(tmp_path: Path) -> None:
    """The header measures SYNC -> last TPDO up to 897.8 us (10 s); the bound of 1,540 us holds it: exit 0."""
    spec = widened(tmp_path)
    assert check(spec)["ok"]
    rc, doc, _ = simulate(spec, "--duration", "2s")
    done = doc["protocols"]["can0"][0]["sync_completion_us"]
    assert done["analysed"] == 1540.0 and 0 < done["max"] <= 900
    assert rc == 0 and doc["violations"] == [] and doc["exceeds_analysis"] == []


def test_04_a_cycle_above_its_bound_is_a_violation(tmp_path: Path) -> None:
    """The same run held against the bound netcfg used to write, 730 us (the header): the header's cycles take
    up to 897.8 us, and in 2 s seed 0 more than 730 us (the fm bursts around SYNC occur every few cycles): exit 1,
    the bus's SYNC cycle named in exceeds_analysis, a line in the text and on stderr."""
    runtime = runtime_file(widened(tmp_path), tmp_path / "runtime.json", bound_ns=730_000)
    rc, doc, stderr = simulate(runtime, "--duration", "2s")
    assert doc["protocols"]["can0"][0]["sync_completion_us"]["max"] > 730
    assert rc == 1 and doc["exceeds_analysis"] == ["can0.sync_cycle"]
    assert any(v.startswith("bus can0: SYNC -> last TPDO took up to") for v in doc["violations"])
    assert "outside the analysis: bus can0: SYNC -> last TPDO" in stderr
    text = cli("simulate", str(runtime), "--duration", "2s")
    assert text.returncode == 1 and "analysed 730 us" in text.stdout


def test_04_incomplete_cycles_within_the_analysed_window_are_violations(tmp_path: Path) -> None:
    """Seam 04 as netcfg used to write it: bound 730 us within the 800 us read window, yet the header's runs see
    33-40 of 1,000 cycles incomplete (a TPDO after the window, late the next cycle): exit 1, a violation."""
    runtime = runtime_file(seam("04"), tmp_path / "runtime.json", bound_ns=730_000)
    rc, doc, _ = simulate(runtime, "--duration", "2s")
    rep = doc["protocols"]["can0"][0]
    assert rep["incomplete_cycles"] > 0 and rep["late_frames"] > 0
    assert rc == 1 and doc["exceeds_analysis"] == ["can0.sync_cycle"]
    assert any(f"{rep['incomplete_cycles']} of {rep['cycles']} SYNC cycles incomplete" in v for v in doc["violations"])


def test_04_forced_simulation_of_the_refused_spec_fails() -> None:
    """Seam 04 is refused now (1,540 us > 800 us); simulated anyway its incomplete cycles are what was analysed:
    a finding, exit 1."""
    rc, doc, _ = simulate(seam("04"), "--duration", "2s", "--force")
    assert rc == 1 and doc["exceeds_analysis"] == []
    assert doc["protocols"]["can0"][0]["incomplete_cycles"] > 0
    assert any("SYNC cycles incomplete" in f and "as analysed" in f for f in doc["findings"])


# -- 03: a TPDO's tx_delay in the synchronised flow analysis --------------------------------------------------


def test_03_flow_from_a_delayed_tpdo_keeps_its_cycle() -> None:
    """Seam 03: fb1 lies in [3000 - 200, 3000 - 47] = [2,800, 2,953] us (SYNC received 47..190 us after its
    queueing, plus d1's 10 us tx_delay; control at 3 ms); 2,935 us measured. fb2, without tx_delay, [2,810, 2,953]."""
    report = check(seam("03"))
    fb1, fb2 = flow(report, "fb1")["synchronised"], flow(report, "fb2")["synchronised"]
    assert (fb1["latency_min_us"], fb1["latency_max_us"]) == (2800.0, 2953.0)
    assert 2800 <= fb1["latency_min_us"] <= 2935 <= fb1["latency_max_us"] <= 2963
    assert (fb2["latency_min_us"], fb2["latency_max_us"]) == (2810.0, 2953.0)


def test_03_long_period_variant_has_no_extra_period() -> None:
    """Seam 03's variant (10 ms period, 500 us read window, control at 1 ms): fb1 in [800, 953] us, not 10,800
    (the header of 03b); 935 us measured."""
    report = check(seam("03b"))
    fb1 = flow(report, "fb1")["synchronised"]
    assert (fb1["latency_min_us"], fb1["latency_max_us"]) == (800.0, 953.0)
    assert fb1["latency_max_us"] <= 953 + 10


def test_03_simulated_flows_fall_inside_the_analysis() -> None:
    """Both specs simulated: fb1 measured 2,935 and 935 us every cycle (the headers), inside the analysed ranges."""
    for name, measured in (("03", 2935.0), ("03b", 935.0)):
        rc, doc, _ = simulate(seam(name), "--duration", "1s")
        fb1 = next(f for f in doc["flows"] if f["name"] == "fb1")
        assert fb1["latency_us"]["max"] == measured and fb1["within_analysis"] is True
        assert rc == 0 and doc["violations"] == []
