"""runtime.json and netcfg.runtime: typed access for a live master, without the compiler.

Numbers come from the specs (specs/*.yaml), CiA 301 (pre-defined connection set: RPDO1 = 0x200 + node id,
TPDO1 = 0x180 + node id, SYNC = 0x080; PDO data little-endian) and seed 001's Table 6.1 (a UDP payload is one
byte of message id, 0x31 PWM or 0x42 encoder, then the data).
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import can
import pytest
from conftest import ROOT, SPECS

import netcfg.runtime as rt
from netcfg.build import build


def build_into(spec: str, out: Path) -> Path:
    report, target, _ = build(SPECS / spec, out)
    assert target is not None, report["errors"]
    return target / "runtime.json"


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("runtime")
    return {name: build_into(f"{name}.yaml", base / name) for name in ("allex2", "cambada", "ntua_sahr")}


@pytest.fixture(scope="module")
def allex2(built: dict[str, Path]) -> rt.RuntimeConfig:
    return rt.load(built["allex2"])


@pytest.fixture(scope="module")
def sahr(built: dict[str, Path]) -> rt.RuntimeConfig:
    return rt.load(built["ntua_sahr"])


def test_rpdo_encodes_little_endian_as_cia301(allex2: rt.RuntimeConfig) -> None:
    """hip_l_cmd is RPDO1 of node 1 mapping 0x60FF target velocity then 0x60B1 velocity offset, both INTEGER32.
    CiA 301 sends PDO data little-endian: 1000 = 0x000003E8 -> e8 03 00 00; -5 = 0xFFFFFFFB -> fb ff ff ff."""
    cmd = allex2.message("hip_l_cmd")
    data = cmd.encode(target_velocity=1000, velocity_offset=-5)
    assert data == bytes([0xE8, 0x03, 0x00, 0x00, 0xFB, 0xFF, 0xFF, 0xFF])
    assert cmd.decode(data) == {"target_velocity": 1000, "velocity_offset": -5}


def test_decode_round_trips_every_message(allex2: rt.RuntimeConfig) -> None:
    for msg in allex2.messages:
        # the largest value each field holds: all ones for unsigned, 2^(n-1) - 1 for signed
        values = {f.name: f.raw_range()[1] for f in msg.fields}
        assert msg.decode(msg.encode(**values)) == values, msg.name


def test_to_can_and_decode_can(allex2: rt.RuntimeConfig) -> None:
    frame = allex2.message("hip_l_cmd").to_can(target_velocity=1000, velocity_offset=-5)
    assert isinstance(frame, can.Message)
    assert frame.arbitration_id == 0x201  # CiA 301 RPDO1 of node 1: 0x200 + 1
    assert frame.is_extended_id is False and frame.dlc == 8
    msg, values = allex2.decode_can(frame)
    assert msg.name == "hip_l_cmd" and values == {"target_velocity": 1000, "velocity_offset": -5}
    # a drive's answer: TPDO1 of node 1 is 0x181, position then velocity actual value (INTEGER32 each)
    reply = can.Message(arbitration_id=0x181, is_extended_id=False, data=bytes([1, 0, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF]))
    msg, values = allex2.decode_can(reply)
    assert msg.name == "hip_l_state" and msg.producer == "hip_l"
    assert values == {"position_actual_value": 1, "velocity_actual_value": -1}


def test_unknown_can_id_and_wrong_length_are_reported(allex2: rt.RuntimeConfig) -> None:
    with pytest.raises(KeyError, match="0x7FF"):
        allex2.decode_can(can.Message(arbitration_id=0x7FF, is_extended_id=False, data=b""))
    with pytest.raises(rt.CodecError, match=r"hip_l_cmd.*8 bytes"):
        allex2.decode_can(can.Message(arbitration_id=0x201, is_extended_id=False, data=b"\x00" * 4))


def test_canopen_parameters_are_typed(allex2: rt.RuntimeConfig) -> None:
    """allex2.yaml: SYNC every 20 ms, read window 10 ms; SYNC's COB-ID is CiA 301's 0x080, sent by the master."""
    co = allex2.bus("can0").canopen
    assert co is not None
    assert (co.sync_period_ns, co.read_window_ns) == (20_000_000, 10_000_000)
    assert (co.sync_id, co.sync_producer) == (0x80, "master")
    sync = allex2.message("can0_SYNC")
    assert (sync.implicit, sync.id, sync.size, sync.encode()) == ("SYNC", 0x80, 0, b"")
    hip = allex2.node("hip_l")
    assert (hip.node_id, hip.device) == (1, "epos4")
    # Table 5 of seed 000: the write process takes 225.8 us to 8557.3 us; it runs 10 ms after each SYNC
    control = allex2.task("master.control")
    assert (control.period_ns, control.bcet_ns, control.wcet_ns) == (20_000_000, 225_800, 8_557_300)
    assert (control.sync_bus, control.offset_ns) == ("can0", 10_000_000)
    pdo = allex2.message("hip_l_effort").pdo
    assert pdo is not None and [(e.index, e.sub) for e in pdo.entries] == [(0x6077, 0), (0x30D1, 2)]


def test_udp_payload_is_message_id_then_data(sahr: rt.RuntimeConfig) -> None:
    """Seed 001, Table 6.1: one byte of message id (0x42 encoder, 4 bytes; 0x31 PWM, 1 byte), then the data.
    The spec gives only sizes, so each message has one raw field; 0x04D2 = 1234 little-endian is d2 04 00 00."""
    enc = sahr.message("hip_encoder")
    datagram = enc.encode_udp(hip_encoder_raw=1234)
    assert datagram == bytes([0x42, 0xD2, 0x04, 0x00, 0x00])
    assert enc.encode_udp(hip_encoder_raw=bytes([0xD2, 0x04, 0x00, 0x00])) == datagram  # raw bytes as they are
    assert sahr.message("hip_pwm").encode_udp(hip_pwm_raw=0x80) == bytes([0x31, 0x80])
    assert enc.rate_hz == Fraction(15_000)  # ntua_sahr.yaml: rate 15 kHz, kept exact
    assert enc.udp == rt.UdpPorts(5001, 6001)


def test_decode_udp_tells_same_id_messages_apart_by_port(sahr: rt.RuntimeConfig) -> None:
    """Both encoders send id 0x42 (ntua_sahr.yaml); their destination ports are 6001 (hip) and 6002 (spring)."""
    datagram = bytes([0x42, 0xD2, 0x04, 0x00, 0x00])
    with pytest.raises(LookupError, match="hip_encoder, spring_encoder"):
        sahr.decode_udp("lan", datagram)
    msg, values = sahr.decode_udp("lan", datagram, dst_port=6002)
    assert msg.name == "spring_encoder" and values == {"spring_encoder_raw": 1234}
    msg, _ = sahr.decode_udp("lan", bytes([0x31, 0x10]))
    assert msg.name == "hip_pwm"


def test_can_and_udp_calls_are_not_mixed(allex2: rt.RuntimeConfig, sahr: rt.RuntimeConfig) -> None:
    with pytest.raises(TypeError, match="encode_udp"):
        sahr.message("hip_pwm").to_can(hip_pwm_raw=1)
    with pytest.raises(TypeError, match="to_can"):
        allex2.message("hip_l_cmd").encode_udp(target_velocity=1, velocity_offset=0)


def test_encoding_errors_name_the_message(allex2: rt.RuntimeConfig) -> None:
    with pytest.raises(rt.CodecError, match=r"hip_l_cmd.*missing fields \['velocity_offset'\]"):
        allex2.message("hip_l_cmd").encode(target_velocity=1)
    with pytest.raises(rt.CodecError, match="does not fit 32 bits"):
        allex2.message("hip_l_cmd").encode(target_velocity=2**31, velocity_offset=0)


def test_unknown_message_name_suggests_close_matches(allex2: rt.RuntimeConfig) -> None:
    with pytest.raises(KeyError) as err:
        allex2.message("hip_l_comd")
    assert "no message named 'hip_l_comd'" in str(err.value) and "'hip_l_cmd'" in str(err.value)
    with pytest.raises(KeyError, match="no bus named 'can1'"):
        allex2.bus("can1")
    with pytest.raises(KeyError, match="did you mean 'hip_l'"):
        allex2.node("hip_L")


def test_ftt_schedule_is_carried(built: dict[str, Path]) -> None:
    """cambada.yaml: EC 5 ms, 5-byte TM, periods 1, 2, 6 and 10 EC -> macro-cycle lcm = 30 ECs, in which a
    message of period p EC is due 30 / p times (encoder1: 2 EC -> 15; odo_position: 10 EC -> 3)."""
    cfg = rt.load(built["cambada"])
    ftt = cfg.bus("lowlevel").ftt
    assert ftt is not None
    assert (ftt.ec_ns, ftt.tm_size, ftt.macro_cycle_ec, len(ftt.schedule)) == (5_000_000, 5, 30, 30)
    assert sum("encoder1" in s.messages for s in ftt.schedule) == 15
    assert sum("odo_position" in s.messages for s in ftt.schedule) == 3
    assert sum("encoder_read" in s.triggers for s in ftt.schedule) == 30  # trigger 8, every EC
    for s in ftt.schedule:
        assert s.mask == sum(1 << i for i in s.ids)  # the TM's EC-schedule: bit i = FTT id i
    assert ftt.slot(31) == ftt.schedule[1]
    assert cfg.trigger("pose_produce").tasks == ("odometry.pose",)
    assert [s.refs for s in cfg.flow("motion").steps][1] == ("holonomic.convert",)


def test_unknown_version_is_rejected_clearly(built: dict[str, Path], tmp_path: Path) -> None:
    data = json.loads(built["allex2"].read_text())
    data["version"] = 99
    path = tmp_path / "future.json"
    path.write_text(json.dumps(data))
    with pytest.raises(rt.RuntimeConfigError) as err:
        rt.load(path)
    text = str(err.value)
    assert str(path) in text and "version 99" in text and "reads version 1" in text
    data["format"] = "something-else"
    path.write_text(json.dumps(data))
    with pytest.raises(rt.RuntimeConfigError, match="not a netcfg runtime config"):
        rt.load(path)
    path.write_text("{not json")
    with pytest.raises(rt.RuntimeConfigError, match=r"future\.json"):
        rt.load(path)


def test_malformed_config_names_the_file(built: dict[str, Path], tmp_path: Path) -> None:
    data = json.loads(built["allex2"].read_text())
    del data["messages"][0]["size"]
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(data))
    with pytest.raises(rt.RuntimeConfigError, match=r"broken\.json.*'size'"):
        rt.load(path)


def test_runtime_json_is_identical_across_builds(built: dict[str, Path], tmp_path: Path) -> None:
    again = build_into("allex2.yaml", tmp_path / "again")
    assert again.read_bytes() == built["allex2"].read_bytes()
    assert str(ROOT) not in again.read_text()  # no machine paths


def test_spec_hash_is_the_sha256_of_the_spec_file(built: dict[str, Path]) -> None:
    for name, path in built.items():
        expected = hashlib.sha256((SPECS / f"{name}.yaml").read_bytes()).hexdigest()
        cfg = rt.load(path)
        assert cfg.spec_sha256 == expected
        assert cfg.matches_spec(SPECS / f"{name}.yaml") and not cfg.matches_spec(SPECS / "large_plant.yaml")


def test_runtime_does_not_import_the_compiler(built: dict[str, Path]) -> None:
    """A master loads its config and exchanges frames with netcfg.runtime alone."""
    code = (
        "import json, sys, netcfg.runtime as rt\n"
        f"cfg = rt.load({str(built['allex2'])!r})\n"
        "cfg.message('hip_l_cmd').encode(target_velocity=1, velocity_offset=2)\n"
        "print(json.dumps(sorted(sys.modules)))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 0, proc.stderr
    loaded = json.loads(proc.stdout)
    compiler = ("netcfg.spec", "netcfg.resolve", "netcfg.model", "netcfg.timing", "netcfg.emit")
    assert [m for m in loaded if m.startswith(compiler)] == []
    assert "netcfg.runtime" in loaded and "pydantic" not in loaded and "yaml" not in loaded
