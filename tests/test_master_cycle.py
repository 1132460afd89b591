"""The CANopen master's cycle, modelled rather than assumed: the SYNC-cycle bound, the master's own timing from
the spec, and the simulator running the live master (netcfg.runtime.canopen_master.MasterCycle) on it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import ROOT, SHARED, check, check_data, cli

REPRO = SHARED / "repro" / "soundness"


def repro(name: str) -> Path:
    path = REPRO / name
    if not path.is_file():
        pytest.skip("the shared soundness reproductions are not next to this checkout")
    return path


def test_sync_cycle_counts_other_messages_release_jitter() -> None:
    """Repro 09: 'other' (0x85, T = 1 ms, J = 900 us, 135 bits at 1 Mbit/s) beats the TPDO 0x181. Two of its
    instances can be released 100 us apart inside one cycle: W = B 135 + SYNC 55 + TPDO 135 + ceil((W + 900) /
    1000) x 135 = 325 + 2 x 135 = 595 us (the file's derivation), over the 500 us window."""
    report = check(repro("09-canopen-sync-jitter.yaml"))
    can0 = report["buses"][0]
    assert can0["sync"]["worst_completion_us"] == 595.0
    assert [e["code"] for e in report["errors"]] == ["sync-cycle"]
    assert "595 us after SYNC, 95 us too late" in report["errors"][0]["message"]


def repro12_data() -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(repro("12-canopen-master-fixed-times.yaml").read_text(encoding="utf-8"))
    return data


def test_a_master_that_keeps_its_cycle_runs_without_overrun() -> None:
    """Repro 12: a 2 ms cycle whose master computes 100 .. 200 us, starting 1 ms after SYNC (after its 1 ms read
    window). Check: 1 ms + 200 us <= 2 ms, no error. The flow 'loop' (drive.apply, state, master.control, cmd,
    drive.apply), with SYNC received 47 .. 190 us after k x 2 ms (47-bit frame; blocked by one 135-bit frame, then
    55 bits) and the master starting exactly 1 ms after k x 2 ms (no master_jitter):
    worst: apply at 47 us, ends 147 us; state samples at the next SYNC (2047 us); control starts 3000 us, ends
    3200 us; cmd done by 3200 + 325 (its response time) = 3525 us; apply at the SYNC after: 4190 - 47 = 4143 us.
    best: apply at 190 us, ends 240 us; state at 2047 us; control at 3000 us; apply at 4047 - 190 = 3857 us.
    Simulated (the live master, 10 s): no overrun, every cycle complete, 'loop' inside 3857 .. 4143 us, exit 0."""
    path = repro("12-canopen-master-fixed-times.yaml")
    report = check(path)
    assert report["ok"], report["errors"]
    loop = next(f for f in report["flows"] if f["name"] == "loop")
    assert (loop["latency_min_us"], loop["latency_max_us"]) == (3857.0, 4143.0)
    r = cli("simulate", str(path), "--duration", "10s", "--seed", "0", "--format", "json")
    assert r.returncode == 0, r.stdout + r.stderr
    doc = json.loads(r.stdout)
    can0 = doc["protocols"]["can0"][0]
    assert can0["cycles"] == 5000 and can0["overruns"] == 0 and can0["incomplete_cycles"] == 0
    flow = doc["flows"][0]
    assert flow["samples"] > 4900 and flow["within_analysis"]
    assert 3857 <= flow["latency_us"]["min"] <= flow["latency_us"]["max"] <= 4143


def test_check_refuses_a_cycle_its_master_cannot_keep(tmp_path: Path) -> None:
    """Repro 12 with a WCET of 1.5 ms: the master's step ends up to 1 ms + 1.5 ms = 2.5 ms after SYNC, after the
    next SYNC is due at 2 ms; and with an offset of 0.5 ms it would compute before its 1 ms read window ends."""
    data = repro12_data()
    data["nodes"][0]["tasks"][0].update(wcet="1500 us")
    report = check_data(tmp_path, data)
    assert [e["code"] for e in report["errors"]] == ["master-cycle"]
    assert "ends up to 2.5 ms after SYNC" in report["errors"][0]["message"]
    line = report["errors"][0]["line"]  # names the master's task in the file written
    assert "control" in (tmp_path / "spec.yaml").read_text(encoding="utf-8").splitlines()[line - 1]
    data = repro12_data()
    data["nodes"][0]["tasks"][0].update(offset="500 us")
    report = check_data(tmp_path, data)
    assert [e["code"] for e in report["errors"]] == ["master-cycle"]
    assert "before the 1 ms read window" in report["errors"][0]["message"]


def test_a_master_slower_than_its_runtime_config_allows_is_a_finding(tmp_path: Path) -> None:
    """The simulator runs the master's times from runtime.json, so a runtime.json whose master step outgrows the
    cycle (edited after the build: 1 ms offset + 1.5 ms > 2 ms) shows overruns: a finding, exit 1."""
    r = cli("build", str(repro("12-canopen-master-fixed-times.yaml")), "-o", str(tmp_path / "out"))
    assert r.returncode == 0, r.stderr
    path = tmp_path / "out" / "runtime.json"
    doc = json.loads(path.read_text(encoding="utf-8"))
    task = doc["nodes"][0]["tasks"][0]
    assert (doc["nodes"][0]["name"], task["name"]) == ("master", "control")
    task["bcet_ns"], task["wcet_ns"] = 1_400_000, 1_500_000
    path.write_text(json.dumps(doc), encoding="utf-8")
    r = cli("simulate", str(path), "--duration", "200ms", "--seed", "1")
    assert r.returncode == 1
    assert "the master overran its 2 ms period in 100 of 100 cycles" in r.stdout, r.stdout


def test_allex2_simulated_flows_fall_inside_their_analysed_range() -> None:
    """ALLEX-2 (seed 000) over 4 seeded gait cycles of 8 s: 400 cycles each, every drive complete, and both flows
    inside the analysed range (test_seeds derives it, the master sending through its FIFO queue: joint_feedback
    7107 .. 9966 us, joint_command 10034 .. 12893 us)."""
    r = cli("simulate", "specs/allex2.yaml", "--duration", "8s", "--runs", "4", "--jobs", "1", "--format", "json")
    assert r.returncode == 0, r.stdout + r.stderr
    doc = json.loads(r.stdout)
    flows = {f["name"]: f for f in doc["flows"]}
    assert flows["joint_feedback"]["analysis_us"] == {"min": 7107.0, "max": 9966.0}
    assert flows["joint_command"]["analysis_us"] == {"min": 10034.0, "max": 12893.0}
    for f in flows.values():
        assert f["samples"] > 4 * 390 and f["within_analysis"], f
    assert doc["exceeds_analysis"] == []


def test_the_simulated_master_is_the_live_one_with_the_spec_times() -> None:
    """The simulator's PDO master is MasterCycle itself: one CycleRecord per cycle, the control step's runs
    between its BCET 225.8 us and WCET 8557.3 us (Table 5, writing), and each SYNC sent on its instant, 10 ms after
    its cycle's (20 ms - the control step's 10 ms offset), at most master_jitter = 13 us late."""
    from netcfg.runtime import load
    from netcfg.sim.canopen import CanopenMaster
    from netcfg.sim.scenario import SimOptions, simulate

    cfg = load(ROOT / "generated" / "allex2" / "runtime.json")
    sc = simulate(cfg, SimOptions(duration_ns=2_000_000_000, seed=5))
    driver = sc.protocols["can0"]
    assert isinstance(driver, CanopenMaster) and driver.run is not None
    assert driver.run.cycles == 100
    runs = sc.task_runs["master.control"]
    assert len(runs) == 100
    assert all(225_800 <= end - start <= 8_557_300 for start, end in runs)
    assert len({end - start for start, end in runs}) > 90  # drawn per cycle
    first = driver.run.records[0].start  # cycle k starts within 13 us of first + k x 20 ms, its SYNC 10 ms later
    for k, rec in enumerate(driver.run.records):
        assert 0 <= round((rec.start - first) * 1e9) - k * 20_000_000 <= 13_000
        assert 0 <= round((rec.sync_sent - first) * 1e9) - k * 20_000_000 - 10_000_000 <= 13_000
    assert cfg.bus("can0").canopen.master_jitter_ns == 13_000  # type: ignore[union-attr]


class _FixedWork:
    """A CycleTiming hook: the same computation time every cycle, no wake-up latency."""

    def __init__(self, work_s: float) -> None:
        self.work = work_s

    def work_s(self, cycle: int) -> float:
        return self.work

    def late_s(self) -> float:
        return 0.0


@pytest.mark.parametrize(("work_s", "sync_after_s"), [(0.004, 0.010), (0.012, 0.012)])
def test_the_sync_keeps_its_instant_unless_the_computation_outlasts_it(work_s: float, sync_after_s: float) -> None:
    """ALLEX-2's master computes 10 ms after SYNC, so each SYNC is due 20 - 10 = 10 ms after its cycle's start:
    a 4 ms computation leaves the SYNC there; a 12 ms one delays it to 12 ms (the writes come first, Figure 7)."""
    from netcfg.runtime import load
    from netcfg.runtime.canopen_master import MasterCycle
    from netcfg.sim.pybus import SimCanBus, VirtualClock
    from netcfg.sim.scenario import Scenario, SimOptions

    cfg = load(ROOT / "generated" / "allex2" / "runtime.json")
    sc = Scenario(cfg, SimOptions(duration_ns=1_000_000_000, canopen="external"))
    sc.start()
    bus = SimCanBus(sc, "can0", node="master")
    try:
        cycle = MasterCycle(cfg, bus, VirtualClock(sc), timing=_FixedWork(work_s), drift_free=True)
        assert cycle.sync_lead_s == 0.010
        run = cycle.run(10)
    finally:
        bus.shutdown()
    for rec in run.records:
        assert rec.written - rec.start == pytest.approx(work_s, abs=1e-9)
        assert rec.sync_sent - rec.start == pytest.approx(sync_after_s, abs=1e-9)


def two_masters() -> dict[str, Any]:
    """Repro 12's 2 ms bus (can0) beside a copy with a 4 ms cycle (can1): one live master per CANopen bus."""
    data = repro12_data()
    data["system"] = "two_masters"
    bus1 = {**data["buses"][0], "name": "can1"}
    bus1["canopen"] = {**bus1["canopen"], "sync_period": "4 ms", "sync_window": "2 ms", "read_window": "2 ms"}
    data["buses"].append(bus1)
    data["nodes"] += [
        {"name": "master1", "role": "master", "node_id": 127, "buses": ["can1"],
         "tasks": [{"name": "control", "sync": True, "offset": "2 ms", "bcet": "300 us", "wcet": "900 us"}]},
        {"name": "drive1", "node_id": 1, "device": "epos4", "buses": ["can1"],
         "tasks": [{"name": "apply", "sync": True, "bcet": "50 us", "wcet": "100 us"}]},
    ]  # fmt: skip
    data["messages"] += [
        {"name": "cmd1", "producer": "master1", "consumers": ["drive1"], "period": "4 ms",
         "pdo": {"rpdo": 1, "transmission": 255, "map": [0x60FF, 0x60B1]}},
        {"name": "state1", "producer": "drive1", "consumers": ["master1"],
         "pdo": {"tpdo": 1, "transmission": 1, "map": [0x6064, 0x606C]}},
    ]  # fmt: skip
    chain = ["drive1.apply", "state1", "master1.control", "cmd1", "drive1.apply"]
    data["flows"].append({"name": "loop1", "chain": chain})
    return data


def test_two_live_masters_share_one_simulation(tmp_path: Path) -> None:
    """Two CANopen buses, each with its live master (each in a thread of its own, one running at a time): 1 s
    gives 500 cycles of 2 ms and 250 of 4 ms, no overrun, both loops inside their analysed ranges, and the same
    figures from two runs with the same seed (deterministic)."""
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(two_masters(), sort_keys=False), encoding="utf-8")
    assert check(path)["ok"]
    outs = [cli("simulate", str(path), "--duration", "1s", "--seed", "3", "--format", "json") for _ in range(2)]
    for r in outs:
        assert r.returncode == 0, r.stdout + r.stderr
    docs = [json.loads(r.stdout) for r in outs]
    for doc in docs:
        doc.pop("speed", None)
    assert docs[0] == docs[1]
    doc = docs[0]
    assert [doc["protocols"][b][0]["cycles"] for b in ("can0", "can1")] == [500, 250]
    assert all(doc["protocols"][b][0]["overruns"] == 0 for b in ("can0", "can1"))
    for f in doc["flows"]:
        assert f["samples"] > 200 and f["within_analysis"], f


def test_the_master_computes_once_per_cycle(tmp_path: Path) -> None:
    """The live master computes once per cycle and then writes its RxPDOs; a second SYNC task on the master would be
    analysed as something it does not run, so check refuses it and names it."""
    data = repro12_data()
    data["nodes"][0]["tasks"].append({"name": "log", "sync": True, "offset": "1500 us", "wcet": "50 us"})
    report = check_data(tmp_path, data)
    assert [e["code"] for e in report["errors"]] == ["master-cycle"]
    assert "2 SYNC tasks on bus 'can0' ('master.control', 'master.log')" in report["errors"][0]["message"]


def test_a_runtime_json_without_master_jitter_reads_as_an_ideal_master() -> None:
    """runtime.json files written before canopen.master_jitter_ns load with 0, the schema's default."""
    from netcfg.runtime import parse

    doc = json.loads((ROOT / "generated" / "allex2" / "runtime.json").read_text(encoding="utf-8"))
    assert doc["buses"][0]["canopen"].pop("master_jitter_ns") == 13_000
    assert parse(doc).bus("can0").canopen.master_jitter_ns == 0  # type: ignore[union-attr]
