"""Actuator profiles as files: the built-in ones load and name their sources, the how-to's example works, a broken
or unrepresentable profile is refused at its file:line:col with the reason, and the codec imports as the runtime
rule says."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from netcfg.devices.actuator_profile import (
    builtin_actuator_names,
    builtin_actuator_profile,
    load_actuator_profile,
    parse_actuator_profile,
)
from netcfg.diagnostics import SpecError
from netcfg.runtime.actuators import ActuatorCodec
from netcfg.runtime.codec import CodecError

ROOT = Path(__file__).resolve().parent.parent
HOWTO = ROOT / "docs" / "how-to" / "actuator-profile.md"
BUILTIN = {"odrive-cansimple", "cubemars-ak80-9-mit", "damiao-dm-j4310", "robstride-rs03", "myactuator-rmd-x8",
           "moteus"}


def test_builtin_profiles_load_and_name_their_documents() -> None:
    assert set(builtin_actuator_names()) == BUILTIN
    for name in BUILTIN:
        p = builtin_actuator_profile(name)
        assert p.name == name and p.plain["source"]["document"] and p.plain["source"]["version"]
        for m in p.plain["messages"]:
            if m.get("reply"):  # every answered command says how soon, and on what basis
                assert m["reply_delay_us"] and m["delay_basis"].split(":")[0] in ("published", "assumed")
            if m["from"] == "device" and m.get("cyclic"):
                assert m["cyclic"] in p.plain["parameters"]
        assert name in builtin_actuator_names()


def test_every_builtin_message_round_trips() -> None:
    """Each message encodes from its fields' resting values and decodes back as itself (device messages) for
    the parameters' defaults and a node id."""
    params = {"odrive-cansimple": {"node_id": 7}, "cubemars-ak80-9-mit": {"node_id": 2},
              "damiao-dm-j4310": {"node_id": 3}, "robstride-rs03": {"node_id": 12, "host_id": 0xFD},
              "myactuator-rmd-x8": {"node_id": 4}, "moteus": {"node_id": 9}}
    for name, given in params.items():
        codec = ActuatorCodec(builtin_actuator_profile(name).plain, **given)
        for m in codec.messages.values():
            values = {f: (m.by_name[f].lo if m.by_name[f].lo is not None and m.by_name[f].lo > 0 else 0)
                      for f in m.inputs}
            frame = m.encode(values)
            if m.sender == "device":
                got = codec.decode(frame.arbitration_id, frame.is_extended, frame.data)
                assert got is not None and got.message == m.name, (name, m.name)


def _howto_example() -> str:
    return re.findall(r"```yaml title=\"acme-j60.yaml\"\n(.*?)```", HOWTO.read_text(encoding="utf-8"), re.S)[0]


def test_howto_example_is_a_working_profile(tmp_path: Path) -> None:
    path = tmp_path / "acme-j60.yaml"
    path.write_text(_howto_example(), encoding="utf-8")
    profile = load_actuator_profile(path)
    codec = ActuatorCodec(profile.plain, node_id=5)
    frame = codec.encode("command", position=0.5, velocity=0.0, kp=40.0, kd=1.0, torque=0.0)
    assert frame.arbitration_id == 0x105 and len(frame.data) == 8
    reply = codec.decode(0x185, False, bytes(7) + b"\x02")
    assert reply is not None and reply.message == "status" and reply.errors == ("OVER_CURRENT",)
    assert codec.decode(0x186, False, bytes(8)) is None


def _problems(tmp_path: Path, text: str) -> list[str]:
    path = tmp_path / "mine.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(SpecError) as exc:
        load_actuator_profile(path)
    return [f"{d.line}:{d.column} {d.code} {d.message}" for d in exc.value.diagnostics]


HEAD = """profile: mine
format: 1
source: {document: My manual, version: "1"}
parameters:
  node_id: {min: 1, max: 63}
messages:
"""


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ("  cmd: {from: host, id: node_id, size: 8, fields: {a: {start_bit: 0, bits: 8, scael: 2}}}\n",
         r"7:\d+ profile-key unknown key 'scael' in field a \(did you mean 'scale'\?\)"),
        ("  cmd: {from: host, id: node_id << 2 | 0x0C, size: 8}\n",
         r"7:\d+ profile-id cmd: the terms 0xC \(bits 2..3\) and 'node_id' \(bits 2..7\) overlap"),
        ("  cmd: {from: host, id: node_id << 24, size: 8}\n",
         r"profile-id cmd: the identifier needs 30 bits, more than the 11 of a standard identifier"),
        ("  cmd: {from: host, id: node_id * 2, size: 8}\n",
         r"profile-id cmd: cannot represent the identifier term 'node_id \* 2'"),
        ("  cmd: {from: host, id: node_id, size: 8, checksum: xor}\n",
         r"7:\d+ profile-unrepresentable 'checksum' in message cmd: frames with a checksum or CRC"),
        ("  cmd: {from: host, id: node_id, size: 8, subframes: []}\n",
         r"profile-unrepresentable 'subframes' in message cmd: register subframes chosen at run time"),
        ("  cmd: {from: host, id: node_id, size: 4, fields: {a: {start_bit: 24, bits: 16}}}\n",
         r"profile-field a \(bits from 24, 16 wide\) runs past the 4-byte frame"),
        ("  cmd: {from: host, id: node_id, size: 8, fields: {a: {start_bit: 0, bits: 8}, b: {start_bit: 4, bits: 8}}}"
         "\n",
         r"profile-overlap b and a share byte 0 bit 4"),
        ("  cmd: {from: host, id: node_id, size: 8, fields: {a: {start_bit: 0, bits: 8, encoding: span}}}\n",
         r"profile-field a: a span field needs range"),
        ("  cmd: {from: host, id: node_id, size: 8, fields: {a: {start_bit: 0, bits: 8, unit: furlong}}}\n",
         r"profile-unit a: unit 'furlong' is not one netcfg converts to SI"),
        ("  cmd: {from: host, id: node_id, size: 8, reply: {message: st}}\n"
         "  st: {from: device, id: 0x40 + node_id, size: 8}\n",
         r"profile-delay cmd: give the reply's delay as delay_us"),
        ("  cmd: {from: host, id: node_id, size: 8, reply: {message: nope, delay_us: [0, 9], basis: assumed, "
         "note: x}}\n", r"profile-reply cmd replies with 'nope', which is not a message the device sends"),
        ("  cmd: {from: host, id: node_id, size: 12}\n", r"profile-size cmd: size must be one of 0, 1, 2"),
    ],
)
def test_refused_with_position_and_reason(tmp_path: Path, body: str, expected: str) -> None:
    problems = _problems(tmp_path, HEAD + body)
    assert any(re.search(expected, p) for p in problems), problems


def test_every_problem_is_reported_at_once(tmp_path: Path) -> None:
    problems = _problems(tmp_path, "profile: Mine\nformat: 2\nsource: {document: x}\nmessages: {}\nfoo: 1\n")
    codes = sorted(p.split()[1] for p in problems)
    assert codes == ["profile-format", "profile-key", "profile-name", "profile-source"]
    assert _problems(tmp_path, "  \n") == ["1:1 profile-empty the profile is empty; start with 'profile: <name>' "
                                           "and 'format: 1'"]
    assert parse_actuator_profile(HEAD + "  c: {from: host, id: 1, size: 0}\n", "x.yaml").message_names() == ["c"]


def test_codec_parameters() -> None:
    plain = builtin_actuator_profile("robstride-rs03").plain
    with pytest.raises(CodecError, match="has no parameters \\['nod_id'\\]"):
        ActuatorCodec(plain, nod_id=1)
    with pytest.raises(CodecError, match="node_id = 200 is outside"):
        ActuatorCodec(plain, node_id=200, host_id=0)
    with pytest.raises(CodecError, match="needs the parameter 'host_id', which has no value"):
        ActuatorCodec(plain, node_id=1)
    codec = ActuatorCodec(plain, node_id=1, host_id=0)
    assert codec.encode("write_run_mode", run_mode="speed").data[4] == 2  # a value name for its number
    with pytest.raises(CodecError, match="missing \\['kd'\\]"):
        codec.encode("operation_control", position=0, velocity=0, kp=0, torque=0)


def test_runtime_codec_imports_without_the_compiler() -> None:
    code = ("import sys, netcfg.runtime.actuators; "
            "bad = {'pydantic', 'jinja2', 'networkx', 'cantools', 'matplotlib', 'yaml', 'netcfg.model', "
            "'netcfg.spec.schema', 'netcfg.devices'} & set(sys.modules); print(sorted(bad))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


ACTIONS = HEAD + """  go: {from: host, id: node_id, size: 1, fields: {mode: {start_bit: 0, bits: 8,
                                                              choices: {0: LOW, 1: HIGH}}}}
  st: {from: device, id: 0x40 + node_id, size: 1, fields: {s: {start_bit: 0, bits: 8, role: state,
                                                               choices: {0: IDLE, 1: RUN}}}}
"""


@pytest.mark.parametrize(
    ("top", "expected"),
    [
        ("enable: {message: st}\n", r"11:\d+ profile-action enable sends 'st', which is not a message the host sends"),
        ("enable: {message: go}\n", r"11:\d+ profile-action enable: give 'go' the value of mode under 'values:'"),
        ("safe_stop: {message: go, values: {mode: HALF}}\n", r"11:\d+ profile-action mode has no value named 'HALF'"),
        ("safe_stop: {message: go, values: {mode: 0, gear: 1}}\n", r"11:\d+ profile-action 'go' has no field 'gear'"),
        ("enable: {message: go, values: {mode: HIGH}, state: {s: FAST}}\n",
         r"11:\d+ profile-action enable state: s has no value named 'FAST'"),
        ("enable: {message: go, values: {mode: HIGH}, state: {t: RUN}}\n",
         r"11:\d+ profile-action enable state: 't' is not a state field of a device message"),
    ],
)
def test_enable_and_safe_stop_are_host_messages_with_every_value(tmp_path: Path, top: str, expected: str) -> None:
    """`enable:` / `safe_stop:` (what `netcfg run` sends before the cycle and to stop) name a host message and give
    each of its fields a value (a number or one of its value names); `state:` names a device state field's value."""
    problems = _problems(tmp_path, ACTIONS + top)
    assert any(re.search(expected, p) for p in problems), problems
    good = parse_actuator_profile(ACTIONS + "enable: {message: go, values: {mode: HIGH}, state: {s: RUN}}\n"
                                  "safe_stop: {message: go, values: {mode: 0}}\n", "x.yaml").plain
    assert good["enable"] == {"message": "go", "values": {"mode": "HIGH"}, "state": {"s": "RUN"}}
    assert good["safe_stop"] == {"message": "go", "values": {"mode": 0}, "state": {}}
