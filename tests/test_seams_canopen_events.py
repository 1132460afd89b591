"""Event-driven TPDOs (transmission type 254/255) and the objects a device must have for what the spec sets.

Seam 02 (tests/data/seams/02-canopen-event-timer-hides-events.yaml, its header the derivation): by CiA 301
(7.3.3 and 0x1800 sub 2/3/5) an event-driven TPDO goes out on every application event, its event timer is one more
event, due when the TPDO has been silent that long, and only the inhibit time (sub 3) spaces two sends. An event
timer therefore adds sends and never bounds them: the worst-case minimum inter-arrival is the inhibit time.
Frame figures: an 8-byte classical frame with 11-bit id is 135 bits worst case (47 + 64 data bits + 24 stuff bits),
1,080 us at 125 kbit/s and 135 us at 1 Mbit/s.
"""

from __future__ import annotations

import re
import shutil
import uuid
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import ROOT, bus, check, check_data, cli, message, runtime_config_of

from netcfg import cia301
from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import summary
from netcfg.sim.scenario import SimOptions

SEAMS = ROOT / "tests" / "data" / "seams"
SEAM = SEAMS / "02-canopen-event-timer-hides-events.yaml"
EDS = SEAMS / "drive_et.eds"
MS = 1_000_000
PDO_LINE = 32  # the seam file's line of d1_state's `pdo:` (its event_timer key is on it)


def _seam(tmp_path: Path, drop: str = "", add: str = "") -> Path:
    """The seam spec, its d1_state's PDO without `drop` and with the key line `add` after its producer (one line, so
    the PDO moves to line PDO_LINE + 1), saved beside a copy of drive_et.eds."""
    shutil.copy(EDS, tmp_path / EDS.name)
    text = SEAM.read_text(encoding="utf-8")
    pdo = "pdo: {tpdo: 1, transmission: 255, event_timer: 100 ms, inhibit: 1 ms, map: [0x6064, 0x606C]}"
    assert text.splitlines()[PDO_LINE - 1].strip() == pdo
    text = text.replace(pdo, pdo.replace(drop, ""))
    if add:
        text = text.replace("    producer: d1\n", f"    producer: d1\n    {add}\n")
    path = tmp_path / "spec.yaml"
    path.write_text(text, encoding="utf-8")
    return path


NO_INHIBIT = "inhibit: 1 ms, "


def _errors(report: dict[str, Any], code: str) -> list[dict[str, Any]]:
    return [e for e in report["errors"] if e["code"] == code]


def test_seam_is_analysed_at_the_inhibit_time_and_refused() -> None:
    """Seam header: d1_state goes out at most every inhibit time, 1 ms, whatever its 100 ms event timer; 1,080 us of
    frame every 1,000 us is 108 % of the bus, so check refuses the spec as overloaded."""
    report = check(SEAM)
    d1 = message(bus(report, "can0"), "d1_state")
    assert (d1["kind"], d1["interval_us"], d1["period_us"]) == ("sporadic", 1000.0, None)
    assert d1["frame_us_worst"] == 1080.0
    assert d1["utilization"] == pytest.approx(1.08)
    assert report["ok"] is False
    assert _errors(report, "overload")


def test_cli_refuses_the_seam() -> None:
    proc = cli("check", str(SEAM))
    assert proc.returncode == 1
    assert "Traceback" not in proc.stderr
    assert "[overload]" in proc.stderr


@pytest.mark.parametrize(
    "add",
    [
        "",  # nothing says how often the application triggers it
        "min_interarrival: 20 ms",  # the application's own gap: a timer expiry may still fall just before an event
    ],
    ids=["nothing", "min_interarrival"],
)
def test_event_timer_without_inhibit_is_refused_at_the_timer(tmp_path: Path, add: str) -> None:
    """Without an inhibit time the timer may run out just before an application event (CiA 301 7.3.3: it is due
    after that long without a send, whatever comes next), so nothing bounds the gap between two sends: one error,
    at d1_state's event_timer, that says to give an inhibit time."""
    report = check(_seam(tmp_path, NO_INHIBIT, add))
    assert [(e["code"], e["line"]) for e in report["errors"]] == [("event-timer", PDO_LINE + bool(add))]
    (err,) = report["errors"]
    assert "inhibit" in err["message"] and err["column"] > 1


def test_event_timer_without_inhibit_exits_1_without_traceback(tmp_path: Path) -> None:
    proc = cli("check", str(_seam(tmp_path, NO_INHIBIT)))
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert f"spec.yaml:{PDO_LINE}:" in proc.stderr and "[event-timer]" in proc.stderr


def test_on_demand_application_leaves_the_timer_periodic(tmp_path: Path) -> None:
    """Application events only at start-up and mode changes: in the steady state the timer alone sends, every
    100 ms: 1,080 us / 100 ms = 1.08 % (what check printed for the seam before, now only where it holds)."""
    report = check(_seam(tmp_path, NO_INHIBIT, "type: on-demand"))
    assert report["ok"], report["errors"]
    d1 = message(bus(report, "can0"), "d1_state")
    assert (d1["kind"], d1["period_us"]) == ("periodic", 100_000.0)
    assert d1["utilization"] == pytest.approx(0.0108)


def test_application_period_within_the_timer_stands(tmp_path: Path) -> None:
    """Application sends every 20 ms, no longer than the 100 ms timer: the timer, restarted by every send, never
    runs out, so the TPDO is periodic at 20 ms: 1,080 us / 20 ms = 5.4 %."""
    report = check(_seam(tmp_path, NO_INHIBIT, "period: 20 ms"))
    assert report["ok"], report["errors"]
    d1 = message(bus(report, "can0"), "d1_state")
    assert (d1["kind"], d1["period_us"], d1["utilization"]) == ("periodic", 20_000.0, pytest.approx(0.054))


def test_application_period_beyond_the_timer_falls_to_the_inhibit_time(tmp_path: Path) -> None:
    """Application sends every 200 ms, the timer at 100 ms runs out between them and may fall just before one: only
    the 1 ms inhibit time spaces them, as in the seam (108 %)."""
    report = check(_seam(tmp_path, add="period: 200 ms"))
    d1 = message(bus(report, "can0"), "d1_state")
    assert (d1["kind"], d1["interval_us"]) == ("sporadic", 1000.0)
    assert _errors(report, "overload")


def test_the_rule_itself() -> None:
    """cia301.tpdo_timing for type 255, SYNC 10 ms, timer 100 ms, inhibit 1 ms (10 x 100 us): the cases above, and
    without a timer the inhibit time stays a floor under the application's own minimum gap (max(20 ms, 1 ms))."""
    sync = 10 * MS
    assert cia301.tpdo_timing(255, sync, 100, 10) == ("sporadic", None, 1 * MS)
    assert cia301.tpdo_timing(254, sync, 100, 10, mit_ns=20 * MS) == ("sporadic", None, 1 * MS)
    assert cia301.tpdo_timing(255, sync, 100, None) == ("sporadic", None, None)
    assert cia301.tpdo_timing(255, sync, 100, None, "on-demand") == ("periodic", 100 * MS, None)
    # a period that keeps the timer from running out stands; one equal to the timer ties with it (the timer may
    # fire a hair before the write: two sends, nothing between them), and so does one that jitter makes reach it
    assert cia301.tpdo_timing(255, sync, 100, None, period_ns=99 * MS) == ("periodic", 99 * MS, None)
    assert cia301.tpdo_timing(255, sync, 100, None, period_ns=100 * MS) == ("sporadic", None, None)
    assert cia301.tpdo_timing(255, sync, 100, 10, period_ns=90 * MS, jitter_ns=10 * MS) == ("sporadic", None, 1 * MS)
    assert cia301.tpdo_timing(255, sync, None, 10, mit_ns=20 * MS) == (None, None, 20 * MS)
    assert cia301.tpdo_timing(255, sync, None, 10) == (None, None, 1 * MS)


def test_simulator_sends_at_the_inhibit_time(tmp_path: Path) -> None:
    """The seam at 1 Mbit/s (135 us every 1 ms: 13.5 %, schedulable): runtime.json carries d1_state sporadic at the
    inhibit time, and the simulator, drawing it at that worst rate, sends it about 200 times in 200 ms (one per ms,
    +-1 for the random phase and 50 ppm drift); at the event timer it would be 2."""
    data = yaml.safe_load(_seam(tmp_path).read_text(encoding="utf-8"))
    data["buses"][0]["bitrate"] = "1 Mbit/s"
    cfg = runtime_config_of(tmp_path / "spec.yaml", data)
    d1 = next(m for m in cfg.messages if m.name == "d1_state")
    assert (d1.kind, d1.interval_ns) == ("sporadic", 1 * MS)
    _, res = run_once(cfg, SimOptions(duration_ns=200 * MS, seed=1))
    count = next(m["count"] for m in summary(res)["messages"] if m["name"] == "d1_state")
    assert 199 <= count <= 201


# -- heartbeats against the device (as event timers are checked against 0x18xx sub 5)


def _heartbeat_spec(tmp_path: Path, eds_text: str, heartbeat: str) -> dict[str, Any]:
    (tmp_path / "drive.eds").write_text(eds_text, encoding="utf-8")
    data: dict[str, Any] = yaml.safe_load(_seam(tmp_path).read_text(encoding="utf-8"))
    data["nodes"][1] = {
        "name": "d1",
        "node_id": 1,
        "device": {"eds": "drive.eds"},
        "heartbeat": heartbeat,
        "buses": ["can0"],
    }
    data["nodes"] = data["nodes"][:2]
    data["messages"] = [data["messages"][1] | {"producer": "d1"}]  # the synchronous TPDO only
    return data


def test_heartbeat_on_a_device_with_a_writable_1017_is_accepted(tmp_path: Path) -> None:
    """drive_et.eds has 0x1017 rw: the heartbeat is the device's to send."""
    report = check_data(tmp_path, _heartbeat_spec(tmp_path, EDS.read_text(encoding="utf-8"), "100 ms"))
    assert report["ok"], report["errors"]


@pytest.mark.parametrize(("heartbeat", "ok"), [("100 ms", True), ("50 ms", False)])
def test_read_only_1017_holds_only_its_own_value(tmp_path: Path, heartbeat: str, ok: bool) -> None:
    """0x1017 read-only with default 100 (ms): a 100 ms heartbeat needs no write; 50 ms would need one the device
    refuses, so it is an error at the node's heartbeat key."""
    text = EDS.read_text(encoding="utf-8")
    block = text[text.index("[1017]") :]
    block = block[: block.index("\n\n")]
    text = text.replace(block, block.replace("AccessType=rw", "AccessType=ro"))
    report = check_data(tmp_path, _heartbeat_spec(tmp_path, text, heartbeat))
    if ok:
        assert report["ok"], report["errors"]
    else:
        saved = (tmp_path / "spec.yaml").read_text(encoding="utf-8").splitlines()
        line = next(k for k, text in enumerate(saved, 1) if text.strip().startswith("heartbeat:"))
        errors = [(e["code"], e["line"]) for e in report["errors"]]
        assert errors == [("heartbeat", line)]
        assert "not writable" in report["errors"][0]["message"]


# -- the live master and the simulated drives (`netcfg run --simulated-drives`)

EFFORT_SYNC = 'pdo: {tpdo: 2, transmission: 1, map: [0x6077, "0x30D1:2"]}'
EFFORT_EVENT = 'pdo: {tpdo: 2, transmission: 255, event_timer: 40 ms, inhibit: 10 ms, map: [0x6077, "0x30D1:2"]}'
CYCLES = 25  # x ALLEX-2's 20 ms SYNC period: 0.5 s of cycle


@pytest.fixture(scope="module")
def event_build(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """specs/allex2.yaml with hip_l on drive_et.eds (the EPOS4's objects with the TPDO event timer, sub 5) and its
    hip_l_effort TPDO event-driven: type 255, event timer 40 ms, inhibit 10 ms; built as `netcfg build` does."""
    from netcfg.commands import main

    folder = tmp_path_factory.mktemp("event_build")
    shutil.copy(EDS, folder / EDS.name)
    text = (ROOT / "specs" / "allex2.yaml").read_text(encoding="utf-8")
    assert text.count(EFFORT_SYNC) == 6 and text.count("    device: epos4\n") == 6
    text = text.replace(EFFORT_SYNC, EFFORT_EVENT, 1)  # the first: hip_l_effort
    text = text.replace("    device: epos4\n", "    device: {eds: drive_et.eds}\n", 1)  # the first: hip_l
    (folder / "spec.yaml").write_text(text, encoding="utf-8")
    assert main(["build", str(folder / "spec.yaml"), "-o", str(folder / "out")]) == 0
    return folder / "out"


def _operate(out: Path, channel: str, **hip_l: Any) -> tuple[Any, Any]:
    import can

    import netcfg.runtime as rt
    from netcfg.runtime.drives import DriveBench
    from netcfg.runtime.operate import BusLog, Plan, operate

    cfg = rt.load(out / "runtime.json")
    options = {"hip_l": hip_l} if hip_l else None
    with (
        DriveBench(cfg, out / "canopen", channel=channel, options=options) as bench,
        BusLog(can.Bus(interface="virtual", channel=channel), None) as bus,
    ):
        outcome = operate(cfg, bus, Plan(cycles=CYCLES))
        sent = dict(bench["hip_l"].event_tpdos_sent)
    return outcome, sent


HOST_SLACK_MS = 50  # how late a drive thread may send on a loaded host (tests/test_fault_drills.py allows the same)


def test_simulated_drive_sends_its_event_tpdo_per_event_timer(event_build: Path) -> None:
    """The drive is OPERATIONAL for at least the 0.5 s of cycle; its event timer sends TPDO2 whenever it has been
    silent 40 ms, so at least 0.5 / 0.04 - 1 = 11 sends (more: set-up and CiA 402 enabling come first); the
    master, allowing the timer plus the analysed response time, reports nothing and the run is ok. The drives are
    threads of this process in wall-clock time: on a loaded host a send can come a few milliseconds late, which the
    master then reports; HOST_SLACK_MS (the fault drills' allowance for a loaded host) tells that from a drive that
    ignores its timer, whose silence lasts the whole run (the next test)."""
    from netcfg.run_result import result_document

    outcome, sent = _operate(event_build, f"events-ok-{uuid.uuid4().hex[:8]}")
    assert outcome.run is not None and outcome.run.cycles == CYCLES
    assert sent.get(2, 0) >= 11
    silences = [float(re.search(r"silent for ([\d.]+) ms", e.text).group(1))  # type: ignore[union-attr]
                for _, e in outcome.events if e.kind == "tpdo-silent"]
    assert all(ms <= 40 + HOST_SLACK_MS for ms in silences), silences
    if not silences:
        assert result_document(outcome)["ok"] is True


def test_master_reports_a_tpdo_silent_beyond_its_event_timer(event_build: Path) -> None:
    """A drive that ignores its event timer sends TPDO2 only on application events: its mapped torque and current
    stay 0 under the bench's velocity model, so once, at the first SYNC. The master reports it silent beyond its
    40 ms event timer once (0.5 s of cycle leave no doubt), for hip_l, without stopping anything, and the run is not
    ok."""
    from netcfg.run_result import result_document

    outcome, sent = _operate(event_build, f"events-mute-{uuid.uuid4().hex[:8]}", no_event_timer=True)
    assert outcome.run is not None and outcome.run.cycles == CYCLES
    assert sent.get(2, 0) <= 1
    silent = [(e.node, e.kind, e.action) for _, e in outcome.events if e.kind == "tpdo-silent"]
    assert silent == [("hip_l", "tpdo-silent", "continue")]
    assert "hip_l_effort" in next(e.text for _, e in outcome.events if e.kind == "tpdo-silent")
    doc = result_document(outcome)
    assert doc["ok"] is False and any(e["kind"] == "tpdo-silent" for e in doc["events"])


def test_bus_yml_import_of_an_event_timer_tpdo_without_inhibit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The seam at 1 Mbit/s built, its bus.yml's d1 TPDO1 given inhibit_time 0, imported back: nothing bounds the
    application's sends, so the importer says to give the TPDO an inhibit time (a min_interarrival would not do, see
    above) and makes it on-demand; check then counts the timer's own sends, periodic at its 100 ms."""
    from netcfg.commands import main

    data = yaml.safe_load(_seam(tmp_path).read_text(encoding="utf-8"))
    data["buses"][0]["bitrate"] = "1 Mbit/s"
    (tmp_path / "spec.yaml").write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    assert main(["build", str(tmp_path / "spec.yaml"), "-o", str(tmp_path / "out")]) == 0
    bus_yml = tmp_path / "out" / "canopen" / "bus.yml"
    text = bus_yml.read_text(encoding="utf-8")
    assert text.count("inhibit_time: 10\n") == 1  # d1's TPDO1: 1 ms in units of 100 us
    bus_yml.write_text(text.replace("inhibit_time: 10\n", "inhibit_time: 0\n"), encoding="utf-8")
    capsys.readouterr()
    assert main(["import", "bus-yml", str(bus_yml), "-o", str(tmp_path / "back.yaml")]) == 0
    warned = capsys.readouterr().err
    assert "[bus-yml-timing]" in warned and "give the TPDO an inhibit_time" in warned
    report = check(tmp_path / "back.yaml")
    assert report["ok"], report["errors"]
    d1 = message(bus(report, "can0"), "d1_state")
    assert (d1["kind"], d1["period_us"]) == ("periodic", 100_000.0)
