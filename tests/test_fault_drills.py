"""Faults the live master (`netcfg run`) survives, drilled on netcfg's simulated drives: a drive that reboots.

Sources of the numbers:
- specs/allex2.yaml (generated/allex2/runtime.json): six EPOS4 drives, node ids 1-6, SYNC period T = 20 ms, read
  window 10 ms, heartbeat 100 ms, the master's consumer heartbeat time 300 ms, on_loss: stop_node; on_reboot is not
  given, so it is the default stop_node.
- CiA 301 7.2.8.3.2.1: a node that boots sends the boot-up message, the heartbeat COB-ID 0x700 + node id with the one
  data byte 0x00, and enters PRE-OPERATIONAL; its object dictionary holds its defaults again (the simulated drive's
  factory state has every PDO disabled). CiA 402: after initialisation the drive is in SWITCH ON DISABLED.
- When a drill happens: drills run after the first cycle that ends at or after their time, so at most one period
  T late; the master reads the bus once per cycle (its read window) and checks after it, so a frame is seen at most
  one period after it was sent. A boot-up at T_drill + outage is therefore reported within [T_drill + outage,
  T_drill + outage + 2 T], plus SLACK_S for the host's threads (the drives answer from threads of this process).
"""

from __future__ import annotations

import json
import time
import uuid
from dataclasses import replace
from pathlib import Path

import can
import pytest
from conftest import ROOT, allex2_cia402_over_pdos, cli

import netcfg.runtime as rt
from netcfg.runtime.cia402 import OPERATION_ENABLED, SWITCH_ON_DISABLED
from netcfg.runtime.drives import DriveBench
from netcfg.runtime.operate import BusLog, Outcome, Plan, operate

pytestmark = pytest.mark.usefixtures("no_leaked_threads")  # conftest.py

GENERATED = ROOT / "generated" / "allex2"
PERIOD_S = 0.020  # allex2's SYNC period
SLACK_S = 0.050  # thread scheduling on a loaded host: the drives and the master share one interpreter


@pytest.fixture(scope="module")
def cfg() -> rt.RuntimeConfig:
    return rt.load(GENERATED / "runtime.json")




def with_on_reboot(cfg: rt.RuntimeConfig, action: str) -> rt.RuntimeConfig:
    return replace(cfg, nodes=tuple(replace(n, on_reboot=action) if n.role == "slave" else n for n in cfg.nodes))


def drill_run(cfg: rt.RuntimeConfig, cycles: int, at_s: float, outage_s: float) -> tuple[Outcome, DriveBench]:
    channel = f"faults-{uuid.uuid4().hex[:8]}"
    bench = DriveBench(cfg, GENERATED / "canopen", channel=channel).start()
    try:
        with BusLog(can.Bus(interface="virtual", channel=channel), None) as bus:
            plan = Plan(cycles=cycles, drills=[(at_s, "knee_r reboots", lambda: bench["knee_r"].reboot(outage_s))])
            out = operate(cfg, bus, plan)
        return out, bench
    finally:
        bench.stop()


def kinds(out: Outcome) -> list[tuple[str, str, str]]:
    return [(e.node, e.kind, e.action) for _, e in out.events]


def drive_kinds(out: Outcome) -> list[tuple[str, str, str]]:
    """The events of a drill on a drive: the master's own missed SYNCs left out, which a wall-clock master on a
    loaded host may report whatever the drill (the drills that cause them assert them with kinds)."""
    return [k for k in kinds(out) if k[:2] != ("master", "missed-sync")]


def assert_boot_up_in_time(out: Outcome, at_s: float, outage_s: float) -> float:
    ((drill_s, _),) = out.drills
    assert at_s <= drill_s <= at_s + PERIOD_S + SLACK_S
    boot_s = next(t for t, e in out.events if e.kind == "boot-up")
    # the drive's scheduler never fires early, and the drill's time is taken before its action runs
    assert drill_s + outage_s <= boot_s <= drill_s + outage_s + 2 * PERIOD_S + SLACK_S
    return boot_s


def test_a_rebooted_drive_is_set_up_again_and_enabled_with_recover(cfg: rt.RuntimeConfig) -> None:
    """on_reboot: recover. The drive comes back with its default dictionary; the master checks its identity, writes
    and reads back its PDOs and start-up values (the set-up's code path), starts it and walks it to OPERATION ENABLED
    over SDO while the others keep cycling."""
    out, bench = drill_run(with_on_reboot(cfg, "recover"), 40, 0.2, 0.05)
    assert drive_kinds(out) == [("knee_r", "boot-up", "recover"), ("knee_r", "recovered", "continue")]
    boot_s = assert_boot_up_in_time(out, 0.2, 0.05)
    knee = out.nodes["knee_r"]
    (reboot,) = knee.reboots
    ((drill_s, _),) = out.drills
    assert reboot["at_s"] == round(boot_s, 6) and reboot["result"] == "recovered"
    # the recovery's time is the time from the boot-up to the end of the CiA 402 walk, measured on the master's clock
    recovered_s = next(t for t, e in out.events if e.kind == "recovered")
    assert abs(reboot["recovery_ms"] - 1e3 * (recovered_s - boot_s)) < 0.01
    assert knee.state == OPERATION_ENABLED
    drive = bench["knee_r"]
    assert drive.reboots == 1
    # it went through the power state machine again from SWITCH ON DISABLED (CiA 402 transitions 2, 3, 4)
    assert drive.power is not None and [s for _, s in drive.power.history][:4] == [
        SWITCH_ON_DISABLED,
        "READY TO SWITCH ON",
        "SWITCHED ON",
        OPERATION_ENABLED,
    ]
    # its four PDOs of runtime.json (knee_r_cmd, knee_r_interp, knee_r_state, knee_r_effort) written again: the
    # factory state it booted with has every PDO disabled
    wanted = {m.id for m in cfg.messages if m.pdo is not None and m.pdo.node == "knee_r"}
    assert {can_id for _, _, can_id, valid, _, _ in drive.pdo_slots() if valid} == wanted
    # knee_r misses samples only between the drill and one period after its recovery (its first SYNC as a started
    # drive may already have gone out); before and after, every cycle has them
    assert out.run is not None
    for rec in out.run.records:
        at = rec.sync_sent - out.t0
        if at < drill_s or at > recovered_s + PERIOD_S:
            assert not [m for m in rec.missing if m.startswith("knee_r")], at
    for name in ("hip_l", "knee_l", "ankle_l", "hip_r", "ankle_r"):
        assert out.run.complete_samples(name) == 40, name


def test_a_rebooted_drive_is_left_stopped_by_default(cfg: rt.RuntimeConfig) -> None:
    """allex2 gives no on_reboot: stop_node. No RxPDO goes to the unconfigured drive, nothing is set up again: it
    stays PRE-OPERATIONAL in SWITCH ON DISABLED, and the others cycle on."""
    out, bench = drill_run(cfg, 30, 0.2, 0.05)
    assert drive_kinds(out) == [("knee_r", "boot-up", "stop_node")]
    boot_s = assert_boot_up_in_time(out, 0.2, 0.05)
    knee = out.nodes["knee_r"]
    assert knee.stopped_at_s == boot_s and knee.reboots[0]["result"] == "left stopped"
    drive = bench["knee_r"]
    assert drive.power is not None and drive.power.state == SWITCH_ON_DISABLED
    assert all(not valid for _, _, _, valid, _, _ in drive.pdo_slots())  # its factory state: nothing written since
    assert out.run is not None and out.run.cycles == 30 and out.ended_by == "cycles"


def test_a_rebooted_drive_stops_everyone_with_stop_all(cfg: rt.RuntimeConfig) -> None:
    out, _ = drill_run(with_on_reboot(cfg, "stop_all"), 40, 0.2, 0.05)
    assert drive_kinds(out) == [("knee_r", "boot-up", "stop_all")]
    assert out.ended_by.startswith("stop_all: knee_r (node 5) rebooted")
    assert out.run is not None and out.run.cycles < 40
    assert {out.nodes[n].safe_state for n in out.nodes if n != "knee_r"} == {"QUICK STOP ACTIVE"}


def test_a_reboot_longer_than_the_heartbeat_timeout_is_a_loss_then_a_boot_up(cfg: rt.RuntimeConfig) -> None:
    """Silent 500 ms: lost after the consumer time 300 ms (reported within 300 ms + one heartbeat period 100 ms + T
    of the outage's start), then the boot-up, and with recover it is set up again."""
    out, _ = drill_run(with_on_reboot(cfg, "recover"), 60, 0.2, 0.5)
    assert drive_kinds(out) == [
        ("knee_r", "lost", "stop_node"),
        ("knee_r", "boot-up", "recover"),
        ("knee_r", "recovered", "continue"),
    ]
    ((drill_s, _),) = out.drills
    lost_s = next(t for t, e in out.events if e.kind == "lost")
    assert drill_s + 0.3 - 0.1 <= lost_s <= drill_s + 0.3 + 0.1 + PERIOD_S + SLACK_S
    assert out.nodes["knee_r"].state == OPERATION_ENABLED


def test_run_reports_the_reboot_in_text_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from netcfg.commands import main

    spec = tmp_path / "recover.yaml"
    text = (ROOT / "specs" / "allex2.yaml").read_text(encoding="utf-8")
    spec.write_text(text.replace("    on_loss: stop_node\n", "    on_loss: stop_node\n    on_reboot: recover\n"))
    code = main(["run", str(spec), "--simulated-drives", "--cycles", "30", "--reset", "knee_r@0.2s+50ms"])
    printed = capsys.readouterr().out
    assert code == 1  # a drive rebooted: the run is not clean, even though it recovered
    assert "drill: knee_r reboots, silent for 50 ms" in printed
    assert "knee_r (node 5) rebooted: boot-up message, its configuration is gone -> recover" in printed
    assert "rebooted at " in printed and "(recover): recovered in " in printed
    code = main(
        ["run", str(spec), "--simulated-drives", "--cycles", "30", "--reset", "knee_r@0.2s+50ms", "--format", "json"]
    )
    doc = json.loads(capsys.readouterr().out)
    assert code == 1 and [e["kind"] for e in doc["events"]] == ["boot-up", "recovered"]
    (reboot,) = {n["name"]: n for n in doc["nodes"]}["knee_r"]["reboots"]
    assert reboot["action"] == "recover" and reboot["result"] == "recovered" and reboot["recovery_ms"] > 0


def test_check_reports_what_the_master_does_per_node() -> None:
    from netcfg.check import analyse_spec
    from netcfg.emit.report_md import emit

    model, report = analyse_spec(ROOT / "specs" / "allex2.yaml")
    assert model is not None
    md = emit(model, report)["report.md"].decode()
    assert "supervision (netcfg run)" in md
    assert "| knee_r | slave | 5 |" in md
    assert "lost after 300 ms without heartbeat: stop_node; EMCY: stop_all; reboot: stop_node" in md


# --- refused set-up: SDO aborts with their CiA 301 meaning, bounded SDO timeouts ----------------------------------


def test_sdo_abort_codes_carry_the_standards_meaning() -> None:
    """CiA 301 v4.2, 7.2.4.3.17, table 22 (the standard's wording)."""
    from netcfg import cia301

    assert cia301.sdo_abort_text(0x06020000) == "object does not exist in the object dictionary"
    assert cia301.sdo_abort_text(0x06090011) == "sub-index does not exist"
    assert cia301.sdo_abort_text(0x06010002) == "attempt to write a read only object"
    assert cia301.sdo_abort_text(0x05040000) == "SDO protocol timed out"
    assert cia301.sdo_abort_text(0x08000022).endswith("because of the present device state")
    assert cia301.sdo_abort_text(0x12345678).startswith("not a CiA 301 abort code")


@pytest.mark.parametrize(
    ("drill", "expected"),
    [
        (
            "knee_r:0x1017=0x06010002",
            "SDO abort 0x06010002 (attempt to write a read only object) on writing 0x1017:00 (Producer heartbeat time)"
            " = 0x64",  # allex2's heartbeat 100 ms
        ),
        (
            "knee_r:0x1A00:0",  # TPDO1's mapping count; the default code
            "SDO abort 0x08000020 (data cannot be transferred or stored to the application) on clearing the mapping "
            "0x1A00:00 (TPDO1 mapping parameter, Number of mapped application objects in PDO) = 0x0",
        ),
    ],
)
def test_a_refused_write_names_the_object_and_its_abort(
    drill: str, expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from netcfg.commands import main

    code = main(["run", str(GENERATED / "runtime.json"), "--simulated-drives", "--cycles", "5", "--sdo-abort", drill])
    printed = capsys.readouterr().out
    assert code == 1 and "nothing was started" in printed
    (line,) = [x for x in printed.splitlines() if "knee_r (node 5): FAILED" in x]
    assert expected in line
    # --allow-missing: the others run, the refused node stays out
    code = main(
        [
            "run",
            str(GENERATED / "runtime.json"),
            "--simulated-drives",
            "--cycles",
            "5",
            "--sdo-abort",
            drill,
            "--allow-missing",
            "--format",
            "json",
        ]
    )
    import json

    nodes = {n["name"]: n for n in json.loads(capsys.readouterr().out)["nodes"]}
    assert not nodes.pop("knee_r")["set_up"]
    assert {n["samples"] for n in nodes.values()} == {5}


def test_sdo_timeout_and_retries_come_from_the_spec(tmp_path: Path) -> None:
    """A node that never answers, with sdo_timeout 50 ms and sdo_retries 2: the identity read is sent 1 + 2 = 3 times,
    each waited for 50 ms, so the node fails after 3 x 50 = 150 ms (plus the host's scheduling, SLACK_S), with the
    CiA 301 abort the master sends on giving up (0x05040000)."""
    from conftest import runtime_config

    from netcfg.runtime.canopen_setup import configure_network

    spec = tmp_path / "slow.yaml"
    text = (ROOT / "specs" / "allex2.yaml").read_text(encoding="utf-8")
    spec.write_text(
        text.replace("    on_loss: stop_node\n", "    on_loss: stop_node\n    sdo_timeout: 50 ms\n    sdo_retries: 2\n")
    )
    cfg = runtime_config(spec)
    assert (cfg.node("knee_r").sdo_timeout_ns, cfg.node("knee_r").sdo_retries) == (50_000_000, 2)
    assert rt.load(GENERATED / "runtime.json").node("knee_r").sdo_timeout_ns == 500_000_000  # the default
    channel = f"faults-{uuid.uuid4().hex[:8]}"
    log = tmp_path / "setup.log"
    with (
        DriveBench(cfg, GENERATED / "canopen", channel=channel, nodes=["knee_r"], silent=True),
        BusLog(can.Bus(interface="virtual", channel=channel), log) as bus,
    ):
        began = time.monotonic()
        report = configure_network(cfg, bus, nodes=["knee_r"])
        took = time.monotonic() - began
    (node,) = report.nodes
    assert not node.ok and node.step == "identity" and node.abort_code == 0x05040000
    assert "within 50 ms, 3 times" in str(node.error) and "SDO protocol timed out" in str(node.error)
    assert 0.150 <= took <= 0.150 + SLACK_S
    requests = [f for f in can.LogReader(str(log)) if not f.is_rx and f.arbitration_id == 0x605]
    assert [bytes(f.data[:4]) for f in requests[:3]] == [bytes([0x40, 0x18, 0x10, 0x01])] * 3  # upload 0x1018:01
    assert bytes(requests[3].data[:1]) == b"\x80" and bytes(requests[3].data[4:]) == (0x05040000).to_bytes(4, "little")


# --- a stalled host ----------------------------------------------------------------------------------------------


def stall_run(
    cfg: rt.RuntimeConfig, cycles: int, span: tuple[float, float], canopen_dir: Path
) -> tuple[Outcome, DriveBench]:
    channel = f"faults-{uuid.uuid4().hex[:8]}"
    bench = DriveBench(cfg, canopen_dir, channel=channel).start()
    try:
        with BusLog(can.Bus(interface="virtual", channel=channel), None) as bus:
            out = operate(cfg, bus, Plan(cycles=cycles, stalls=[span]))
        return out, bench
    finally:
        bench.stop()


def test_a_stalled_master_reports_the_sync_instants_it_missed_and_resumes(cfg: rt.RuntimeConfig) -> None:
    """The loop held from 0.3 s to 0.5 s. The stall begins after the first cycle ending at or after 0.3 s, whose SYNC
    went out one period before (0.28..0.30 s + SLACK_S); the next SYNC goes out when the stall ends, at 0.5 s. The
    SYNC instants strictly between are missed: with T = 20 ms, (0.5 - last) / T - 1 of them, 9 or 10. The EPOS4
    profile has no RPDO deadline and no consumer heartbeat time, so each drive keeps its last command and says so;
    no drive is lost (the heartbeats came during the stall and wait in the receive queue)."""
    out, bench = stall_run(cfg, 40, (0.3, 0.5), GENERATED / "canopen")
    assert kinds(out) == [("master", "missed-sync", "continue")]
    (gap,) = out.sync_gaps
    assert 0.28 <= gap["from_s"] <= 0.30 + SLACK_S and 0.5 <= gap["to_s"] <= 0.5 + SLACK_S
    assert gap["missed"] == round((gap["to_s"] - gap["from_s"]) / PERIOD_S) - 1 and 9 <= gap["missed"] <= 10
    assert gap["instants_s"] == [round(gap["from_s"] + k * PERIOD_S, 6) for k in range(1, gap["missed"] + 1)]
    assert out.run is not None and out.run.cycles == 40  # it resumed and ran every cycle
    for name, drive in bench.drives.items():
        (note,) = drive.notes
        assert note.startswith("no SYNC for ") and note.endswith("so it kept its last command"), name
        assert not out.nodes[name].lost_at_s and out.run.complete_samples(name) == 40


def test_a_drive_with_an_rpdo_deadline_faults_when_the_master_stalls(cfg: rt.RuntimeConfig, tmp_path: Path) -> None:
    """knee_r's EDS given an RPDO1 deadline (0x1400 sub 5, the RPDO's event timer, CiA 301 7.5.2.35) of 50 ms: with
    the master held 200 ms it sends EMCY 0x8250 (CiA 301 table 21, "RPDO timeout") and faults; the master learns it
    when it resumes, and allex2's on_emcy stop_all ends the run."""
    import shutil

    folder = tmp_path / "canopen"
    shutil.copytree(GENERATED / "canopen", folder)
    eds = folder / "knee_r.eds"
    text = eds.read_text(encoding="utf-8")
    sub5 = (
        "[1400sub5]\nParameterName=Event timer\nObjectType=0x7\nDataType=0x0006\nAccessType=rw\nDefaultValue=50\n"
        "PDOMapping=0\n\n[1401]\n"
    )
    text = text.replace(
        "ParameterName=RPDO1 communication parameter\nObjectType=0x9\nSubNumber=3\n",
        "ParameterName=RPDO1 communication parameter\nObjectType=0x9\nSubNumber=4\n",
        1,
    )
    eds.write_text(text.replace("[1401]\n", sub5, 1), encoding="utf-8")
    out, bench = stall_run(cfg, 60, (0.3, 0.5), folder)
    assert kinds(out) == [("knee_r", "emcy", "stop_all"), ("master", "missed-sync", "continue")]
    # once for the stall; maybe once more after it, when the run ends and the RxPDOs stop again before the NMT stop
    note, *more = bench["knee_r"].notes
    assert all(m == note for m in more)
    assert note.startswith("RPDO1 not received within its deadline of 50 ms") and "EMCY 0x8250" in note
    assert bench["knee_r"].emcy_sent[0][0] == 0x8250
    assert out.ended_by.startswith("stop_all: knee_r: EMCY 0x8250")


# --- bus-off of the master's controller ---------------------------------------------------------------------------


def test_the_master_rides_out_a_bus_off_and_measures_its_recovery(cfg: rt.RuntimeConfig) -> None:
    """The controller bus-off for 200 ms (the drill at the first cycle end at or after 0.3 s). The next cycle's
    sends fail; after it the master sees python-can's BusState.ERROR (netcfg's bus wrapper plays it), so it detects
    the bus-off within one period T of the drill. It stops sending and looks every BUS_POLL_S (1 ms) for the bus:
    back 200 ms after the drill, its first SYNC follows at once (within SLACK_S). The SYNC instants between the last
    SYNC sent and that one are reported missed, and supervision restarts its clocks: no drive is taken for lost,
    though the master heard no heartbeat for 200 ms (the consumer time is 300 ms, but it would be the same beyond)."""
    from netcfg.runtime.operate import BUS_POLL_S

    channel = f"faults-{uuid.uuid4().hex[:8]}"
    with (
        DriveBench(cfg, GENERATED / "canopen", channel=channel),
        BusLog(can.Bus(interface="virtual", channel=channel), None) as bus,
    ):
        out = operate(cfg, bus, Plan(cycles=40, drills=[(0.3, "bus-off", lambda: bus.bus_off(0.2))]))
    assert kinds(out) == [
        ("master", "bus-off", "hold"),
        ("master", "bus-on", "continue"),
        ("master", "missed-sync", "continue"),
    ]
    ((drill_s, _),) = out.drills
    assert 0.3 <= drill_s <= 0.3 + PERIOD_S + SLACK_S
    (off,) = out.bus_offs
    assert drill_s <= off["detected_s"] <= drill_s + PERIOD_S + SLACK_S
    # the wrapper times the bus-off on time.monotonic, the master on its own clock: 1e-4 s for the two scales
    assert drill_s + 0.2 <= off["back_s"] + 1e-4 <= drill_s + 0.2 + BUS_POLL_S + SLACK_S
    assert abs(off["off_ms"] - 1e3 * (off["back_s"] - off["detected_s"])) < 0.01
    assert 0 <= off["recovery_ms"] <= 1e3 * SLACK_S
    (gap,) = out.sync_gaps
    assert gap["to_s"] == off["first_sync_s"] and gap["from_s"] < drill_s  # from the last SYNC that went out
    assert gap["missed"] == round((gap["to_s"] - gap["from_s"]) / PERIOD_S) - 1
    assert out.run is not None and out.run.cycles == 40
    assert out.run.send_errors.get("SYNC 0x80") == 1  # the one cycle before the bus-off was detected
    assert all(n.lost_at_s is None for n in out.nodes.values())


def test_socketcan_error_frames_say_bus_off_and_restarted() -> None:
    """SocketCAN reports controller states in error frames (linux/can/error.h: CAN_ERR_BUSOFF 0x40, CAN_ERR_RESTARTED
    0x100 in the identifier), not in python-can's bus.state; the master takes both."""
    from netcfg.runtime.operate import _Operation

    op = _Operation.__new__(_Operation)  # only its frame routing: no bus, no plan
    op.error_frame_bus_off, op.sdo_routes = False, {}
    op.supervisor = None

    class Sink:
        def feed(self, frame: can.Message, t: float) -> bool:
            return False

    op.supervisor = Sink()  # type: ignore[assignment]
    op._on_frame(can.Message(is_error_frame=True, arbitration_id=0x40), 0.0)
    assert op.error_frame_bus_off
    op._on_frame(can.Message(is_error_frame=True, arbitration_id=0x100), 0.0)
    assert not op.error_frame_bus_off


def test_a_drive_enabled_over_its_pdos_is_walked_up_again_over_them(tmp_path: Path) -> None:
    """hip_l with its controlword in RxPDO1 and its statusword in TPDO2 (as in test_run's PDO enabling test) and
    on_reboot: recover: after the set-up again the master walks it to OPERATION ENABLED through those PDOs, one
    CiA 402 transition per cycle (2, 3, 4), and only then reports it recovered."""
    from netcfg.commands import main

    text = allex2_cia402_over_pdos()
    text = text.replace("    on_loss: stop_node\n", "    on_loss: stop_node\n    on_reboot: recover\n", 1)  # hip_l
    spec = tmp_path / "pdo402.yaml"
    spec.write_text(text, encoding="utf-8")
    assert main(["build", str(spec), "-o", str(tmp_path / "out")]) == 0
    cfg = rt.load(tmp_path / "out" / "runtime.json")
    channel = f"faults-{uuid.uuid4().hex[:8]}"
    with (
        DriveBench(cfg, channel=channel) as bench,
        BusLog(can.Bus(interface="virtual", channel=channel), None) as bus,
    ):
        plan = Plan(cycles=40, drills=[(0.2, "hip_l reboots", lambda: bench["hip_l"].reboot(0.05))])
        out = operate(cfg, bus, plan)
        history = [n for n, _ in bench["hip_l"].power.history] if bench["hip_l"].power else []
    assert drive_kinds(out) == [("hip_l", "boot-up", "recover"), ("hip_l", "recovered", "continue")]
    hip_l = out.nodes["hip_l"]
    assert hip_l.cia402_over == "PDO" and hip_l.state == OPERATION_ENABLED
    assert history[:4] == [1, 2, 3, 4]  # the rebooted drive's own machine: initialised, then up over the RxPDO
    recovered = next(e for _, e in out.events if e.kind == "recovered")
    assert recovered.text.endswith("SWITCH ON DISABLED -> READY TO SWITCH ON -> SWITCHED ON -> OPERATION ENABLED")


def test_a_failed_set_up_again_follows_on_loss(cfg: rt.RuntimeConfig) -> None:
    """The rebooted drive refuses its heartbeat time (0x1017) on the set-up again: the recovery fails, reported with
    the abort's CiA 301 meaning, and knee_r's on_loss (stop_node) leaves it stopped while the others run on."""
    cfg = with_on_reboot(cfg, "recover")
    channel = f"faults-{uuid.uuid4().hex[:8]}"

    with (
        DriveBench(cfg, GENERATED / "canopen", channel=channel) as bench,
        BusLog(can.Bus(interface="virtual", channel=channel), None) as bus,
    ):

        def reboot_and_refuse() -> None:
            bench["knee_r"].abort_writes[0x1017] = 0x06010002
            bench["knee_r"].reboot(0.05)

        out = operate(cfg, bus, Plan(cycles=40, drills=[(0.2, "knee_r reboots", reboot_and_refuse)]))
    assert drive_kinds(out) == [("knee_r", "boot-up", "recover"), ("knee_r", "recovery-failed", "stop_node")]
    failed = next(e for _, e in out.events if e.kind == "recovery-failed")
    assert "SDO abort 0x06010002 (attempt to write a read only object)" in failed.text
    knee = out.nodes["knee_r"]
    assert knee.stopped_at_s is not None and knee.reboots[0]["recovered_at_s"] is None
    assert out.run is not None and out.run.cycles == 40 and out.run.complete_samples("hip_l") == 40


def test_an_sdo_timeout_out_of_range_is_an_error(tmp_path: Path) -> None:
    from conftest import check

    spec = tmp_path / "zero.yaml"
    text = (ROOT / "specs" / "allex2.yaml").read_text(encoding="utf-8")
    spec.write_text(text.replace("    on_loss: stop_node\n", "    on_loss: stop_node\n    sdo_timeout: 0 ms\n", 1))
    report = check(spec)
    (error,) = report["errors"]
    assert (error["code"], error["line"]) == ("sdo-timeout", 49)  # hip_l's on_loss is on line 48 of allex2.yaml
    assert "more than 0 and at most 60 s" in error["message"]


def test_an_emcy_of_a_drive_enabled_over_its_pdos_leaves_it_listed_in_fault(tmp_path: Path) -> None:
    """hip_l walked up through its PDOs (its statusword in TPDO2) sends EMCY 0x2310 at 0.5 s; on_emcy stop_all (the
    default). CiA 402: the drive's fault reaction ends in FAULT; the statusword of the cycle that saw the EMCY was
    sampled at the SYNC before it and says OPERATION ENABLED: the EMCY has the last word, so the node is listed in
    FAULT, as its safe stop finds it (before, the table said OPERATION ENABLED beside 'safe stop -> FAULT')."""
    spec = tmp_path / "pdo402.yaml"
    spec.write_text(allex2_cia402_over_pdos(), encoding="utf-8")
    proc = cli("run", str(spec), "--simulated-drives", "--cycles", "50", "--emcy", "hip_l@0.5s", "--format", "json")
    doc = json.loads(proc.stdout)
    hip_l = next(n for n in doc["nodes"] if n["name"] == "hip_l")
    assert (hip_l["state"], hip_l["safe_state"]) == ("FAULT", "FAULT")
    assert doc["ended_by"].startswith("stop_all: hip_l: EMCY 0x2310")
