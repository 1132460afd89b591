"""runtime.json and netcfg.runtime: typed access for a live master, without the compiler.

Numbers come from the specs (specs/*.yaml), CiA 301 (pre-defined connection set: RPDO1 = 0x200 + node id,
TPDO1 = 0x180 + node id, SYNC = 0x080; PDO data little-endian; PDO COB-ID bit 31 = not valid, bit 30 = no RTR,
bit 29 = 29-bit identifier; data type codes 0x02 INTEGER8, 0x05 UNSIGNED8), CiA 402 (0x60C2 interpolation time
period: sub 1 value, sub 2 index, period = value * 10^index s), maxon's EDS of the EPOS4 50/5 in ../shared/devices/
([DeviceInfo] VendorNumber 0x000000FB, ProductNumber 0x61500000, RevisionNumber 0x01700000; 4 RPDO and 4 TPDO
communication objects 0x1400-0x1403, 0x1800-0x1803) and seed 001's Table 6.1 (a UDP payload is one byte of message
id, 0x31 PWM or 0x42 encoder, then the data).
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
import sys
from fractions import Fraction
from pathlib import Path
from typing import Any

import can
import canopen
import pytest
import yaml
from conftest import EPOS4_EDS, ROOT, SPECS, check, load_spec

import netcfg.runtime as rt
from netcfg.build import build
from netcfg.runtime import codec


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
    The spec gives only sizes, so each message has one raw field; the paper gives no byte order, netcfg's codec
    is little-endian (netcfg.runtime.codec), so 0x04D2 = 1234 is d2 04 00 00."""
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
    """A master loads its config and exchanges frames with netcfg.runtime alone (and netcfg.cia301 for CANopen): no
    compiler module (spec, resolve, model, timing, emit, devices) is loaded."""
    code = (
        "import json, sys, netcfg.runtime as rt, netcfg.runtime.canopen_master, netcfg.runtime.drives\n"
        f"cfg = rt.load({str(built['allex2'])!r})\n"
        "cfg.message('hip_l_cmd').to_can(target_velocity=1, velocity_offset=2)\n"
        "print(json.dumps(sorted(sys.modules)))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 0, proc.stderr
    loaded = json.loads(proc.stdout)
    # netcfg.cia301 is allowed: a table of the standard with no dependencies, from which the CANopen master and the
    # drives take COB-ID, PDO and data type rules as the compiler does; netcfg.inputs, the input guard every reader
    # goes through (standard library only)
    allowed = ("netcfg.runtime", "netcfg.cia301", "netcfg.inputs")
    # and the link layer's python-can frames, through which the frame went to python-can (it imports nothing of
    # netcfg, and the layer's package loads no link until asked for one)
    frames = {"netcfg.links", "netcfg.links.pycan_frames"}
    assert [m for m in loaded if m.startswith("netcfg.") and not m.startswith(allowed) and m not in frames] == []
    assert frames <= set(loaded)
    assert "netcfg.runtime" in loaded and "pydantic" not in loaded and "yaml" not in loaded


# --- CANopen device facts and the simulator's bounds (keys added within version 1) ------------------------------------

NEW_NODE_KEYS = ("identity", "eds", "dcf", "sdo_init", "rpdo_count", "tpdo_count")
NEW_PDO_KEYS = ("cob_id",)
NEW_FLOW_KEYS = ("unsync_latency_min_ns", "unsync_latency_max_ns")
DRIVES = ("hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r")  # specs/allex2.yaml, device epos4
EPOS4_VENDOR = 0x000000FB  # maxon_epos4_50-5.eds [DeviceInfo] VendorNumber; also epos4.yaml vendor_id
EPOS4_50_5_PRODUCT = 0x61500000  # maxon_epos4_50-5.eds [DeviceInfo] ProductNumber (the 50/5 variant only)
EPOS4_50_5_REVISION = 0x01700000  # maxon_epos4_50-5.eds [DeviceInfo] RevisionNumber
UNSIGNED8, INTEGER8 = 0x05, 0x02  # CiA 301 table 44; the EDS's 60C2sub1 / 60C2sub2 DataType
PDO_INVALID, NO_RTR, EXTENDED = 1 << 31, 1 << 30, 1 << 29  # CiA 301 PDO COB-ID bits


def vendor_eds_build(tmp_path: Path) -> rt.RuntimeConfig:
    """allex2 with every drive described by maxon's EDS instead of the built-in profile."""
    shutil.copy(EPOS4_EDS, tmp_path / "epos4.eds")
    data = load_spec("allex2.yaml")
    for node in data["nodes"]:
        if node.get("device") == "epos4":
            node["device"] = {"eds": "epos4.eds"}
    spec = tmp_path / "allex2_vendor.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    report, target, _ = build(spec, tmp_path / "out")
    assert target is not None, report["errors"]
    return rt.load(target / "runtime.json")


def eds_pdo_objects(text: str) -> tuple[int, int]:
    """How many RPDO (0x1400-0x15FF) and TPDO (0x1800-0x19FF) communication objects an EDS/DCF defines."""
    heads = {int(h, 16) for h in re.findall(r"^\[([0-9A-Fa-f]{4})\]", text, re.MULTILINE)}
    return sum(0x1400 <= h < 0x1600 for h in heads), sum(0x1800 <= h < 0x1A00 for h in heads)


def test_identity_comes_from_the_device_profile(allex2: rt.RuntimeConfig, sahr: rt.RuntimeConfig) -> None:
    """The built-in epos4 profile knows maxon's vendor id; its product code differs per variant (allex2.yaml's
    drives are 50/8, the shared EDS is the 50/5's), so it stays unknown rather than guessed, as does the revision."""
    for name in DRIVES:
        assert allex2.node(name).identity == rt.NodeIdentity(EPOS4_VENDOR, None, None), name
    assert allex2.node("master").identity is None  # no device profile: nothing to check
    assert all(n.identity is None for n in sahr.nodes)  # Ethernet nodes


@pytest.mark.usefixtures("needs_shared")
def test_identity_and_pdo_counts_from_a_vendor_eds(tmp_path: Path) -> None:
    """With maxon's EDS as the device, its [DeviceInfo] gives all three identity values (0x1018 has no
    DefaultValue there), and its 0x1400-0x1403 / 0x1800-0x1803 give the PDO counts."""
    cfg = vendor_eds_build(tmp_path)
    rx, tx = eds_pdo_objects(EPOS4_EDS.read_text(encoding="latin-1"))
    assert (rx, tx) == (4, 4)
    for name in DRIVES:
        node = cfg.node(name)
        assert node.identity == rt.NodeIdentity(EPOS4_VENDOR, EPOS4_50_5_PRODUCT, EPOS4_50_5_REVISION), name
        assert (node.rpdo_count, node.tpdo_count) == (rx, tx)
        # the spec's heartbeat (0x1017, UNSIGNED16 = 0x0006 in CiA 301 table 44), then the EDS's own data types
        # for 0x60C2; maxon's EDS has no 0x1007 or 0x1019 to write
        assert [(w.index, w.sub, w.data_type) for w in node.sdo_init or ()] == [
            (0x1017, 0, 0x0006),
            (0x60C2, 1, UNSIGNED8),
            (0x60C2, 2, INTEGER8),
        ]


@pytest.mark.usefixtures("needs_shared")
def test_pdo_counts_equal_the_eds_pdo_objects(allex2: rt.RuntimeConfig, built: dict[str, Path]) -> None:
    """The built-in profile's counts equal the vendor EDS's number of PDO communication objects, and the generated
    DCF of each drive defines exactly that many (NrOfRXPDO / NrOfTXPDO too)."""
    vendor = eds_pdo_objects(EPOS4_EDS.read_text(encoding="latin-1"))
    for name in DRIVES:
        node = allex2.node(name)
        assert (node.rpdo_count, node.tpdo_count) == vendor, name
        assert node.dcf is not None
        dcf = (built["allex2"].parent / node.dcf).read_text(encoding="ascii")
        assert eds_pdo_objects(dcf) == vendor
        assert f"NrOfRXPDO={vendor[0]}\n" in dcf and f"NrOfTXPDO={vendor[1]}\n" in dcf
    master = allex2.node("master")
    assert (master.rpdo_count, master.tpdo_count) == (None, None)  # no device profile


def test_eds_and_dcf_name_the_files_the_build_wrote(allex2: rt.RuntimeConfig, built: dict[str, Path]) -> None:
    """Every CANopen file the build wrote is named by exactly one node, and each named file exists, relative to
    the runtime.json's folder; the master without a device profile has a DCF only."""
    hip = allex2.node("hip_l")
    assert (hip.eds, hip.dcf) == ("canopen/hip_l.eds", "canopen/hip_l.dcf")
    assert allex2.path("canopen/hip_l.eds") == built["allex2"].parent / "canopen" / "hip_l.eds"
    master = allex2.node("master")
    assert (master.eds, master.dcf) == (None, "canopen/master.dcf")
    named = sorted(f for n in allex2.nodes for f in (n.eds, n.dcf) if f is not None)
    folder = built["allex2"].parent
    written = sorted(str(p.relative_to(folder)) for p in (folder / "canopen").glob("*.[ed][dc][sf]"))
    assert named == written and len(named) == 2 * len(DRIVES) + 1
    with pytest.raises(ValueError, match="not loaded from a file"):
        rt.parse(json.loads(built["allex2"].read_text())).path("canopen/hip_l.eds")


def test_non_canopen_nodes_have_no_device_facts(built: dict[str, Path]) -> None:
    for name in ("cambada", "ntua_sahr"):
        for node in rt.load(built[name]).nodes:
            assert (node.eds, node.dcf, node.identity, node.rpdo_count, node.tpdo_count) == (None,) * 5
            assert node.sdo_init == ()  # stated: nothing to write


def test_sdo_init_sets_the_cia402_interpolation_period_to_the_sync_period(allex2: rt.RuntimeConfig) -> None:
    """allex2.yaml: SYNC every 20 ms. CiA 402 0x60C2: 20 * 10^-3 s = 20 ms, sub 1 UNSIGNED8, sub 2 INTEGER8.
    Before it the heartbeat the spec gives each drive, 100 ms into 0x1017 (UNSIGNED16, 0x0006 in CiA 301 table 44;
    the built-in EPOS4 profile has no 0x1007 or 0x1019 to write). Nothing else: the spec cannot state the modes of
    operation (0x6060)."""
    want = (
        rt.SdoWrite(0x1017, 0, 0x0006, 100),
        rt.SdoWrite(0x60C2, 1, UNSIGNED8, 20),
        rt.SdoWrite(0x60C2, 2, INTEGER8, -3),
    )
    for name in DRIVES:
        assert allex2.node(name).sdo_init == want, name
    assert allex2.node("master").sdo_init == ()


def test_sdo_init_follows_the_sync_period_unit(tmp_path: Path) -> None:
    """A 7.5 ms SYNC is no whole number of ms: CiA 402 allows 75 * 10^-4 s; 300 ms exceeds an UNSIGNED8 of ms,
    so 30 * 10^-2 s."""
    data = load_spec("allex2.yaml")
    for node in data["nodes"]:
        node.pop("tasks", None)  # task timing that fitted 20 ms is not the point here
    data.pop("flows", None)
    for period, value in (("7.5 ms", (75, -4)), ("300 ms", (30, -2))):
        data["buses"][0]["canopen"] = {"sync_period": period}
        spec = tmp_path / "fast.yaml"
        spec.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
        report, target, _ = build(spec, tmp_path / period.replace(" ", ""))
        assert target is not None, report["errors"]
        writes = rt.load(target / "runtime.json").node("hip_l").sdo_init
        assert writes is not None and tuple(w.value for w in writes if w.index == 0x60C2) == value, period


def test_pdo_cob_id_has_the_cia301_bits_and_equals_the_dcf(allex2: rt.RuntimeConfig, built: dict[str, Path]) -> None:
    """hip_l (node 1): TPDO1 0x180 + 1 with bit 30 (no RTR) = 0x40000181; RPDO1 0x200 + 1 without flags = 0x201; both
    valid (bit 31 clear). Every PDO's value equals 0x14xx/0x18xx sub 1's ParameterValue in the DCF of the node whose
    slot it is, as the canopen package reads it."""
    state, cmd = allex2.message("hip_l_state").pdo, allex2.message("hip_l_cmd").pdo
    assert state is not None and cmd is not None
    assert state.cob_id == NO_RTR | (0x180 + 1) == 0x40000181
    assert cmd.cob_id == 0x200 + 1
    folder = built["allex2"].parent
    ods: dict[str, Any] = {}
    pdos = [m for m in allex2.messages if m.pdo is not None]
    assert len(pdos) == 4 * len(DRIVES)
    for m in pdos:
        assert m.pdo is not None and m.pdo.cob_id is not None
        assert not m.pdo.cob_id & PDO_INVALID and bool(m.pdo.cob_id & EXTENDED) == m.extended
        assert m.pdo.cob_id & 0x7FF == m.id
        node = allex2.node(m.pdo.node)
        assert node.dcf is not None
        od = ods.setdefault(node.name, canopen.import_od(str(folder / node.dcf), node.node_id))
        comm = (0x1400 if m.pdo.kind == "rpdo" else 0x1800) + m.pdo.number - 1
        assert od[comm][1].value == m.pdo.cob_id, m.name


def test_flows_carry_the_unsynchronised_bounds(built: dict[str, Path]) -> None:
    """The analysis report (netcfg check) gives each flow's bounds without SYNC alignment in us; runtime.json has them
    in ns."""
    for name in ("allex2", "cambada", "ntua_sahr"):
        report = check(SPECS / f"{name}.yaml")
        cfg = rt.load(built[name])
        for row in report["flows"]:
            flow = cfg.flow(row["name"])
            unsync = row["unsynchronised"]
            assert flow.unsync_latency_min_ns == round(unsync["latency_min_us"] * 1000), (name, flow.name)
            assert flow.unsync_latency_max_ns == round(unsync["latency_max_us"] * 1000), (name, flow.name)
    # allex2.yaml joint_feedback: SYNC alignment makes the flow slower at best and faster at worst
    flow = rt.load(built["allex2"]).flow("joint_feedback")
    assert flow.unsync_latency_min_ns is not None and flow.latency_min_ns is not None
    assert flow.unsync_latency_max_ns is not None and flow.latency_max_ns is not None
    assert flow.unsync_latency_min_ns < flow.latency_min_ns and flow.unsync_latency_max_ns > flow.latency_max_ns


def test_a_version_1_file_without_the_added_keys_still_loads(built: dict[str, Path], tmp_path: Path) -> None:
    """runtime.json written before the device facts and unsynchronised bounds existed: same version, loads, the
    new fields are None, and everything else is as before."""
    data = json.loads(built["allex2"].read_text())
    new = rt.load(built["allex2"])
    stripped = 0
    for node in data["nodes"]:
        for key in NEW_NODE_KEYS:
            del node[key]
            stripped += 1
    for msg in data["messages"]:
        if msg["pdo"] is not None:
            for key in NEW_PDO_KEYS:
                del msg["pdo"][key]
                stripped += 1
    for flow in data["flows"]:
        for key in NEW_FLOW_KEYS:
            del flow[key]
            stripped += 1
    assert stripped == 6 * 7 + 24 + 2 * len(data["flows"])  # 7 nodes, 24 PDOs (allex2.yaml)
    path = tmp_path / "old.json"
    path.write_text(json.dumps(data))
    old = rt.load(path)
    assert old.version == new.version == 1
    for node in old.nodes:
        assert (node.identity, node.eds, node.dcf, node.sdo_init, node.rpdo_count, node.tpdo_count) == (None,) * 6
    assert all(m.pdo.cob_id is None for m in old.messages if m.pdo is not None)
    assert all(f.unsync_latency_min_ns is None and f.unsync_latency_max_ns is None for f in old.flows)
    assert [m.name for m in old.messages] == [m.name for m in new.messages]
    values = {"target_velocity": 1000, "velocity_offset": -5}
    assert old.message("hip_l_cmd").encode(**values) == new.message("hip_l_cmd").encode(**values)
    assert [(f.latency_min_ns, f.latency_max_ns) for f in old.flows] == [
        (f.latency_min_ns, f.latency_max_ns) for f in new.flows
    ]


@pytest.mark.parametrize(
    ("damage", "text"),
    [
        (lambda d: d["messages"][0].update(period_ns="fast"), "period_ns: must be a whole number, not str"),
        (lambda d: d["messages"][1].update(producer="ghost"), "node 'ghost' is not in the config"),
        (lambda d: d["nodes"][0]["tasks"][0].update(sync_bus="can9"), "bus 'can9' is not in the config"),
        (lambda d: d["flows"][0]["steps"][0].update(refs=["nowhere"]), "message 'nowhere' is not in the config"),
        (lambda d: d.pop("buses"), "missing key 'buses'"),
    ],
)
def test_a_damaged_runtime_config_is_refused_with_what_is_wrong(damage: Any, text: str) -> None:
    """A hand-edited or damaged runtime.json is refused when loaded, naming what is wrong, instead of failing
    later inside a master or the simulator."""
    doc = json.loads((ROOT / "generated" / "allex2" / "runtime.json").read_text())
    damage(doc)
    with pytest.raises(rt.RuntimeConfigError, match=re.escape(text)):
        rt.parse(doc, "damaged.json")


def test_collect_window_is_the_read_window_else_the_sync_window_else_the_period() -> None:
    """How long a master (live or simulated) collects after SYNC: CiA 301 0x1007 ends synchronous PDOs at the
    synchronous window, so it stands in for a missing read window; the SYNC period bounds both."""
    params = rt.CanopenParams(20_000_000, None, None, "master", 0x80)
    assert params.collect_window_ns() == 20_000_000
    with_sync_window = rt.CanopenParams(20_000_000, 12_000_000, None, "master", 0x80)
    assert with_sync_window.collect_window_ns() == 12_000_000
    assert rt.CanopenParams(20_000_000, 12_000_000, 10_000_000, "master", 0x80).collect_window_ns() == 10_000_000


def test_int_range_is_twos_complement_or_unsigned() -> None:
    assert codec.int_range(8, True) == (-128, 127) and codec.int_range(8, False) == (0, 255)
    assert codec.int_range(1, False) == (0, 1) and codec.int_range(64, True) == (-(2**63), 2**63 - 1)
    field = codec.Field("x", 0, 24, signed=True)
    assert field.raw_range() == codec.int_range(24, True)
