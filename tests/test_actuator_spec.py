"""Actuator nodes in a spec: `device:` an actuator profile and `actuator:` its setup become ordinary messages and
tasks that check analyses; their mistakes are reported at the spec's line. The quadruped example's bus load is
computed here by hand from ISO 11898-1's frame layout, not read from netcfg."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import ROOT, check, check_data

from netcfg.devices.actuator_profile import builtin_actuator_profile
from netcfg.runtime.actuators import ActuatorCodec
from netcfg.runtime.codec import Field

QUADRUPED = ROOT / "examples" / "quadruped_mit.yaml"


def joint(name: str, node_id: int, master_id: int, **actuator: Any) -> dict[str, Any]:
    setup: dict[str, Any] = {"parameters": {"master_id": master_id},
                             "commands": [{"message": "mit_command", "rate": "1 kHz"}]}
    setup.update(actuator)
    return {"name": name, "node_id": node_id, "buses": ["can0"], "device": "damiao-dm-j4310", "actuator": setup}


def spec(*nodes: dict[str, Any], protocol: str = "can") -> dict[str, Any]:
    bus: dict[str, Any] = {"name": "can0", "protocol": protocol, "bitrate": "1 Mbit/s"}
    if protocol == "can-fd":
        bus["data_bitrate"] = "5 Mbit/s"
    return {
        "system": "arm",
        "buses": [bus],
        "nodes": [{"name": "host", "role": "master", "buses": ["can0"],
                   "tasks": [{"name": "control", "period": "1 ms", "wcet": "100 us"}]}, *nodes],
    }


def errors(tmp_path: Path, data: dict[str, Any]) -> list[dict[str, Any]]:
    return check_data(tmp_path, data)["errors"]


def test_a_command_its_reply_and_the_task_between_them(tmp_path: Path) -> None:
    from netcfg.check import analyse_spec

    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(spec(joint("j1", 1, 0x11))))
    model, report = analyse_spec(path)
    assert model is not None and not report["errors"], report["errors"]
    cmd, reply = model.messages["j1_mit_command"], model.messages["j1_feedback"]
    assert (cmd.id, cmd.producer, cmd.consumers, cmd.period_ns, cmd.size) == (0x01, "host", ("j1",), 1_000_000, 8)
    assert (reply.id, reply.producer, reply.consumers, reply.period_ns) == (0x11, "j1", ("host",), 1_000_000)
    task = model.task("j1.mit_command")
    assert (task.on_message, task.bcet_ns, task.wcet_ns) == ("j1_mit_command", 0, 500_000)  # the profile's 0..500 us
    assert model.sent_by["j1_feedback"] == ("j1.mit_command",)
    rows = {r["name"]: r for r in report["buses"][0]["messages"]}
    # the reply's release jitter is its command's response range plus the reply delay: it answers after both
    assert rows["j1_feedback"]["wcrt_us"] > rows["j1_mit_command"]["wcrt_us"] + 500


def test_span_signals_are_the_linear_map_the_codec_decodes() -> None:
    """A span field as a signal: raw * (hi - lo) / (2^bits - 1) + lo is the codec's decoding (its encoding truncates
    where a DBC factor would round: the one difference)."""
    from netcfg.resolve.actuators import _signal

    profile = builtin_actuator_profile("damiao-dm-j4310")
    codec = ActuatorCodec(profile.plain, node_id=1)
    mc = codec.message("feedback")
    plain = {f["name"]: f for f in next(m for m in profile.plain["messages"] if m["name"] == "feedback")["fields"]}
    for f in mc.payload:
        if f.encoding != "span":
            continue
        s = _signal(f, plain[f.name])
        for raw in (0, 1, 1000, (1 << f.bits) - 1):
            assert raw * s.scale + s.offset == pytest.approx(f.from_raw(raw, si=False), abs=1e-12)
        assert Field(s.name, s.start_bit, s.bits, big_endian=s.big_endian).ops == f.layout.ops


def test_quadruped_bus_load_by_hand() -> None:
    """ISO 11898-1, worst-case stuffing (as tests/test_frames.py): a standard frame with s data bytes is
    47 + 8s bits (44 of frame, 3 of intermission) and at most floor((34 + 8s - 1) / 4) stuff bits."""
    s = 8
    bits = 47 + 8 * s + (34 + 8 * s - 1) // 4
    assert bits == 135
    frames_per_ms = 3 * 2  # three joints per leg bus, a command and its reply each
    load_1khz = frames_per_ms * bits / 1000  # at 1 Mbit/s a bit is 1 us; a cycle is 1000 us
    assert load_1khz == pytest.approx(0.81)
    assert 2 * load_1khz > 1  # a 2 kHz loop (a second command per cycle) needs 162 % of each bus: it cannot fit
    report = check(QUADRUPED)
    assert len(report["buses"]) == 4
    for bus in report["buses"]:
        assert len(bus["messages"]) == 6
        assert bus["utilization"] == pytest.approx(load_1khz, abs=5e-4)
        assert {r["frame_bits_worst"] for r in bus["messages"]} == {bits}
    # the load fits, the worst-case replies do not: each is late past the 1 ms cycle (the example's header says why)
    late = {e["message"].split("'")[1] for e in report["errors"] if e["code"] == "deadline"}
    assert late == {f"{leg}_{j}_feedback" for leg in ("fl", "fr", "rl", "rr") for j in ("hip", "thigh", "knee")}
    (flow,) = report["flows"]
    assert flow["name"] == "control_loop" and 0 < flow["latency_min_us"] < flow["latency_max_us"] < 10_000


def test_profile_file_and_cyclic_rates(tmp_path: Path) -> None:
    """A profile from a file, like a vendor EDS; the device's own messages at their rates (ODrive: heartbeat and
    encoder estimates on by default)."""
    from netcfg.check import analyse_spec

    src = ROOT / "netcfg" / "devices" / "actuators" / "odrive-cansimple.yaml"
    (tmp_path / "mine.yaml").write_text(src.read_text())
    node = {"name": "axis0", "node_id": 3, "buses": ["can0"], "device": {"actuator": "mine.yaml"},
            "actuator": {"commands": [{"message": "set_input_torque", "period": "2 ms"}],
                         "cyclic": [{"message": "heartbeat", "period": "50 ms"}]}}
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(spec(node)))
    model, report = analyse_spec(path)
    assert model is not None and not report["errors"], report["errors"]
    assert model.messages["axis0_set_input_torque"].id == 3 << 5 | 0x0E
    assert model.messages["axis0_heartbeat"].period_ns == 50_000_000
    assert model.messages["axis0_get_encoder_estimates"].period_ns == 10_000_000  # the default rate
    assert "axis0_get_iq" not in model.messages  # 0 by default: off


BASE = spec(joint("j1", 1, 0x11), joint("j2", 2, 0x12))


def mutate(change: Any) -> dict[str, Any]:
    data = copy.deepcopy(BASE)
    change(data)
    return data


def _set(path: list[Any], value: Any) -> Any:
    def change(data: dict[str, Any]) -> None:
        target = data
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    return change


CASES = {
    "unknown profile": (_set(["nodes", 1, "device"], "damiao-dm-j431"), "unknown-device",
                        "did you mean 'damiao-dm-j4310'"),
    "a command the profile lacks": (_set(["nodes", 1, "actuator", "commands", 0, "message"], "mit_comand"),
                                    "actuator-message", "did you mean 'mit_command'"),
    "a device message as a command": (_set(["nodes", 1, "actuator", "commands", 0, "message"], "feedback"),
                                      "actuator-message", "one of the device's own"),
    "a rate faster than the reply": (_set(["nodes", 1, "actuator", "commands", 0, "rate"], "4 kHz"),
                                     "actuator-rate", "before the answer may come"),
    "a cyclic message that is not": (_set(["nodes", 1, "actuator", "cyclic"],
                                          [{"message": "feedback", "period": "1 ms"}]),
                                     "actuator-cyclic", "only when asked"),
    "an unknown parameter": (_set(["nodes", 1, "actuator", "parameters", "p_mx"], 3), "actuator-parameter",
                             "did you mean 'p_max'"),
    "a parameter out of range": (_set(["nodes", 1, "actuator", "parameters", "master_id"], 5000), "actuator-parameter",
                                 "outside"),
    "colliding identifiers": (_set(["nodes", 2, "actuator", "parameters", "master_id"], 0x11), "duplicate-id",
                              "collides with 'j1_feedback'"),
    "a reply on a command's identifier": (_set(["nodes", 2, "actuator", "parameters", "master_id"], 0x01),
                                          "duplicate-id", "j1_mit_command"),
    "no master to command it": (_set(["nodes", 0, "role"], "slave"), "actuator-commander", "commanded_by"),
    "commanded by a stranger": (_set(["nodes", 1, "actuator", "commanded_by"], "hots"), "unknown-node",
                                "did you mean 'host'"),
    "a profile on the wrong link": (_set(["nodes", 1, "device"], "moteus"), "actuator-link", "can-fd"),
    "actuator without a profile": (_set(["nodes", 0, "actuator"], {"commands": []}), "wrong-section", "device"),
}


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_mistakes_are_reported_at_their_line(tmp_path: Path, case: str) -> None:
    change, code, words = CASES[case]
    got = errors(tmp_path, mutate(change))
    assert any(e["code"] == code and words in e["message"] for e in got), got
    assert all(e["line"] > 1 for e in got)


def test_actuator_on_a_canopen_bus_is_refused(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["buses"][0] = {"name": "can0", "protocol": "canopen", "bitrate": "1 Mbit/s",
                        "canopen": {"sync_period": "1 ms"}}
    data["nodes"][0]["node_id"] = 100
    got = errors(tmp_path, data)
    assert any(e["code"] == "actuator-link" and "can or can-fd" in e["message"] for e in got), got


def test_errors_in_a_profile_file_are_at_the_profile_s_line(tmp_path: Path) -> None:
    (tmp_path / "bad.yaml").write_text("profile: bad-one\nformat: 1\nsource: {document: d, version: v}\n"
                                       "messages:\n  x: {from: hots, id: 1, size: 8}\n")
    data = mutate(_set(["nodes", 1, "device"], {"actuator": "bad.yaml"}))
    got = errors(tmp_path, data)
    assert any(e["file"].endswith("bad.yaml") and e["line"] == 5 for e in got), got


def test_runtime_json_carries_what_the_codec_needs(tmp_path: Path) -> None:
    """A master builds each actuator's codec from runtime.json alone; the frames are the profile's own."""
    from conftest import runtime_config_of

    from netcfg.runtime.schema import check_document

    cfg = runtime_config_of(tmp_path / "spec.yaml", spec(joint("j1", 1, 0x11)))
    node = next(n for n in cfg.nodes if n.name == "j1")
    assert node.actuator is not None and node.actuator.commanded_by == "host"
    (command,) = node.actuator.commands
    assert (command.command, command.message, command.reply, command.reply_message) == (
        "mit_command", "j1_mit_command", "feedback", "j1_feedback")
    values = {"position": 0.5, "velocity": -1.0, "kp": 20.0, "kd": 1.0, "torque": 0.25}
    expected = ActuatorCodec(builtin_actuator_profile("damiao-dm-j4310").plain, node_id=1, master_id=0x11)
    got = node.actuator.codec().encode("mit_command", values)
    assert got == expected.encode("mit_command", values)
    assert got.arbitration_id == next(m for m in cfg.messages if m.name == "j1_mit_command").id
    # a node without the key (every runtime.json written before it) has no actuator
    assert next(n for n in cfg.nodes if n.name == "host").actuator is None
    # a profile that no longer makes a codec is the file's problem, named
    import json

    from netcfg.check import analyse_spec
    from netcfg.emit.runtime_json import runtime_document

    model, report = analyse_spec(tmp_path / "spec.yaml")
    assert model is not None
    doc = json.loads(json.dumps(runtime_document(model, report)))
    assert check_document(doc, strict=True) == []
    j1 = next(n for n in doc["nodes"] if n["name"] == "j1")
    j1["actuator"]["parameters"] = [p for p in j1["actuator"]["parameters"] if p[0] != "node_id"]
    assert any("do not make a codec" in p for p in check_document(doc))


def test_dbc_and_header_say_what_their_signals_cannot(tmp_path: Path) -> None:
    from conftest import cli

    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(spec(joint("j1", 1, 0x11))))
    assert cli("build", str(path), "-o", str(tmp_path / "out")).returncode == 0
    dbc = (tmp_path / "out" / "dbc" / "can0.dbc").read_text()
    assert 'CM_ BO_ 1 "damiao-dm-j4310 mit_command; position, velocity, kp, kd, torque MIT-packed' in dbc
    assert "SG_ position : 15|16@0+ (0.00038147554741741054,-12.5) [-12.5|12.5]" in dbc
    header = (tmp_path / "out" / "c" / "host.h").read_text()
    assert "truncate to the count below" in header


def test_tune_keeps_what_the_profile_fixes(tmp_path: Path) -> None:
    """An actuator's identifiers are its firmware's, and the spec has no place for their offsets: tune reorders the
    others only, and writes a spec check accepts."""
    from conftest import cli

    data = spec(joint("j1", 1, 0x11, commands=[{"message": "mit_command", "rate": "250 Hz"}]))
    data["nodes"].append({"name": "other", "buses": ["can0"]})
    data["messages"] = [{"name": f"status{k}", "producer": "other", "consumers": ["host"], "id": 0x300 + k,
                         "size": 8, "period": "10 ms"} for k in range(2)]
    path, out = tmp_path / "spec.yaml", tmp_path / "tuned.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    done = cli("tune", str(path), "-o", str(out), "--robust")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "j1_" not in done.stdout
    assert check(out)["ok"]
    tuned = yaml.safe_load(out.read_text())
    assert tuned["nodes"][1]["actuator"] == data["nodes"][1]["actuator"]
    assert {m["id"] for m in tuned["messages"]} == {0x300, 0x301}
