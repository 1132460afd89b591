"""The joints' ros2_control description, held against its real consumers: the committed ALLEX-2 build's xacro
expands with the `xacro` package inside the example robot (examples/allex2_legs.urdf.xacro) and the result parses
with `urdf_parser_py`; every joint of its <ros2_control> block is a moving joint of that URDF; the rules
ros2_control's parser holds a hardware description to (interface names, a joint once, a plugin) and
canopen_ros2_control/RobotSystem's own (its parameters, each joint's device a CiA 402 driver of the bus.yml); the
controllers' YAML; the scaling factors, derived here by hand from the EPOS4's figures; and Lely's dcfgen taking
the bus.yml with ros2_canopen's keys."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from conftest import ROOT, SPECS, cli

GENERATED = ROOT / "generated" / "allex2"
XACRO = GENERATED / "ros2_control" / "allex2.ros2_control.xacro"
EXAMPLE = ROOT / "examples" / "allex2_legs.urdf.xacro"
EDS = ROOT.parent / "shared" / "devices" / "maxon_epos4_50-5.eds"
INTERFACES = {"position", "velocity", "effort"}  # hardware_interface_type_values.hpp's HW_IF_*
JOINTS = [f"{side}_{j}_joint" for side in ("left", "right") for j in ("hip", "knee", "ankle")]


@pytest.fixture(scope="module")
def urdf_text() -> str:
    xacro = pytest.importorskip("xacro")
    doc = xacro.process_file(
        str(EXAMPLE), mappings={"bus_config": "/opt/robot/bus.yml", "master_config": "/opt/robot/master.dcf"}
    )
    return str(doc.toprettyxml(indent="  "))


def ros2_control_blocks(text: str) -> list[ET.Element]:
    return ET.fromstring(text).findall("ros2_control")


def test_the_example_robot_expands_and_parses(urdf_text: str) -> None:
    urdf = pytest.importorskip("urdf_parser_py.urdf")
    robot = urdf.URDF.from_xml_string(urdf_text)
    moving = {j.name: j for j in robot.joints if j.type != "fixed"}
    assert sorted(moving) == sorted(JOINTS)
    # the URDF's limits are the spec's: the example copies them, and the spec's are what the block says
    spec = yaml.safe_load((SPECS / "allex2.yaml").read_text(encoding="utf-8"))
    for joint in spec["joints"]:
        limit = moving[joint["name"]].limit
        assert [limit.lower, limit.upper] == joint["limits"]["position"]
        assert limit.velocity == joint["limits"]["velocity"]


def test_every_ros2_control_joint_is_a_moving_joint_of_the_urdf(urdf_text: str) -> None:
    root = ET.fromstring(urdf_text)
    moving = {j.get("name") for j in root.findall("joint") if j.get("type") != "fixed"}
    named = [j.get("name") for block in ros2_control_blocks(urdf_text) for j in block.findall("joint")]
    assert named and set(named) <= moving
    assert len(named) == len(set(named)), "a joint appears in more than one place"  # ros2_control refuses that


def test_the_block_holds_ros2_controls_rules(urdf_text: str) -> None:
    """What hardware_interface's component_parser requires, and RobotSystem's on_init reads."""
    blocks = ros2_control_blocks(urdf_text)
    assert len(blocks) == 1 and blocks[0].get("name") and blocks[0].get("type") == "system"
    hardware = blocks[0].find("hardware")
    assert hardware is not None
    assert hardware.findtext("plugin") == "canopen_ros2_control/RobotSystem"
    params = {p.get("name"): p.text for p in hardware.findall("param")}
    assert params == {
        "bus_config": "/opt/robot/bus.yml",
        "master_config": "/opt/robot/master.dcf",
        "can_interface_name": "can0",
        "master_bin": '""',  # RobotSystem takes the two quote characters for no master.bin
    }
    bus = yaml.safe_load((GENERATED / "canopen" / "bus.yml").read_text(encoding="utf-8"))
    for joint in blocks[0].findall("joint"):
        commands = [c.get("name") for c in joint.findall("command_interface")]
        states = [s.get("name") for s in joint.findall("state_interface")]
        assert commands + states and set(commands + states) <= INTERFACES
        assert len(commands) == len(set(commands)) and len(states) == len(set(states))
        for command in joint.findall("command_interface"):
            bounds = {p.get("name"): float(p.text or "nan") for p in command.findall("param")}
            assert bounds["min"] < bounds["max"]
        jparams = {p.get("name"): p.text for p in joint.findall("param")}
        device = bus[jparams["device_name"]]  # RobotSystem looks the joint's device up in the bus.yml by name
        assert device["driver"] == "ros2_canopen::Cia402Driver" and device["package"] == "canopen_402_driver"
        assert int(jparams["node_id"]) == device["node_id"]


def test_the_controllers_run_at_the_control_rate() -> None:
    doc = yaml.safe_load((GENERATED / "ros2_control" / "controllers.yaml").read_text(encoding="utf-8"))
    manager = doc["controller_manager"]["ros__parameters"]
    assert manager["update_rate"] == 50  # the master's control task runs each SYNC, every 20 ms
    assert manager["joint_state_broadcaster"]["type"] == "joint_state_broadcaster/JointStateBroadcaster"
    assert manager["can0_velocity_controller"]["type"] == "forward_command_controller/ForwardCommandController"
    forward = doc["can0_velocity_controller"]["ros__parameters"]
    assert forward == {"joints": JOINTS, "interface_name": "velocity"}


def _eds_default(index: int, sub: int) -> int:
    text = EDS.read_text(encoding="latin-1")
    name = f"[{index:04X}sub{sub}]" if f"[{index:04X}sub{sub}]" in text else f"[{index:04X}]"  # a VAR has no sub
    section = text.split(name, 1)[1]
    return int(re.search(r"DefaultValue=(\S+)", section).group(1), 0)  # type: ignore[union-attr]


def test_the_scaling_factors_by_hand_from_the_epos4_figures() -> None:
    """EDS 0x3010:1: 500 encoder pulses per motor revolution, 4 counts each (both edges of both channels); EDS
    0x60A9: velocities in rpm; the spec's harmonic drive: 100 motor revolutions per joint revolution."""
    if not EDS.is_file():
        pytest.skip("the EPOS4 EDS is not beside the repository")
    pulses = _eds_default(0x3010, 1)
    assert pulses == 500 and _eds_default(0x60A9, 0) == 0x00B44700
    counts_per_joint_revolution = pulses * 4 * 100  # 200,000
    bus = yaml.safe_load((GENERATED / "canopen" / "bus.yml").read_text(encoding="utf-8"))
    for drive in ("hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r"):
        keys = bus[drive]
        assert math.isclose(keys["scale_pos_to_dev"], 200_000 / (2 * math.pi))  # 31,830.99 counts per rad
        assert math.isclose(keys["scale_pos_from_dev"], 2 * math.pi / counts_per_joint_revolution)  # 31.4 urad
        assert math.isclose(keys["scale_vel_to_dev"], 100 * 60 / (2 * math.pi))  # 954.93 motor rpm per rad/s
        assert math.isclose(keys["scale_vel_from_dev"], 2 * math.pi / (60 * 100))
        assert keys["offset_pos_to_dev"] == keys["offset_pos_from_dev"] == 0.0
        assert keys["scale_pos_to_dev"] * keys["scale_pos_from_dev"] == pytest.approx(1.0, rel=1e-15)


def test_a_zero_offset_and_an_effort_come_out_as_ros2_canopen_applies_them(tmp_path: Path) -> None:
    """joint = device * scale_from + offset_from, device = joint * scale_to + offset_to: the two invert each other;
    the effort is per mille of the motor's rated torque, times the gear."""
    text = (SPECS / "allex2.yaml").read_text(encoding="utf-8")
    text = text.replace(
        "{name: left_hip_joint, node: hip_l, gear_ratio: 100, encoder_counts: 2000,",
        "{name: left_hip_joint, node: hip_l, gear_ratio: 100, encoder_counts: 2000, zero: 0.25, rated_torque: 0.5,",
    )
    spec = tmp_path / "allex2.yaml"
    spec.write_text(text, encoding="utf-8")
    proc = cli("build", str(spec), "-o", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    keys = yaml.safe_load((tmp_path / "out" / "canopen" / "bus.yml").read_text(encoding="utf-8"))["hip_l"]
    device = 12_345
    joint = device * keys["scale_pos_from_dev"] + keys["offset_pos_from_dev"]
    assert joint * keys["scale_pos_to_dev"] + keys["offset_pos_to_dev"] == pytest.approx(device)
    assert keys["offset_pos_from_dev"] == 0.25
    assert keys["scale_eff_from_dev"] == pytest.approx(0.5 * 100 / 1000)


def test_a_spec_without_joints_gets_no_ros2_control_files(tmp_path: Path) -> None:
    proc = cli("build", str(SPECS / "large_plant.yaml"), "-o", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "out" / "ros2_control").exists()
    assert "driver:" not in (tmp_path / "out" / "canopen" / "bus.yml").read_text(encoding="utf-8")


def test_dcfgen_takes_the_bus_yml_with_ros2_canopens_keys(tmp_path: Path) -> None:
    beside = Path(sys.executable).parent / "dcfgen"
    dcfgen = str(beside) if beside.is_file() else shutil.which("dcfgen")
    if dcfgen is None:
        pytest.skip("Lely's dcf-tools (dcfgen) are not installed")
    work = tmp_path / "canopen"
    shutil.copytree(GENERATED / "canopen", work)
    assert "scale_pos_to_dev" in (work / "bus.yml").read_text(encoding="utf-8")
    (work / "out").mkdir()
    proc = subprocess.run([dcfgen, "-r", "bus.yml", "-d", "out"], cwd=work, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (work / "out" / "master.dcf").is_file()


PLAIN_CAN = """
system: cart
buses:
  - {name: can0, protocol: can, bitrate: 500 kbit/s}
nodes:
  - {name: ctrl, buses: [can0]}
  - {name: wheel, buses: [can0]}
messages:
  - name: wheel_state
    id: 0x100
    producer: wheel
    consumers: [ctrl]
    period: 10 ms
    signals: [{name: speed, bits: 16, signed: true, unit: rpm}]
joints:
  - {name: wheel_joint, node: wheel, gear_ratio: 20, state: {velocity: wheel_state.speed}, limits: {velocity: 50.0}}
"""


def test_a_bus_without_a_hardware_plugin_gets_no_placeholder(tmp_path: Path) -> None:
    """A joint on a plain CAN bus is checked (its 16-bit rpm signal carries 32767 / 20 rpm = 171.6 rad/s at the
    wheel), but no published plugin drives such a bus: no ros2_control files rather than an empty block."""
    spec = tmp_path / "cart.yaml"
    spec.write_text(PLAIN_CAN, encoding="utf-8")
    proc = cli("build", str(spec), "-o", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "out" / "ros2_control").exists()
    spec.write_text(PLAIN_CAN.replace("velocity: 50.0", "velocity: 200.0"), encoding="utf-8")
    proc = cli("check", str(spec))
    assert proc.returncode == 1 and "carries -171.573..171.568 rad/s" in proc.stderr
