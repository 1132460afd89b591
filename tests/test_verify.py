"""`netcfg verify`: a recorded CAN log held against the spec and its analysis.

The logs here are what `netcfg simulate --log` records for ALLEX-2 (seed 000: SYNC every 20 ms, an 8 s gait cycle
of 400 samples per drive), edited frame by frame where a test needs a fault, and written back through python-can's
own writers (candump -L, Vector ASC and BLF). Bounds come from the runtime configuration the analysis wrote
(`wcrt_ns`), never from this file.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import can
import pytest
from conftest import ROOT, SPECS, cli
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from netcfg import runtime
from netcfg.verify import check_frames, verify_log
from netcfg.verify.logs import read_log

ALLEX2 = SPECS / "allex2.yaml"
RUNTIME = ROOT / "generated" / "allex2" / "runtime.json"
GAIT_SAMPLES = 400  # seed 000: 8 s gait cycle, SYNC every 20 ms


@pytest.fixture(scope="module")
def cfg() -> runtime.RuntimeConfig:
    return runtime.load(RUNTIME)


@pytest.fixture(scope="module")
def undeclared(tmp_path_factory: pytest.TempPathFactory) -> runtime.RuntimeConfig:
    """specs/allex2.yaml without its `<joint>_command` flows: only hip_l_cmd is declared as sent by master.control
    (the joint_command flow), the other five commands by no task, although the master sends them all alike."""
    import yaml

    from netcfg.check import analyse_spec
    from netcfg.emit import runtime_json

    spec = yaml.safe_load(ALLEX2.read_text(encoding="utf-8"))
    spec["flows"] = [f for f in spec["flows"] if f["name"] in ("joint_feedback", "joint_command")]
    path = tmp_path_factory.mktemp("undeclared") / "allex2.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    model, report = analyse_spec(path)
    assert model is not None and report["ok"], report["errors"]
    return runtime.parse(json.loads(runtime_json.emit(model, report)["runtime.json"]))


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The simulated ALLEX-2 network's 8 s gait cycle as a candump -L log, recorded by `netcfg simulate --log`."""
    log = tmp_path_factory.mktemp("verify") / "gait.log"
    proc = cli("simulate", str(ALLEX2), "--duration", "8s", "--log", str(log))
    assert proc.returncode == 0, proc.stderr
    return log


def frames_of(log: Path) -> list[can.Message]:
    with can.LogReader(str(log)) as reader:
        return list(reader)


def write(frames: list[can.Message], path: Path) -> Path:
    frames = sorted(frames, key=lambda m: m.timestamp)
    with can.Logger(str(path)) as writer:
        for m in frames:
            writer.on_message_received(m)
    return path


def verify_json(*args: str) -> tuple[int, dict[str, Any], str]:
    proc = cli("verify", *args, "--format", "json")
    return proc.returncode, json.loads(proc.stdout) if proc.stdout else {}, proc.stderr


def inject_faults(cfg: runtime.RuntimeConfig, frames: list[can.Message]) -> tuple[list[can.Message], dict[str, Any]]:
    """The recorded frames with three faults: hip_l_effort's 100th frame removed (a gap of one period; hip_l_cmd, sent
    by the master when its control step ends, is allowed a spread so wide that a log cannot tell a missing frame from
    a late one), hip_l_state's 200th frame moved to 500 us after its SYNC (the analysis allows wcrt_ns), one frame
    with identifier 0x555."""
    effort = cfg.message("hip_l_effort")
    state = cfg.message("hip_l_state")
    sync_id = cfg.bus("can0").canopen.sync_id  # type: ignore[union-attr]
    out = list(frames)
    efforts = [m for m in out if m.arbitration_id == effort.id]
    removed = efforts[99]
    out.remove(removed)
    states = [m for m in out if m.arbitration_id == state.id]
    moved = states[199]
    sync_before = max(m.timestamp for m in out if m.arbitration_id == sync_id and m.timestamp < moved.timestamp)
    moved.timestamp = sync_before + 500e-6
    stranger = can.Message(timestamp=frames[len(frames) // 2].timestamp + 1e-6, channel="can0", arbitration_id=0x555,
                           is_extended_id=False, data=b"\x01\x02")
    out.append(stranger)
    facts = {
        "gap_at": efforts[100].timestamp,
        "late_at": moved.timestamp,
        "late_by_us": 500 - state.wcrt_ns / 1000,  # type: ignore[operator]
        "unknown_at": stranger.timestamp,
    }
    return out, facts


def test_the_simulated_allex2_log_passes(recorded: Path) -> None:
    """Every periodic message came 8 s / its period times: the SYNC and the PDOs 400 (seed 000's 400 samples in
    8 s), the drives' heartbeats 80 (every 100 ms, as the spec sets them); nothing outside the analysis."""
    code, report, err = verify_json(str(ALLEX2), str(recorded))
    assert code == 0, err
    assert report["ok"] and report["violations"] == [] and report["unknown_ids"] == []
    for m in report["messages"]:
        if m["kind"] == "periodic":
            assert m["count"] == round(8_000_000 / m["nominal_period_us"]), m["name"]
            assert m["missing"] == 0 and m["within_analysis"] is True
    assert sum(m["count"] == GAIT_SAMPLES for m in report["messages"]) == 1 + 6 * 3  # SYNC, 3 PDOs per drive
    bus = report["buses"][0]
    assert bus["canopen"]["sync"]["count"] == GAIT_SAMPLES
    # every synchronous TPDO arrived inside the synchronous window (10 ms, seed 000)
    assert all(p["inside_window"] for p in bus["canopen"]["synchronous_pdos"])
    assert bus["canopen"]["sync_window_us"] == 10_000


def test_a_gap_a_late_frame_and_an_unknown_identifier_are_exactly_three_violations(
    recorded: Path, cfg: runtime.RuntimeConfig, tmp_path: Path
) -> None:
    frames, facts = inject_faults(cfg, frames_of(recorded))
    log = write(frames, tmp_path / "faulty.log")
    code, report, err = verify_json(str(RUNTIME), str(log))
    assert code == 1
    start = min(m.timestamp for m in frames)
    got = {v["kind"]: v for v in report["violations"]}
    assert len(report["violations"]) == 3 and set(got) == {"gap", "late", "unknown_id"}
    assert got["gap"]["message"] == "hip_l_effort"
    assert got["gap"]["time_us"] == round((facts["gap_at"] - start) * 1e6)
    assert "1 period missing" in got["gap"]["detail"]
    assert got["late"]["message"] == "hip_l_state"
    assert got["late"]["time_us"] == round((facts["late_at"] - start) * 1e6)
    assert f"{facts['late_by_us']:.0f} us late" in got["late"]["detail"]
    assert got["unknown_id"]["time_us"] == round((facts["unknown_at"] - start) * 1e6)
    assert report["unknown_ids"] == [
        {"bus": "can0", "id": 0x555, "extended": False, "count": 1, "first_us": got["unknown_id"]["time_us"]}
    ]
    gapped = next(m for m in report["messages"] if m["name"] == "hip_l_effort")
    assert gapped["missing"] == 1 and gapped["count"] == GAIT_SAMPLES - 1
    # one line per violation on stderr: the log, when, what, which message, by how much
    lines = err.strip().splitlines()
    assert len(lines) == 3 and all(line.startswith(f"{log}: ") for line in lines)
    assert any("late: hip_l_state:" in line and f"{facts['late_by_us']:.0f} us late" in line for line in lines)


def test_asc_and_blf_written_by_python_can_give_identical_reports(
    recorded: Path, cfg: runtime.RuntimeConfig, tmp_path: Path
) -> None:
    """The same frames through python-can's ASC and BLF writers (and its candump, PCAN TRC and CSV ones). ASC counts
    time from its first frame and BLF keeps the absolute time, so the reports differ only in `start_us` (where the
    log's clock started) and `log`."""
    frames, _ = inject_faults(cfg, frames_of(recorded))
    reports = []
    for suffix in (".asc", ".blf", ".log", ".trc", ".csv"):
        report = verify_log(cfg, write(frames, tmp_path / f"same{suffix}"))
        reports.append({k: v for k, v in report.items() if k not in ("start_us", "log")})
    assert all(r == reports[0] for r in reports)
    assert reports[0]["violation_count"] == 3


def test_the_vectorised_candump_reader_matches_python_cans(recorded: Path, cfg: runtime.RuntimeConfig) -> None:
    fast = verify_log(cfg, recorded)
    reference = verify_log(cfg, recorded, fast=False)
    assert fast == reference


def _columns(path: Path, fast: bool) -> list[tuple[Any, ...]]:
    channels, batches = read_log(path, fast=fast)
    rows: list[tuple[Any, ...]] = []
    for b in batches:
        for i in range(len(b)):
            rows.append((int(b.t_us[i]), channels.names[b.channel[i]], int(b.can_id[i]), int(b.flags[i]),
                         int(b.length[i]), bytes(b.data[i])))
    return rows


frame_strategy = st.builds(
    lambda ts, ch, ext, ident, data, kind: (ts, ch, ext, ident if ext else ident & 0x7FF, data, kind),
    st.integers(0, 2_000_000_000_000_000),
    st.sampled_from(["can0", "vcan1", "7"]),
    st.booleans(),
    st.integers(0, (1 << 29) - 1),
    st.binary(max_size=8),
    st.sampled_from(["data", "data", "data", "remote", "fd", "error"]),
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(frame_strategy, max_size=30))
def test_vectorised_and_python_can_readers_agree_on_any_candump_file(
    tmp_path: Path, frames: list[tuple[Any, ...]]
) -> None:
    """Data, remote, CAN FD and error frames, 11- and 29-bit, several interfaces, microsecond times."""
    msgs = []
    for ts, ch, ext, ident, data, kind in sorted(frames, key=lambda f: f[0]):
        t = ts / 1e6
        if kind == "error":
            msgs.append(can.Message(timestamp=t, channel=ch, is_error_frame=True))
        elif kind == "remote":
            msgs.append(can.Message(timestamp=t, channel=ch, arbitration_id=ident, is_extended_id=ext,
                                    is_remote_frame=True, dlc=len(data)))
        else:
            msgs.append(can.Message(timestamp=t, channel=ch, arbitration_id=ident, is_extended_id=ext, data=data,
                                    is_fd=kind == "fd"))
    path = tmp_path / "any.log"
    with can.CanutilsLogWriter(str(path)) as writer:
        for m in msgs:
            writer.on_message_received(m)
    assert _columns(path, fast=True) == _columns(path, fast=False)


def test_canopen_services_are_listed_not_unknown(
    recorded: Path, cfg: runtime.RuntimeConfig, tmp_path: Path
) -> None:
    """CiA 301's predefined connection set: heartbeat 0x700 + node id (state byte: 0x05 operational, 0x7F
    pre-operational), EMCY 0x080 + node id, NMT 0x000 (command, node). hip_l's recorded heartbeats are replaced by
    two of ours (the simulated drives send 0x00 in theirs)."""
    hip_l = cfg.node("hip_l").node_id
    assert hip_l is not None
    frames = [m for m in frames_of(recorded) if m.arbitration_id != 0x700 + hip_l]
    t0 = frames[0].timestamp
    extra = [
        can.Message(timestamp=t0 + 0.0001, channel="can0", arbitration_id=0x000, is_extended_id=False,
                    data=bytes([0x01, 0x00])),
        can.Message(timestamp=t0 + 0.5, channel="can0", arbitration_id=0x700 + hip_l, is_extended_id=False,
                    data=b"\x7f"),
        can.Message(timestamp=t0 + 1.5, channel="can0", arbitration_id=0x700 + hip_l, is_extended_id=False,
                    data=b"\x05"),
        can.Message(timestamp=t0 + 2.5, channel="can0", arbitration_id=0x080 + hip_l, is_extended_id=False,
                    data=bytes([0x10, 0x81, 0x11, 0, 0, 0, 0, 0])),
    ]
    report = verify_log(cfg, write(frames + extra, tmp_path / "services.log"))
    assert report["unknown_ids"] == []
    co = report["buses"][0]["canopen"]
    assert co["nmt_commands"] == [{"time_us": 100, "command": "start", "node": "all nodes"}]
    assert [(s["time_us"], s["state"]) for s in co["nmt_states"] if s["node"] == "hip_l"] == [
        (500_000, "pre-operational"), (1_500_000, "operational")]
    assert co["heartbeats"]["hip_l"] == {"count": 2, "state": "operational"}
    assert co["emcy"] == [{"time_us": 2_500_000, "node": "hip_l", "code": "0x8110", "register": 0x11}]
    assert [t for t in (s["time_us"] for s in co["nmt_states"])] == sorted(s["time_us"] for s in co["nmt_states"])


def test_signals_outside_the_specs_limits(cfg: runtime.RuntimeConfig) -> None:
    """A limit on hip_l_state.position_actual_value (the spec's `min`/`max`), frames encoded by netcfg.runtime."""
    doc = json.loads(RUNTIME.read_text(encoding="utf-8"))
    for m in doc["messages"]:
        if m["name"] == "hip_l_state":
            for s in m["signals"]:
                if s["name"] == "position_actual_value":
                    s["min"], s["max"] = -1000, 4000
    limited = runtime.parse(doc)
    msg = cfg.message("hip_l_state")  # the same layout without the limits, which the codec would enforce
    positions = [0, 4000, 5000, -1500, 100]
    frames = [
        (i * 20_000_000, "can0", msg.id, False, msg.encode(position_actual_value=p, velocity_actual_value=0))
        for i, p in enumerate(positions)
    ]
    report = check_frames(limited, frames)
    ranges = [v for v in report["violations"] if v["kind"] == "range"]
    assert len(ranges) == 1 and ranges[0]["message"] == "hip_l_state"
    assert ranges[0]["time_us"] == 40_000  # the third frame, 2 periods after the first
    assert "in 2 frame(s), worst 5000" in ranges[0]["detail"]  # 5000 is 1000 above 4000, -1500 500 below -1000


def test_a_flooded_window_exceeds_the_analysed_load(
    recorded: Path, cfg: runtime.RuntimeConfig, tmp_path: Path
) -> None:
    """500 extra 8-byte frames of hip_l_cmd within one 100 ms window: at least 500 x 135 bits (55 + 10 x 8, worst
    stuffing, Davis et al. 2007) = 67.5 ms of a 1 Mbit/s bus, more than any window can carry by the analysis."""
    frames = frames_of(recorded)
    t0 = frames[0].timestamp + 1.0
    flood = [can.Message(timestamp=t0 + i * 150e-6, channel="can0", arbitration_id=0x201, is_extended_id=False,
                         data=bytes(8)) for i in range(500)]
    report = verify_log(cfg, write(frames + flood, tmp_path / "flood.log"))
    loads = [v for v in report["violations"] if v["kind"] == "load"]
    assert loads and all("bus can0" in v["detail"] for v in loads)
    assert report["buses"][0]["load"]["max"] >= 500 * 135 / 100_000


def test_unreadable_logs_exit_2_without_a_traceback(
    tmp_path: Path, recorded: Path, cfg: runtime.RuntimeConfig
) -> None:
    from netcfg.verify import LogError

    garbage = tmp_path / "garbage.log"
    garbage.write_text("this is not a candump log\n", encoding="utf-8")
    blf = tmp_path / "broken.blf"
    blf.write_bytes(b"LOGG" + bytes(40))
    for log in (garbage, blf):  # the command line: exit 2, one line, no traceback
        proc = cli("verify", str(RUNTIME), str(log))
        assert proc.returncode == 2, (log, proc.stderr)
        assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    # a damaged line is named by its number: here the 101st, after 100 good ones
    lines = recorded.read_text(encoding="ascii").splitlines(keepends=True)
    damaged = tmp_path / "damaged.log"
    damaged.write_text("".join([*lines[:100], "(0.5) can0 12X#00\n", *lines[100:]]), encoding="ascii")
    unknown_suffix = tmp_path / "gait.txt"
    unknown_suffix.write_bytes(recorded.read_bytes())
    for log, fmt, says in (
        (damaged, None, f"{damaged}:101: not a candump -L line: '(0.5) can0 12X#00'"),
        (blf, None, f"{blf}: not a readable log"),
        (tmp_path / "absent.log", None, "no such file"),
        (recorded, "xyz", "--log-format 'xyz'"),
        (unknown_suffix, None, "give --log-format"),
    ):
        with pytest.raises(LogError, match=re.escape(says)):
            verify_log(cfg, log, log_format=fmt)
    assert verify_log(cfg, unknown_suffix, log_format="candump")["ok"]


def test_simulate_holds_its_trace_with_the_same_checker(tmp_path: Path) -> None:
    """CAMBADA on FTT-CAN. The simulator sends every frame with worst-case stuffing, so each synchronous message's
    latest end is its analysed worst case from the EC start; the log stamps the trigger message's end, and verify
    adds back the trigger message's shortest time: 5 bytes at 250 kbit/s, 47 + 8 x 5 = 87 bits against the worst
    55 + 10 x 5 = 105 (Davis et al. 2007, eq. 1), so the measured worst is the analysed one less 18 bits, 72 us."""
    log = tmp_path / "cambada.log"
    proc = cli("simulate", str(SPECS / "cambada.yaml"), "--duration", "1s", "--log", str(log), "--format", "json")
    assert proc.returncode == 0, proc.stderr
    check = json.loads(proc.stdout)["log_check"]
    assert check["ok"] and check["violation_count"] == 0
    # the file it wrote gives the same verdict through netcfg verify
    code, report, _ = verify_json(str(SPECS / "cambada.yaml"), str(log))
    assert code == 0
    synchronous = [m for m in report["messages"] if m["response_from"] == "tm"]
    assert len(synchronous) == 8  # the SRT of seed 002, Table 2: FTT ids 0-7
    for m in synchronous:
        assert m["response_us"]["max"] == m["wcrt_us"] - 72, m["name"]


def test_simulate_keeps_its_two_violation_lists_apart(tmp_path: Path) -> None:
    """`violations` answers "did a measured range leave its analysed one" (one line per message or flow, beside
    `exceeds_analysis`); `log_check.violations` is the written trace judged frame by frame by verify's checker,
    in verify's own shape. One lost hip_l_state (ALLEX-2's TxPDO1 of node 1, every 20 ms SYNC) is a gap in the
    trace, not a response beyond its bound: the first list stays empty, the second names the gap, and the lost
    frame alone makes the exit code 1."""
    log = tmp_path / "allex2.log"
    proc = cli(
        "simulate", str(SPECS / "allex2.yaml"), "--duration", "200ms", "--fault", "lose:hip_l_state@100ms",
        "--log", str(log), "--format", "json",
    )
    assert proc.returncode == 1, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["lost"] == 1
    assert doc["violations"] == [] and doc["exceeds_analysis"] == []
    check = doc["log_check"]
    assert not check["ok"] and check["violation_count"] == len(check["violations"]) >= 1
    for v in check["violations"]:
        assert set(v) == {"kind", "message", "time_us", "detail"}  # verify's JSON contract
    assert ("gap", "hip_l_state") in {(v["kind"], v["message"]) for v in check["violations"]}
    _, report, _ = verify_json(str(SPECS / "allex2.yaml"), str(log))
    assert [(v["kind"], v["message"]) for v in report["violations"]] == [
        (v["kind"], v["message"]) for v in check["violations"]
    ]


def test_report_plots_are_deterministic(recorded: Path, cfg: runtime.RuntimeConfig, tmp_path: Path) -> None:
    from netcfg.verify.plots import draw

    report = verify_log(cfg, recorded)
    report["messages"] = [m for m in report["messages"] if m["name"] in ("can0_SYNC", "hip_l_state")]
    first = draw(report, tmp_path / "a")
    second = draw(report, tmp_path / "b")
    assert [Path(p).name for p in first] == ["period_can0_SYNC.png", "period_hip_l_state.png",
                                             "response_hip_l_state.png", "load_can0.png"]
    for a, b in zip(first, second):
        assert Path(a).read_bytes() == Path(b).read_bytes()


def simulated_log(name: str, duration_ns: int, path: Path) -> runtime.RuntimeConfig:
    """The simulator's trace of generated/<name>/runtime.json, written as `simulate --log` writes it."""
    from netcfg.sim.can_trace import trace_frames
    from netcfg.sim.montecarlo import run_once
    from netcfg.sim.scenario import SimOptions
    from netcfg.sim.trace import write_trace

    cfg = runtime.load(ROOT / "generated" / name / "runtime.json")
    sc, _ = run_once(cfg, SimOptions(duration_ns=duration_ns, trace=True))
    write_trace(trace_frames(sc), path)
    return cfg


def test_a_multi_bus_log_maps_channels_to_buses(tmp_path: Path) -> None:
    """large_plant's three buses: the simulator names each frame's channel after its bus; the same frames under
    numbered channels need --bus CHANNEL=BUS and then give the same report."""
    named = tmp_path / "plant.log"
    plant = simulated_log("large_plant", 300_000_000, named)
    frames = frames_of(named)
    buses = sorted({str(m.channel) for m in frames})
    assert len(buses) == 3
    for m in frames:
        m.channel = f"vcan{buses.index(str(m.channel))}"
    numbered = write(frames, tmp_path / "numbered.log")
    proc = cli("verify", str(ROOT / "generated" / "large_plant" / "runtime.json"), str(numbered))
    assert proc.returncode == 2 and "--bus vcan0=BUS" in proc.stderr
    by_name = verify_log(plant, named)
    by_map = verify_log(plant, numbered, bus={f"vcan{i}": b for i, b in enumerate(buses)})
    assert by_map["frames"] == len(frames) and by_map["unknown_ids"] == []
    assert {k: v for k, v in by_map.items() if k != "log"} == {k: v for k, v in by_name.items() if k != "log"}


def test_a_live_master_feeds_python_can_messages(recorded: Path, cfg: runtime.RuntimeConfig) -> None:
    """The checker a master calls (Checker.feed_messages) gives the report `netcfg verify` gives for the log, but for
    what only a first read of the whole log can tell (netcfg.verify.api): its fault phases and whose clock stamped
    it; this log has no fault and the simulator's, a wire's, clock."""
    from netcfg.verify import Checker

    checker = Checker(cfg)
    frames = frames_of(recorded)
    for start in range(0, len(frames), 1000):  # as frames arrive, in pieces
        checker.feed_messages(frames[start : start + 1000])
    live = checker.finish()
    whole = verify_log(cfg, recorded)
    first_read = ("fault_phases", "phase_sequence", "fault_count", "timestamps")
    assert live == {k: v for k, v in whole.items() if k != "log" and k not in first_read}
    assert whole["fault_count"] == 0 and whole["timestamps"]["clock"] == "wire"


def test_the_analysed_utilisation_is_the_analysis_own(tmp_path: Path) -> None:
    """verify compares the measured load with the analysis' utilisation over every frame a log shows: on CAN the
    report's figure (ALLEX-2), on FTT-CAN the report's load plus its trigger-message overhead (CAMBADA: seed 002's
    27 % bus load and 8.4 % TM overhead)."""
    from conftest import check

    for name in ("allex2", "cambada"):
        log = tmp_path / f"{name}.log"
        system = simulated_log(name, 100_000_000, log)
        analysed = check(SPECS / f"{name}.yaml")["buses"][0]
        verified = verify_log(system, log)["buses"][0]
        extra = analysed["ftt"]["tm_overhead"] if "ftt" in analysed else 0.0
        assert verified["utilization_analysed"] == pytest.approx(analysed["utilization"] + extra, abs=1e-6)
        if name == "cambada":
            assert verified["utilization_analysed"] == pytest.approx(0.27 + 0.084, abs=0.001)


def test_error_frames_are_one_violation_with_their_count(cfg: runtime.RuntimeConfig) -> None:
    sync = cfg.message("can0_SYNC")
    frames: list[tuple[Any, ...]] = [(i * 20_000_000, "can0", sync.id, False, b"") for i in range(10)]
    frames += [(30_000_000 + i * 1000, "can0", 0, False, b"", True) for i in range(3)]
    report = check_frames(cfg, sorted(frames, key=lambda f: f[0]))
    errors = [v for v in report["violations"] if v["kind"] == "error_frames"]
    assert report["error_frames"] == 3 and len(errors) == 1
    assert errors[0]["time_us"] == 30_000 and errors[0]["detail"].startswith("3 error frame(s)")


def test_usage_problems(recorded: Path, tmp_path: Path) -> None:
    """A spec with errors is exit 1 (its errors named); a system without a CAN bus, an unknown bus, exit 2."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("system: x\nbuses: [\n", encoding="utf-8")
    proc = cli("verify", str(bad), str(recorded))
    assert proc.returncode == 1 and f"{bad}:3:1: error:" in proc.stderr and "no log was checked" in proc.stderr
    proc = cli("verify", str(ROOT / "generated" / "ntua_sahr" / "runtime.json"), str(recorded))
    assert proc.returncode == 2 and "no CAN bus" in proc.stderr
    proc = cli("verify", str(RUNTIME), str(recorded), "--bus", "can9")
    assert proc.returncode == 2 and "no bus named 'can9'" in proc.stderr


@settings(max_examples=40, deadline=None)
@given(offsets=st.lists(st.floats(-0.5, 0.5), min_size=6, max_size=40), data=st.data())
def test_jitter_inside_the_analysis_is_quiet_and_a_dropped_frame_is_one_gap(
    offsets: list[float], data: st.DataObject, undeclared: runtime.RuntimeConfig
) -> None:
    """knee_l_cmd every 20 ms, each frame moved by at most half the analysed slack (worst-case response, which
    holds the release jitter, - best transmission time), so every interval is within period +- slack: no gap, no
    warning. Without one frame (not the first or the last): exactly one gap of one period, at the frame after it.
    The allex2 variant where no task is declared to send knee_l_cmd: its bound is the master's FIFO queue alone
    (2,880 us); declared as sent by master.control it also carries the control step's spread (11,224.5 us, more
    than half a period), and a log can then not tell a missing frame from a late one and an early one."""
    cfg = undeclared
    cmd = cfg.message("knee_l_cmd")
    assert cmd.period_ns is not None and cmd.wcrt_ns is not None
    from netcfg.timing.frames import bits_to_ns, can_frame_bits

    slack_ns = cmd.wcrt_ns - bits_to_ns(can_frame_bits(cmd.size, cmd.extended, "nominal"), 1_000_000)
    times = [k * cmd.period_ns + int(o * (slack_ns - 2000)) for k, o in enumerate(offsets)]  # 2 us for rounding
    frames = [(t, "can0", cmd.id, False, bytes(cmd.size)) for t in times]

    def about_cmd(report: dict[str, Any]) -> list[tuple[str, Any]]:
        return [(v["kind"], v["time_us"]) for v in report["violations"] + report["warnings"]
                if v["message"] == cmd.name]

    assert about_cmd(check_frames(cfg, frames)) == []
    drop = data.draw(st.integers(1, len(frames) - 2))
    report = check_frames(cfg, frames[:drop] + frames[drop + 1 :])
    first = (times[0] + 500) // 1000
    assert about_cmd(report) == [("gap", (times[drop + 1] + 500) // 1000 - first)]


def test_a_message_sent_by_a_task_may_stray_by_the_tasks_spread(
    recorded: Path, cfg: runtime.RuntimeConfig, undeclared: runtime.RuntimeConfig
) -> None:
    """hip_l_cmd goes out when master.control finishes (runtime.json's sent_by): control runs 10 ms after SYNC for
    225.8-8557.3 us (seed 000, Table 5). The analysis counts that spread as the command's release jitter, so its
    worst-case response from the nominal release holds it (Davis et al. 2007, eq. 13: R = J + w + C), and its
    interval may stray from 20 ms by R less its best transmission (8 bytes: 47 + 64 = 111 bits, 111 us at
    1 Mbit/s). specs/allex2.yaml declares all six commands so (seed 000 section 4.4.1: the control step sends
    every command frame): none draws a warning. Declared by no task (the `undeclared` variant), knee_l_cmd, sent
    the same way by the simulated master, has no such jitter in its analysis, and its intervals draw a warning."""
    report = verify_log(cfg, recorded)
    by_name = {m["name"]: m for m in report["messages"]}
    cmd = cfg.message("hip_l_cmd")
    assert cmd.sent_by == ("master.control",) and cmd.wcrt_ns is not None
    assert cmd.wcrt_ns >= 8_557_300 - 225_800  # the control step's spread is inside the analysed response
    assert by_name["hip_l_cmd"]["analysed_jitter_us"] == pytest.approx((cmd.wcrt_ns - 111_000) / 1000)
    assert by_name["hip_l_cmd"]["warnings"] == 0
    assert report["ok"] and report["warning_count"] == 0
    assert all(by_name[m.name]["warnings"] == 0 for m in cfg.messages if m.name.endswith("_cmd"))
    assert {m.name for m in cfg.messages if m.sent_by == ("master.control",)} == {
        f"{joint}_cmd" for joint in ("hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r")
    }
    loose = {m["name"]: m for m in verify_log(undeclared, recorded)["messages"]}
    assert loose["knee_l_cmd"]["warnings"] == 1 and loose["hip_l_cmd"]["warnings"] == 0


def test_strict_makes_undeclared_jitter_a_violation(
    recorded: Path, cfg: runtime.RuntimeConfig, undeclared: runtime.RuntimeConfig
) -> None:
    """The five command RxPDOs that no task is declared to send in the `undeclared` variant (runtime.json's
    sent_by) stray beyond their own analysed jitter in the simulated cycle (see the test above): with strict, one
    jitter violation each. The spec as it is declares them, and strict finds nothing."""
    loose = {m.name for m in undeclared.messages if m.name.endswith("_cmd") and not m.sent_by}
    assert len(loose) == 5
    report = verify_log(undeclared, recorded, strict=True)
    assert {(v["kind"], v["message"]) for v in report["violations"]} == {("jitter", n) for n in loose}
    assert report["violation_count"] == 5 and not report["ok"]
    assert verify_log(cfg, recorded, strict=True)["ok"]


def test_a_progress_bar_only_on_a_terminal(monkeypatch: pytest.MonkeyPatch, recorded: Path) -> None:
    import io

    from netcfg.commands import verify as verify_cli

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    for stream, shown in ((Terminal(), True), (io.StringIO(), False)):
        monkeypatch.setattr("sys.stderr", stream)
        _, batches = read_log(recorded, progress=verify_cli._progress)
        assert sum(len(b) for b in batches) > 0
        verify_cli._progress_done()
        assert ("100% of the log" in stream.getvalue()) is shown


def test_the_rate_check_takes_the_bus_clock_tolerance(tmp_path: Path) -> None:
    """A sender 4,000 ppm slow sends a 10 ms message 998 times in 10 s: a bus that allows +-5,000 ppm
    (clock_tolerance) expects at least floor(9.994 s x (1 - 0.005) / 10 ms) + 1 = 995 of them, so the log is inside
    the analysis; with the default 100 ppm it needs 1,000, and the same log breaks the rate check."""
    spec = tmp_path / "tol.yaml"
    text = (
        "system: tol\n"
        "buses:\n  - {name: can0, protocol: can, bitrate: 500k, clock_tolerance: 5000}\n"
        "nodes:\n  - {name: a, buses: [can0]}\n  - {name: b, buses: [can0]}\n"
        "messages:\n"
        "  - {name: m1, id: 0x100, producer: a, consumers: [b], size: 8, period: 1 ms}\n"
        "  - {name: m2, id: 0x200, producer: b, consumers: [a], size: 8, period: 10 ms}\n"
    )
    spec.write_text(text, encoding="utf-8")
    log = tmp_path / "drift.log"
    sim = cli("simulate", str(spec), "--duration", "10s", "--drift", "4000", "--seed", "3", "--log", str(log))
    assert sim.returncode == 0, sim.stderr
    assert cli("verify", str(spec), str(log)).returncode == 0
    spec.write_text(text.replace("clock_tolerance: 5000", "clock_tolerance: 100"), encoding="utf-8")
    strict = cli("verify", str(spec), str(log), "--format", "json")
    assert strict.returncode == 1 and "rate" in json.loads(strict.stdout)["violations_by_kind"]
