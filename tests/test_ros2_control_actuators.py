"""Joints on actuator buses in ros2_control: ODrive's own plugin, odrive_ros2_control 0.0.1 (odriverobotics/ros_odrive),
described as its package publishes it, the description expanded by ROS's xacro inside a robot and parsed by its URDF
parser; an actuator whose vendor publishes no plugin is left out and said so.

The plugin's names are its package's: the class `odrive_ros2_control_plugin/ODriveHardwareInterface`
(odrive_hardware_interface.xml), the hardware parameter `can` and the joint parameter `node_id` (README.md, and
on_init() in src/odrive_hardware_interface.cpp, which reads them); it writes Set_Input_Vel's Input_Vel as
vel_setpoint / (2 pi) and reads Get_Encoder_Estimates' Pos_Estimate and Vel_Estimate times 2 pi (write(),
on_can_msg()), so a joint's factor from the ODrive's rev and rev/s is 2 pi with no gear (README: "Transmission ...
is already handled on the ODrive side")."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import check_data, cli

PLUGIN = "odrive_ros2_control_plugin/ODriveHardwareInterface"


def wheels(**left: Any) -> dict[str, Any]:
    """Two ODrive wheels (node ids 0 and 1) and one Damiao DM-J4310 joint on one bus, each commanded at 100 Hz; the
    wheels' encoder estimates come at the profile's default 10 ms."""
    def odrive(name: str, node_id: int, **more: Any) -> dict[str, Any]:
        return {"name": name, "node_id": node_id, "buses": ["can0"], "device": "odrive-cansimple",
                "actuator": {"commands": [{"message": "set_input_vel", "rate": "100 Hz"}], **more}}

    def wheel(name: str, node: str, **more: Any) -> dict[str, Any]:
        return {"name": name, "node": node, "command": {"velocity": f"{node}_set_input_vel.input_vel"},
                "state": {"position": f"{node}_get_encoder_estimates.pos_estimate",
                          "velocity": f"{node}_get_encoder_estimates.vel_estimate"},
                "limits": {"velocity": 20.0}, **more}

    return {
        "system": "wheels",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": "1 Mbit/s"}],
        "nodes": [{"name": "host", "role": "master", "buses": ["can0"]}, odrive("left", 0), odrive("right", 1),
                  {"name": "arm", "node_id": 5, "buses": ["can0"], "device": "damiao-dm-j4310",
                   "actuator": {"parameters": {"master_id": 0x15},
                                "commands": [{"message": "mit_command", "rate": "100 Hz"}]}}],
        "joints": [wheel("left_wheel_joint", "left", **left), wheel("right_wheel_joint", "right"),
                   {"name": "arm_joint", "node": "arm", "command": {"position": "arm_mit_command.position"},
                    "state": {"position": "arm_feedback.position"}}],
    }


ROBOT = """<?xml version="1.0"?>
<robot name="wheels" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="{xacro}"/>
  <link name="base"/>
  <link name="left"/>
  <link name="right"/>
  <link name="arm"/>
  <joint name="left_wheel_joint" type="continuous"><parent link="base"/><child link="left"/></joint>
  <joint name="right_wheel_joint" type="continuous"><parent link="base"/><child link="right"/></joint>
  <joint name="arm_joint" type="continuous"><parent link="base"/><child link="arm"/></joint>
  <xacro:wheels_ros2_control {call}/>
</robot>
"""


def build(tmp_path: Path, data: dict[str, Any]) -> tuple[Path, str]:
    spec = tmp_path / "wheels.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    out = tmp_path / "out"
    proc = cli("build", str(spec), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    return out, proc.stderr


def expand(tmp_path: Path, out: Path, call: str = "") -> str:
    xacro = pytest.importorskip("xacro")
    robot = tmp_path / "robot.urdf.xacro"
    robot.write_text(ROBOT.format(xacro=out / "ros2_control" / "wheels.ros2_control.xacro", call=call))
    return str(xacro.process_file(str(robot)).toprettyxml(indent="  "))


def test_odrive_joints_get_odrives_plugin(tmp_path: Path) -> None:
    out, stderr = build(tmp_path, wheels())
    text = expand(tmp_path, out)
    urdf = pytest.importorskip("urdf_parser_py.urdf")
    robot = urdf.URDF.from_xml_string(text)
    assert sorted(j.name for j in robot.joints) == ["arm_joint", "left_wheel_joint", "right_wheel_joint"]
    [block] = ET.fromstring(text).findall("ros2_control")
    assert block.findtext("hardware/plugin") == PLUGIN
    assert {p.get("name"): p.text for p in block.findall("hardware/param")} == {"can": "can0"}  # the bus's name
    joints = {j.get("name"): j for j in block.findall("joint")}
    assert sorted(joints) == ["left_wheel_joint", "right_wheel_joint"]  # the Damiao joint has no plugin
    assert [joints[n].findtext("param[@name='node_id']") for n in sorted(joints)] == ["0", "1"]  # the spec's ids
    left = joints["left_wheel_joint"]
    assert [c.get("name") for c in left.findall("command_interface")] == ["velocity"]
    assert {p.get("name"): float(p.text or "") for p in left.findall("command_interface/param")} == {
        "min": -20.0, "max": 20.0}
    assert [s.get("name") for s in left.findall("state_interface")] == ["position", "velocity"]
    # its vendor publishes no ros2_control plugin: said in the file and by build, no plugin made up
    assert "no official ros2_control plugin for damiao-dm-j4310" in stderr
    assert "arm_joint on bus can0: no official ros2_control plugin" in (
        out / "ros2_control" / "wheels.ros2_control.xacro").read_text()
    # the interface the plugin opens is a macro argument
    block = ET.fromstring(expand(tmp_path, out, 'can="can1"')).find("ros2_control")
    assert block is not None and block.findtext("hardware/param[@name='can']") == "can1"
    controllers = yaml.safe_load((out / "ros2_control" / "controllers.yaml").read_text())
    assert controllers["controller_manager"]["ros__parameters"]["update_rate"] == 100  # the commands' 100 Hz


def test_an_odrive_joint_scales_as_the_plugin_does(tmp_path: Path) -> None:
    """rev/s and rev times 2 pi, no gear (the plugin's write() and on_can_msg(), the module docstring)."""
    from netcfg.check import analyse_spec

    spec = tmp_path / "wheels.yaml"
    spec.write_text(yaml.safe_dump(wheels(), sort_keys=False), encoding="utf-8")
    model, report = analyse_spec(spec)
    assert model is not None and report["ok"], report["errors"]
    joint = model.joints["left_wheel_joint"]
    assert joint.command["velocity"].from_dev == 2 * math.pi
    assert joint.state["position"].from_dev == joint.state["velocity"].from_dev == 2 * math.pi
    # the Damiao joint's MIT position is in rad already (the profile's unit): factor 1, no encoder counts needed
    assert model.joints["arm_joint"].command["position"].from_dev == 1.0


def test_a_gear_ratio_the_plugin_would_not_apply_is_a_warning(tmp_path: Path) -> None:
    report = check_data(tmp_path, wheels(gear_ratio=9.0))
    assert report["ok"]
    assert [w["code"] for w in report["warnings"]] == ["joint-gear"]
    assert "applies no gear ratio" in report["warnings"][0]["message"]


def test_a_state_the_plugin_never_gets_is_left_out(tmp_path: Path) -> None:
    """The plugin reads its effort from Get_Torques as the axis sends it on its own; requested by a remote frame at
    a rate instead (the profile's request_torques; torques_msg_rate_ms stays 0), the plugin, which asks for nothing,
    would never see it: the joint is left out, and the reason said."""
    data = wheels(state={"position": "left_get_encoder_estimates.pos_estimate",
                         "effort": "left_get_torques.torque_estimate"})
    data["nodes"][1]["actuator"]["commands"].append({"message": "request_torques", "rate": "100 Hz"})
    out, stderr = build(tmp_path, data)
    block = ET.fromstring((out / "ros2_control" / "wheels.ros2_control.xacro").read_text()).find(
        ".//ros2_control")
    assert block is not None
    assert [j.get("name") for j in block.findall("joint")] == ["${prefix}right_wheel_joint"]
    assert "left_wheel_joint on bus can0: " + PLUGIN + " reads its effort from get_torques and never asks for it" in (
        stderr)


def test_a_profile_s_plugin_section_is_checked(tmp_path: Path) -> None:
    from netcfg.devices.actuator_profile import parse_actuator_profile
    from netcfg.diagnostics import SpecError

    text = (Path(__file__).parent.parent / "netcfg" / "devices" / "actuators" / "odrive-cansimple.yaml").read_text()
    broken = text.replace("velocity: set_input_vel.input_vel,", "velocity: set_input_vel.input_speed,")
    with pytest.raises(SpecError) as exc:
        parse_actuator_profile(broken, "mine.yaml")
    [d] = exc.value.diagnostics
    assert d.code == "profile-ros2" and "'set_input_vel.input_speed' is no field" in d.message
    line = next(i for i, s in enumerate(broken.splitlines(), start=1) if "input_speed" in s)
    assert (d.file, d.line) == ("mine.yaml", line)
