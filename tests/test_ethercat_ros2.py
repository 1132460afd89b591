"""Joints on EtherCAT drives for ICube's ethercat_driver_ros2: the URDF `<ec_module>` of each joint against the slave
YAML build writes for it (the driver's example configurations, *.ros2_control.xacro, name the plugin and the
parameters alias, position, mode_of_operation, slave_config), and the channels' factor and offset as the driver
applies them (ethercat_interface's EcPdoChannelManager: a state interface = factor * entry + offset; the entry
written = factor * command + offset), worked out by hand from the joints' gear and encoder figures."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.conftest import SPECS, check_data, cli
from tests.test_ethercat import spec

GEAR, COUNTS = 100, 2000  # specs/allex2_ethercat.yaml's joints, those of specs/allex2.yaml
RAD_PER_COUNT = 2 * math.pi / (COUNTS * GEAR)  # 3.1416e-5 rad a count at the joint
RAD_S_PER_RPM = 2 * math.pi / (60 * GEAR)  # the EPOS4's velocity in rpm at the motor
DRIVES = ["hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r"]


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("allex2_ethercat")
    done = cli("build", str(SPECS / "allex2_ethercat.yaml"), "-o", str(out))
    assert done.returncode == 0, done.stderr
    return out


def channels(slave: dict[str, Any], key: str) -> dict[int, dict[str, Any]]:
    return {c["index"]: c for p in slave[key] for c in p["channels"]}


def test_the_channels_factors_by_hand(built: Path) -> None:
    slave = yaml.safe_load((built / "ethercat" / "ecat0" / "hip_l.yaml").read_text(encoding="utf-8"))
    rx, tx = channels(slave, "rpdo"), channels(slave, "tpdo")
    assert rx[0x607A]["command_interface"] == "position"
    assert rx[0x607A]["factor"] == pytest.approx(1 / RAD_PER_COUNT)  # 31,830.99 counts a radian
    assert tx[0x6064]["factor"] == pytest.approx(RAD_PER_COUNT) and "offset" not in tx[0x6064]
    assert tx[0x606C]["factor"] == pytest.approx(RAD_S_PER_RPM)  # 1.0472e-3 rad/s an rpm
    assert "factor" not in rx[0x6040] and "factor" not in tx[0x6077]  # no joint interface; no rated torque given
    # as the driver reads it: 50,000 counts are a quarter turn of the joint
    assert tx[0x6064]["factor"] * 50_000 == pytest.approx(math.pi / 2)


def test_each_ec_module_names_its_slave_file(built: Path) -> None:
    xacro = pytest.importorskip("xacro")
    wrapper = (  # a robot's URDF that includes the file and calls its macro
        '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        f'<xacro:include filename="{built}/ros2_control/allex2_ethercat.ros2_control.xacro"/>'
        f'<xacro:allex2_ethercat_ros2_control slave_config_dir="{built}/ethercat/ecat0"/></robot>'
    )
    (built / "robot.urdf.xacro").write_text(wrapper, encoding="utf-8")
    urdf = ET.fromstring(xacro.process_file(str(built / "robot.urdf.xacro")).toxml())
    (block,) = urdf.findall("ros2_control")
    hardware = block.find("hardware")
    assert hardware is not None and hardware.findtext("plugin") == "ethercat_driver/EthercatDriver"
    params = {p.get("name"): p.text for p in hardware.findall("param")}
    assert params == {"master_id": "0", "control_frequency": "1000"}  # the spec's 1 ms cycle
    for position, joint in enumerate(block.findall("joint")):
        (module,) = joint.findall("ec_module")
        assert module.findtext("plugin") == "ethercat_generic_plugins/EcCiA402Drive"
        p = {e.get("name"): e.text for e in module.findall("param")}
        assert module.get("name") == DRIVES[position] and p["position"] == str(position) and p["alias"] == "0"
        assert p["mode_of_operation"] == "8"  # CiA 402 cyclic synchronous position: the joints command positions
        slave_file = Path(str(p["slave_config"]))
        assert slave_file.exists()
        assert f"slave {position} of EtherCAT bus 'ecat0'" in slave_file.read_text(encoding="utf-8")


def test_a_zero_and_a_rated_torque(tmp_path: Path) -> None:
    """zero 0.3 rad and a rated torque of 0.1 N m: the position state reads 0.3 rad at 0 counts; the command writes
    -0.3 rad * 31,830.99 = -9,549.3 counts for 0 rad; the effort state is 0.1 * 100 / 1000 = 0.01 N m a per mille."""
    pdos = [{"index": 0x1600, "map": [0x6040, 0x607A]}, {"index": 0x1A00, "map": [0x6041, 0x6064, 0x6077]}]
    data = spec(tmp_path, [{"node": "d1", "profile": "cia402", "pdos": pdos}])
    data["joints"] = [{"name": "j1", "node": "d1", "gear_ratio": GEAR, "encoder_counts": COUNTS, "zero": 0.3,
                       "rated_torque": 0.1}]
    (tmp_path / "spec.yaml").write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    done = cli("build", str(tmp_path / "spec.yaml"), "-o", str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    slave = yaml.safe_load((tmp_path / "out" / "ethercat" / "ecat" / "d1.yaml").read_text(encoding="utf-8"))
    rx, tx = channels(slave, "rpdo"), channels(slave, "tpdo")
    assert tx[0x6064]["offset"] == 0.3
    assert rx[0x607A]["offset"] == pytest.approx(-0.3 / RAD_PER_COUNT)
    assert tx[0x6077]["factor"] == pytest.approx(0.01) and tx[0x6077]["state_interface"] == "effort"


def test_a_joint_on_a_slave_that_maps_none_of_its_objects(tmp_path: Path) -> None:
    data = spec(tmp_path, [{"node": "d1", "profile": "cia402", "pdos": [{"index": 0x1600, "map": [0x6040]}]}])
    data["joints"] = [{"name": "j1", "node": "d1", "encoder_counts": COUNTS}]
    report = check_data(tmp_path, data)
    (found,) = [e for e in report["errors"] if e["code"] == "joint-interfaces"]
    assert "node 'd1' maps no CiA 402 target or actual value" in found["message"]


def test_limits_beyond_the_entry(tmp_path: Path) -> None:
    # 0x6077 is 16 bits: 32,767 per mille of 0.1 N m through a gear of 100 is 327.67 N m at most
    pdos = [{"index": 0x1A00, "map": [0x6041, 0x6077]}]
    data = spec(tmp_path, [{"node": "d1", "profile": "cia402", "pdos": pdos}])
    data["joints"] = [{"name": "j1", "node": "d1", "gear_ratio": GEAR, "rated_torque": 0.1, "limits": {"effort": 400}}]
    report = check_data(tmp_path, data)
    (found,) = [e for e in report["errors"] if e["code"] == "joint-limits"]
    assert "Torque actual value of PDO 0x1A00, which carries -327.68..327.67 N m" in found["message"]
