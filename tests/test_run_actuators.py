"""`netcfg run` on an actuator bus: the simulated actuators (built from their profiles), the reactions to a lost
actuator and to an error flag, the run's log held by `netcfg verify`, and a run against odrive-can's own mock ODrive.

Figures come from the profiles and hand calculations written beside each assertion; the master runs in wall-clock
time on a shared host, so a timing figure is asserted only within a stated slack of the host's latency."""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import threading
import time
from pathlib import Path
from typing import Any

import can
import pytest
import yaml
from conftest import ROOT, cli

from netcfg.commands import main

PERIOD_S = 0.020  # the test arm's commands: 50 Hz
LOSS_S = 3 * PERIOD_S  # no heartbeat_timeout: 3 periods of the slowest message expected (actuator_plan.LOSS_MULTIPLIER)
HOST_SLACK_S = 0.100  # how late a wall-clock thread may wake on a loaded 2-core host


def arm(tmp_path: Path, **reactions: dict[str, str]) -> Path:
    """Three Damiao DM-J4310 joints (node ids 1-3, feedback on 0x11-0x13) at 50 Hz on one 1 Mbit/s bus."""
    nodes: list[dict[str, Any]] = [{"name": "controller", "role": "master", "buses": ["arm_can"]}]
    for i, name in enumerate(("shoulder", "elbow", "wrist"), start=1):
        nodes.append({
            "name": name, "node_id": i, "buses": ["arm_can"], "device": "damiao-dm-j4310",
            **reactions.get(name, {}),
            "actuator": {"parameters": {"master_id": 0x10 + i}, "commands": [{"message": "mit_command",
                                                                                "rate": "50 Hz"}]},
        })
    path = tmp_path / "arm.yaml"
    path.write_text(yaml.safe_dump({"system": "arm", "buses": [{"name": "arm_can", "protocol": "can",
                                                                "bitrate": "1 Mbit/s"}], "nodes": nodes}))
    return path


def run_json(*args: str) -> tuple[int, dict[str, Any]]:
    proc = cli("run", *args, "--simulated-drives", "--format", "json")
    assert proc.returncode in (0, 1), proc.stderr
    return proc.returncode, json.loads(proc.stdout)


def events(doc: dict[str, Any]) -> list[tuple[str, str, str]]:
    return [(e["node"], e["kind"], e["action"]) for e in doc["events"]]


def test_a_run_answers_every_command_and_verify_holds_its_log(tmp_path: Path) -> None:
    """50 cycles: each joint gets its enable (FF..FC), 50 MIT commands and its disable (FF..FD), all on its node id
    (the profile's 'special commands' share the command's identifier), and answers each with a feedback frame (the
    profile: one feedback frame answers every frame the motor accepts): 52 frames each way per joint. The log is
    the one `netcfg verify` reads; what a bus's analysis bounds (load, periods) holds there. A reply's delay is
    the host's thread latency on top of the profile's 0..500 us, so 'late' (a response) is not what this is about."""
    spec, log = arm(tmp_path), tmp_path / "run.log"
    code, doc = run_json(str(spec), "--cycles", "50", "--log", str(log))
    assert code == 0 and doc["ok"] and doc["ended_by"] == "cycles" and doc["cycles"] == 50, doc
    assert doc["period_ms"] == 20.0
    for name, a in doc["actuators"].items():
        assert a["enabled"] == "answered" and a["safe_stop"] == "answered", (name, a)
        assert a["commands"] == 50 and a["replies"] + a["missing"] == 50, (name, a)
        assert a["states"] == {"status": "DISABLED"}  # the profile: safe_stop leaves the motor DISABLED
        assert a["errors"] == []
    proc = cli("verify", str(spec), str(log), "--format", "json")
    got = json.loads(proc.stdout)
    # the host's latency, named as such: a reply late by thread latency, or a command the host sent late (host_late:
    # verify tells a host-stamped log by frames closer together than the wire allows)
    assert set(got["violations_by_kind"]) <= {"late", "host_late"}, got["violations_by_kind"]
    counts = {m["name"]: m["count"] for m in got["messages"]}
    for name in ("shoulder", "elbow", "wrist"):
        assert counts[f"{name}_mit_command"] == 52
        assert counts[f"{name}_feedback"] == 52 - doc["actuators"][name]["missing"]


def test_a_lost_actuator_stops_the_arm(tmp_path: Path) -> None:
    """The elbow stops answering at 0.4 s; its on_loss is the default stop_all. Its last feedback came at most one
    period (20 ms) before, so it is lost between 0.4 + 60 - 20 ms and 0.4 + 60 ms (plus the host's latency); every
    joint then gets its safe stop, the two that answer answer it, and the run fails (exit 1)."""
    code, doc = run_json(str(arm(tmp_path)), "--cycles", "100", "--kill", "elbow@0.4s")
    assert code == 1 and not doc["ok"]
    assert events(doc) == [("elbow", "lost", "stop_all")]
    assert doc["ended_by"] == "stop_all:elbow"
    lost = doc["actuators"]["elbow"]["lost_at_s"]
    assert 0.4 + LOSS_S - PERIOD_S <= lost <= 0.4 + LOSS_S + HOST_SLACK_S, lost
    assert [doc["actuators"][n]["safe_stop"] for n in ("shoulder", "elbow", "wrist")] == ["answered", "sent",
                                                                                          "answered"]
    assert doc["cycles"] < 100


def test_a_lost_actuator_held_and_stopped_alone(tmp_path: Path) -> None:
    """on_loss continue (hold): the master reports the wrist lost and keeps commanding it to the end; on_loss
    stop_node: the elbow gets its safe stop at its loss and no command after, while the others run on."""
    spec = arm(tmp_path, wrist={"on_loss": "continue"}, elbow={"on_loss": "stop_node"})
    code, doc = run_json(str(spec), "--cycles", "40", "--kill", "wrist@0.2s", "--kill", "elbow@0.4s")
    assert code == 1 and doc["ended_by"] == "cycles" and doc["cycles"] == 40
    assert events(doc) == [("wrist", "lost", "continue"), ("elbow", "lost", "stop_node")]
    a = doc["actuators"]
    assert a["wrist"]["commands"] == 40 and a["shoulder"]["commands"] == 40
    # 0.4 s: 21 commands (t = 0, 20, ..., 400 ms), and at most until its loss + the host's latency
    assert 21 <= a["elbow"]["commands"] <= 21 + math.ceil((LOSS_S + HOST_SLACK_S) / PERIOD_S)
    assert a["elbow"]["stopped_at_s"] == pytest.approx(a["elbow"]["lost_at_s"], abs=0.001)
    assert a["shoulder"]["safe_stop"] == "answered"


def test_an_error_flag_in_a_reply(tmp_path: Path) -> None:
    """From 0.3 s the shoulder's feedback carries status 8, the first of the profile's error_values (OVER_VOLTAGE,
    the manual's feedback status table): on_emcy stop_all ends the run; the wrist's, on_emcy continue, is reported
    and held."""
    code, doc = run_json(str(arm(tmp_path)), "--cycles", "100", "--fault", "shoulder@0.3s")
    assert code == 1 and doc["ended_by"] == "stop_all:shoulder"
    assert [(e["node"], e["kind"], e["detail"], e["action"]) for e in doc["events"]] == [
        ("shoulder", "error", "feedback reports OVER_VOLTAGE", "stop_all")]
    assert doc["events"][0]["t_s"] >= 0.3
    code, doc = run_json(str(arm(tmp_path, wrist={"on_emcy": "continue"})), "--cycles", "30", "--fault",
                         "wrist@0.2s")
    assert code == 1 and doc["ended_by"] == "cycles" and doc["cycles"] == 30
    assert events(doc) == [("wrist", "error", "continue")]
    assert doc["actuators"]["wrist"]["commands"] == 30 and doc["actuators"]["wrist"]["errors"] == ["OVER_VOLTAGE"]


def test_run_refuses_what_an_actuator_bus_does_not_have(tmp_path: Path) -> None:
    spec = str(arm(tmp_path))
    for args, words in (
        (["--set", "wrist.mit_command.stiffness=1"], "has no fields ['stiffness']"),
        (["--set", "wrist.mit_command.kp=9000"], "kp = 9000.0 is outside [0.0, 500.0]"),
        (["--set", "wrist=1"], "NODE.COMMAND.FIELD=VALUE"),
        (["--fault", "knee@1s"], "'knee' is not an actuator of bus 'arm_can'"),
        (["--emcy", "wrist@1s"], "act on a CANopen run"),
    ):
        proc = cli("run", spec, "--simulated-drives", "--cycles", "2", *args)
        assert proc.returncode == 2 and words in proc.stderr, (args, proc.stderr)
    proc = cli("run", str(ROOT / "specs" / "allex2.yaml"), "--simulated-drives", "--cycles", "2", "--set",
               "hip_l.x.y=1")
    assert proc.returncode == 2 and "act on an actuator bus" in proc.stderr


# -- odrive-can's own mock ODrive (odrive_can.mock.ODriveCANMock), which nobody here wrote

ODRIVE_SPEC = {
    "system": "odrive_mock",
    "buses": [{"name": "can0", "protocol": "can", "bitrate": "250 kbit/s"}],
    "nodes": [
        {"name": "host", "role": "master", "buses": ["can0"]},
        # node 0: the DBC the mock decodes with is the vendor's for axis 0; its loops send the heartbeat every 0.2 s
        # and the encoder estimates every 0.1 s (ODriveCANMock.heartbeat_loop / encoder_loop defaults)
        {"name": "axis0", "node_id": 0, "buses": ["can0"], "device": "odrive-cansimple",
         "actuator": {"parameters": {"heartbeat_msg_rate_ms": 200, "encoder_msg_rate_ms": 100},
                      "commands": [{"message": "set_input_vel", "rate": "20 Hz"}]}},
    ],
}


class _Mock:
    """ODriveCANMock on a python-can virtual channel, its asyncio loop in a thread of its own."""

    def __init__(self, channel: str) -> None:
        from odrive_can.mock import ODriveCANMock

        self.bus = can.Bus(interface="virtual", channel=channel)
        self.mock = ODriveCANMock(axis_id=0, can_bus=self.bus)
        self.loop = asyncio.new_event_loop()
        self.task: asyncio.Task[None] | None = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        self.task = self.loop.create_task(self.mock.main())
        with contextlib.suppress(asyncio.CancelledError):  # cancelled by stop()
            self.loop.run_until_complete(self.task)

    def stop(self) -> None:
        if self.task is not None:
            self.loop.call_soon_threadsafe(self.task.cancel)
        self.thread.join(5)
        self.mock.notifier.stop()
        self.bus.shutdown()


def _remote_request(channel: str) -> Any:
    """Send ODrive's Get_Error request (request_error: a remote frame on 0x003) and decode the first answer."""
    from netcfg.devices.actuator_profile import builtin_actuator_profile
    from netcfg.runtime.actuators import ActuatorCodec

    codec = ActuatorCodec(builtin_actuator_profile("odrive-cansimple").plain, node_id=0)
    frame = codec.encode("request_error")
    assert frame.is_remote and frame.arbitration_id == 0x003 and frame.data == b""
    with can.Bus(interface="virtual", channel=channel) as bus:
        bus.send(can.Message(arbitration_id=frame.arbitration_id, is_extended_id=False, is_remote_frame=True, dlc=8))
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            msg = bus.recv(timeout=0.5)
            if msg is not None and not msg.is_remote_frame and msg.arbitration_id == 0x003:
                return codec.decode(msg.arbitration_id, False, bytes(msg.data))
    return None


def test_run_against_odrive_cans_own_mock(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The master enables the axis (Set_Axis_State CLOSED_LOOP_CONTROL), commands Set_Input_Vel 2 rev/s at 20 Hz
    for 1.5 s and sets it IDLE at the end. The mock takes 0.5 s to change state (its set_axis_state sleeps 0.5 s)
    and then reports it in its heartbeat; its velocity model ramps to the setpoint at 10 rev/s^2 (roc=10), 0.2 s
    for 2 rev/s. What netcfg decodes from the mock's frames is what the mock holds, and what the vendor's DBC
    decodes from the same frames."""
    import cantools
    import odrive_can

    spec = tmp_path / "odrive.yaml"
    spec.write_text(yaml.safe_dump(ODRIVE_SPEC))
    log = tmp_path / "run.log"
    channel = f"odrive-mock-{id(tmp_path)}"
    mock = _Mock(channel)
    try:
        code = main(["run", str(spec), "--interface", "virtual", "--channel", channel, "--cycles", "30", "--set",
                     "axis0.set_input_vel.input_vel=2", "--log", str(log), "--format", "json"])
        model = mock.mock.odrive
        held = {"velocity": model.velocity, "setpoint": model.model.setpoint, "state": str(model.axis_state)}
        rtr = _remote_request(channel)
    finally:
        mock.stop()
    # a remote request (RTR, no data, DLC 8) netcfg's codec encodes is answered by the mock with its Get_Error, which
    # netcfg decodes: no active error, no disarm reason (the mock answers every request with zeros)
    assert rtr is not None and rtr.message == "get_error"
    assert rtr.values == {"active_errors": 0, "disarm_reason": 0} and rtr.errors == ()
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and doc["ok"], doc
    a = doc["actuators"]["axis0"]
    assert a["enabled"] == "sent" and a["commands"] == 30 and a["safe_stop"] == "sent"
    assert held["setpoint"] == 2.0  # the mock decoded netcfg's Set_Input_Vel with the vendor's DBC
    assert held["state"] == "CLOSED_LOOP_CONTROL"  # ... and its Set_Axis_State (the IDLE at the end takes 0.5 s)
    assert a["states"]["axis_state"] == "CLOSED_LOOP_CONTROL"  # netcfg read it from the mock's heartbeat
    # the mock's last encoder frame holds its velocity as a float32: 2.0 is exact
    assert a["last"]["get_encoder_estimates"]["vel_estimate"] == pytest.approx(2 * math.pi * held["velocity"],
                                                                               rel=1e-6)
    assert held["velocity"] == 2.0
    assert a["heard"]["heartbeat"] >= 5 and a["heard"]["get_encoder_estimates"] >= 10  # 1.5 s at 0.2 s and 0.1 s
    # every frame the mock sent, decoded by the vendor's DBC and by netcfg's codec, agrees
    dbc = cantools.database.load_file(Path(odrive_can.__file__).parent / "dbc" / "odrive-cansimple-0.6.10.dbc")
    from netcfg.devices.actuator_profile import builtin_actuator_profile
    from netcfg.runtime.actuators import ActuatorCodec

    codec = ActuatorCodec(builtin_actuator_profile("odrive-cansimple").plain, node_id=0)
    compared = 0
    for frame in can.LogReader(str(log)):
        if frame.arbitration_id not in (0x001, 0x009):
            continue
        ours = codec.decode(frame.arbitration_id, False, bytes(frame.data), units="wire")
        theirs = dbc.decode_message(frame.arbitration_id, bytes(frame.data), decode_choices=False)
        assert ours is not None
        for name, value in theirs.items():
            assert ours.values[name.lower()] == pytest.approx(value, rel=1e-7, abs=1e-12), (name, frame)
        compared += 1
    assert compared >= 15


def test_verify_measures_a_reply_from_its_command(tmp_path: Path) -> None:
    """A hand-made log of the arm's shoulder: commands at 0, 20 and 40 ms, answered 300 us, 300 us and 5,000 us after
    (the log's own times). verify measures each feedback from the command frame before it and holds it against the
    feedback's analysed worst case (runtime.json's wcrt_ns, which holds the profile's 0..500 us): 300 us is inside,
    5,000 us is late by 5,000 us less that bound."""
    from netcfg.check import analyse_spec

    spec = arm(tmp_path)
    model, report = analyse_spec(spec)
    assert model is not None and report["ok"]
    wcrt_us = next(m for b in report["buses"] for m in b["messages"] if m["name"] == "shoulder_feedback")["wcrt_us"]
    assert 300 < wcrt_us < 5_000
    log = tmp_path / "hand.log"
    command, feedback = "001#7FFF7FF000000000", "011#117FFF7FF7FF0000"  # position 0, ...: the codec's zero command
    lines = []
    for k, answer_us in enumerate((300, 300, 5_000)):
        t = 1.0 + 0.020 * k
        lines += [f"({t:.6f}) can0 {command}", f"({t + answer_us / 1e6:.6f}) can0 {feedback}"]
    log.write_text("\n".join(lines) + "\n")
    got = json.loads(cli("verify", str(spec), str(log), "--format", "json").stdout)
    fb = next(m for m in got["messages"] if m["name"] == "shoulder_feedback")
    assert fb["response_from"] == "command"
    assert (fb["response_us"]["min"], fb["response_us"]["max"]) == (300, 5_000)
    late = [v for v in got["violations"] if v["kind"] == "late"]
    assert [v["message"] for v in late] == ["shoulder_feedback"]
    assert f"5000 us after its command; the analysed worst case is {wcrt_us:.0f} us" in late[0]["detail"]


def test_a_simulated_odrive_answers_a_remote_request(tmp_path: Path) -> None:
    """ODrive CAN Simple: a remote frame on node_id << 5 | 0x03 asks for Get_Error, which the axis sends on the same
    identifier (protocol page); the simulated axis answers it, with no error set, and with the first flag of
    active_errors and disarm_reason (bit 0, INITIALIZING in the profile's table) once it is faulted."""
    from conftest import runtime_config_of

    from netcfg.runtime.simulated_actuator import ActuatorBench

    spec = {**ODRIVE_SPEC, "nodes": [ODRIVE_SPEC["nodes"][0], {**ODRIVE_SPEC["nodes"][1], "node_id": 3}]}
    cfg = runtime_config_of(tmp_path / "odrive.yaml", spec)
    channel = f"odrive-sim-{id(tmp_path)}"
    codec = cfg.node("axis0").actuator.codec()  # type: ignore[union-attr]
    with ActuatorBench(cfg, "can0", channel=channel) as bench, can.Bus(interface="virtual", channel=channel) as bus:
        answers = []
        for fault in (False, True):
            if fault:
                bench["axis0"].fault()
            bus.send(can.Message(arbitration_id=3 << 5 | 0x03, is_extended_id=False, is_remote_frame=True, dlc=8))
            deadline = time.monotonic() + 2.0
            while time.monotonic() < deadline:
                msg = bus.recv(timeout=0.2)
                got = None if msg is None else codec.decode(msg.arbitration_id, msg.is_extended_id, bytes(msg.data))
                if got is not None and got.message == "get_error":
                    answers.append(got)
                    break
    assert [a.errors for a in answers] == [(), ("INITIALIZING", "INITIALIZING")]  # active_errors, disarm_reason bit 0


# -- every actuator bus of a spec at once

def legs(tmp_path: Path) -> Path:
    """Two buses, two Damiao DM-J4310 joints each (node ids 1-2, feedback on 0x11-0x12 on either bus), 50 Hz."""
    nodes: list[dict[str, Any]] = [{"name": "controller", "role": "master", "buses": ["left_can", "right_can"]}]
    for side in ("left", "right"):
        for i, joint in enumerate(("hip", "knee"), start=1):
            nodes.append({"name": f"{side}_{joint}", "node_id": i, "buses": [f"{side}_can"],
                          "device": "damiao-dm-j4310", "actuator": {"parameters": {"master_id": 0x10 + i},
                                       "commands": [{"message": "mit_command", "rate": "50 Hz"}]}})
    path = tmp_path / "legs.yaml"
    path.write_text(yaml.safe_dump({"system": "legs", "nodes": nodes, "buses": [
        {"name": f"{side}_can", "protocol": "can", "bitrate": "1 Mbit/s"} for side in ("left", "right")]}))
    return path


def test_a_run_drives_every_actuator_bus_and_verify_reads_each(tmp_path: Path) -> None:
    """Both buses at once, 30 cycles of 20 ms each, the simulated joints of each bus on a virtual channel of its own
    (the same identifiers on both buses: a joint answers only on its own). The one log names each frame's bus, so
    verify holds each bus's frames against that bus: per joint its enable, 30 MIT commands and its disable, 32
    frames, and as many feedback frames less the missing."""
    spec, log = legs(tmp_path), tmp_path / "legs.log"
    code, doc = run_json(str(spec), "--cycles", "30", "--log", str(log))
    assert code == 0 and doc["ok"], doc
    assert [b["bus"] for b in doc["buses"]] == ["left_can", "right_can"]
    for b in doc["buses"]:
        assert b["cycles"] == 30 and b["ended_by"] == "cycles"
        assert set(b["actuators"]) == {f"{b['bus'].split('_')[0]}_{j}" for j in ("hip", "knee")}
        for a in b["actuators"].values():
            assert a["commands"] == 30 and a["replies"] + a["missing"] == 30 and a["enabled"] == "answered"
    channels = {line.split()[1] for line in log.read_text().splitlines()}
    assert channels == {"left_can", "right_can"}
    got = json.loads(cli("verify", str(spec), str(log), "--format", "json").stdout)
    assert set(got["violations_by_kind"]) <= {"late", "host_late"}, got["violations_by_kind"]
    assert not got["unknown_ids"]
    counts = {m["name"]: m["count"] for m in got["messages"]}
    missing = {n: a["missing"] for b in doc["buses"] for n, a in b["actuators"].items()}
    for name in missing:
        assert counts[f"{name}_mit_command"] == 32
        assert counts[f"{name}_feedback"] == 32 - missing[name]


def test_a_lost_joint_stops_every_bus(tmp_path: Path) -> None:
    """The left knee stops answering at 0.2 s; its on_loss, the default stop_all, stops the whole run: the right
    bus ends with it, each of its joints gets its safe stop and answers it."""
    code, doc = run_json(str(legs(tmp_path)), "--cycles", "100", "--kill", "left_knee@0.2s")
    assert code == 1 and not doc["ok"]
    left, right = doc["buses"]
    assert [(e["node"], e["kind"], e["action"]) for e in left["events"]] == [("left_knee", "lost", "stop_all")]
    assert left["ended_by"] == right["ended_by"] == "stop_all:left_knee"
    assert right["cycles"] < 100
    assert [right["actuators"][n]["safe_stop"] for n in ("right_hip", "right_knee")] == ["answered", "answered"]


def test_several_buses_on_hardware_need_a_channel_each(tmp_path: Path) -> None:
    spec = str(legs(tmp_path))
    proc = cli("run", spec, "--interface", "socketcan", "--cycles", "2")
    assert proc.returncode == 2 and "--channel left_can=CHANNEL,right_can=CHANNEL" in proc.stderr, proc.stderr
    proc = cli("run", spec, "--interface", "socketcan", "--channel", "left_can=can0", "--cycles", "2")
    assert proc.returncode == 2 and "give each actuator bus its channel" in proc.stderr, proc.stderr


def test_the_quadruped_s_four_buses_at_once(tmp_path: Path) -> None:
    """examples/quadruped_mit.yaml at 50 Hz instead of 1 kHz (which check refuses, the example's own comment):
    its four leg buses run at once, three joints each on a virtual channel of its own, and verify reads the one log
    per bus: each of the 24 messages has its 25 commands or answers plus the enable and the disable (Damiao's
    special frames share the command's identifier, and each is answered), 27 frames."""
    data = yaml.safe_load((ROOT / "examples" / "quadruped_mit.yaml").read_text())
    for node in data["nodes"]:
        for command in (node.get("actuator") or {}).get("commands", []):
            command["rate"] = "50 Hz"
        for task in node.get("tasks", []):
            task["period"] = "20 ms"
    data.pop("flows")  # the control loop's flow is bounded against the 1 ms cycle
    spec, log = tmp_path / "quadruped.yaml", tmp_path / "quadruped.log"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    code, doc = run_json(str(spec), "--cycles", "25", "--log", str(log))
    assert code == 0 and doc["ok"], doc
    assert [(b["bus"], b["cycles"], len(b["actuators"])) for b in doc["buses"]] == [
        (bus, 25, 3) for bus in ("fl_can", "fr_can", "rl_can", "rr_can")]
    got = json.loads(cli("verify", str(spec), str(log), "--format", "json").stdout)
    assert set(got["violations_by_kind"]) <= {"late", "host_late"}, got["violations_by_kind"]
    assert not got["unknown_ids"] and len(got["messages"]) == 24
    missing = {n: a["missing"] for b in doc["buses"] for n, a in b["actuators"].items()}
    for m in got["messages"]:
        node = m["name"].rsplit("_", 2)[0] if m["name"].endswith("_mit_command") else m["name"].rsplit("_", 1)[0]
        assert m["count"] == 27 - (missing[node] if m["name"].endswith("_feedback") else 0), m


def test_run_counts_a_reply_late_from_the_commands_send(tmp_path: Path) -> None:
    """The master times a reply from its command's send, at or after the command's release; the analysis bounds the
    reply from its command's earliest end (netcfg.timing.can_transactions), and that end is at most the command's
    own worst case after its release. So the master's bound is the sum of the two figures `check` reports (never the
    reply's alone, which a reply within the analysis can pass by the command's queueing and frame)."""
    from conftest import runtime_config

    from netcfg.check import analyse_spec
    from netcfg.runtime.actuator_plan import plan_actuators

    spec = arm(tmp_path)
    _, report = analyse_spec(spec)
    rows = {m["name"]: m for b in report["buses"] for m in b["messages"]}
    cfg = runtime_config(spec)
    got = {(c.node, c.command): c.bound_ns for p in plan_actuators(cfg, "arm_can") for c in p.commands}
    for node in ("shoulder", "elbow", "wrist"):
        reply, command = rows[f"{node}_feedback"]["wcrt_ns"], rows[f"{node}_mit_command"]["wcrt_ns"]
        assert got[(node, "mit_command")] == reply + command


def test_a_command_the_host_sent_late_is_named_the_hosts(tmp_path: Path) -> None:
    """A log a host stamped (host_clock: 20 commands each answered 50 us later, closer than a CAN frame can follow
    another: 8 bytes at 1 Mbit/s take 111 us without a stuff bit) in which the master skipped its command at 200 ms:
    one period of the shoulder's 20 ms missing, and its answer with it. On a host's log that is the master's host
    sending late, as a late SYNC is (host_late), not a gap of the bus."""
    spec = arm(tmp_path)
    log = tmp_path / "host.log"
    command, feedback = "001#7FFF7FF000000000", "011#117FFF7FF7FF0000"
    lines = []
    for k in range(20):
        if k == 10:
            continue
        t = 1.0 + 0.020 * k
        lines += [f"({t:.6f}) can0 {command}", f"({t + 50e-6:.6f}) can0 {feedback}"]
    log.write_text("\n".join(lines) + "\n")
    got = json.loads(cli("verify", str(spec), str(log), "--format", "json").stdout)
    kinds = {v["kind"] for v in got["violations"] if v["message"] in ("shoulder_mit_command", "shoulder_feedback")}
    assert "host_late" in kinds and "gap" not in kinds, got["violations"]
