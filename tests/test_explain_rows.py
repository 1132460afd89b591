"""`check --explain` derives every row check's table lists, the protocol's own frames (SYNC, heartbeats) too."""

from __future__ import annotations

import json

from conftest import SPECS, cli


def explain(name: str) -> dict:
    proc = cli("check", str(SPECS / "allex2.yaml"), "--explain", name, "--format", "json")
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_the_sync_row_is_explained() -> None:
    """ALLEX-2's SYNC leaves the master's FIFO with its twelve RxPDOs (README, Transmit queues): blocking by the
    longest lower-priority frame, a 1-byte heartbeat (55 + 10 stuff bits = 65 us at 1 Mbit/s), the queue's 1,315 us
    (SYNC 55, six 8-byte RxPDO1 of 135, six 2-byte RxPDO2 of 75: 55 + 810 + 450), and the twelve TPDOs above the
    queue's lowest message (six of 135, six 6-byte of 115: 1,500): 65 + 1,315 + 1,500 = 2,880 us."""
    doc = explain("can0_SYNC")
    assert doc["frame"]["c_us"] == 55 and doc["id"] == 0x80
    assert doc["wcrt_us"] == 65 + 1315 + 1500


def test_a_heartbeat_row_is_explained() -> None:
    """A heartbeat is one byte (CiA 301 7.2.8.3.2.4): 47 + 8 = 55 bits and up to 10 stuff bits, C = 65 us."""
    doc = explain("hip_l_heartbeat")
    assert doc["id"] == 0x700 + 1 and doc["frame"]["bits_worst"] == 65 and doc["wcrt_us"] is not None


def test_an_unknown_name_suggests_a_protocol_frame() -> None:
    proc = cli("check", str(SPECS / "allex2.yaml"), "--explain", "can0_SYNK")
    assert proc.returncode == 2 and "did you mean 'can0_SYNC'?" in proc.stderr, proc.stderr


def test_a_flow_is_explained_step_by_step() -> None:
    """CAMBADA's motion flow (seed 002): --explain gives check's bounds for it and lists its chain's steps with
    their own figures; the messages' offsets are Table 2's init times (velocity vectors at EC 0, the set-points at
    EC 5, 5 ms ECs), as offset: auto places them."""
    proc = cli("check", str(SPECS / "cambada.yaml"), "--explain", "motion", "--format", "json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    checked = json.loads(cli("check", str(SPECS / "cambada.yaml"), "--format", "json").stdout)
    flow = next(f for f in checked["flows"] if f["name"] == "motion")
    assert (doc["latency_min_us"], doc["latency_max_us"]) == (flow["latency_min_us"], flow["latency_max_us"])
    names = [[item["name"] for item in step["items"]] for step in doc["steps"]]
    assert names == [["velocity_linear", "velocity_angular"], ["holonomic.convert"], ["motor_setpoints"],
                     ["motor1.apply_setpoint", "motor2.apply_setpoint", "motor3.apply_setpoint"]]
    offsets = {i["name"]: i["offset_us"] for s in doc["steps"] for i in s["items"] if i["kind"] == "message"}
    assert offsets == {"velocity_linear": 0, "velocity_angular": 0, "motor_setpoints": 5 * 5_000}
    text = cli("check", str(SPECS / "cambada.yaml"), "--explain", "motion").stdout
    assert text.startswith("flow motion (synchronised)")
