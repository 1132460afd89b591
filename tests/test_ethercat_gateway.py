"""Flows across an EtherCAT segment and a CAN bus behind a gateway slave (specs/ethercat_can_gateway.yaml): a slave's
PDO as a message, its delivery in the cycle, the flows' bounds derived by hand, the simulator holding the measured
latencies inside them, and the errors a wrong PDO message gets."""

from __future__ import annotations

import copy
import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml

from netcfg.links import ethercat as link
from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import summary
from netcfg.sim.scenario import SimOptions
from tests.conftest import SPECS, check, check_data, cli, runtime_config

EXAMPLE = SPECS / "ethercat_can_gateway.yaml"

# The example's segment, by hand (netcfg.protocols.ethercat.messages for the model):
# - the image: the gateway's RxPDO 0x1600 (2 bytes, INT 0x7000) then its TxPDO 0x1A00 (4 bytes: 0x6000, 0x6001), one
#   LRW datagram of 6 bytes: 8 + 14 + 2 + 10 + 6 + 2 + 4 = 46 bytes, padded to a 64-byte Ethernet frame, 84 bytes
#   with preamble and gap: 6,720 ns at 80 ns a byte;
# - the gateway's 2 m of cable at 0.7 c: 9.53 ns one way;
# - the frame back at the master: 50,000 (jitter) + 6,720 + 2,000 (its forwarding, the default of an ESI whose
#   Physics is "YY": an RJ45 slave) + 19 (cables out and back) = 58,739 ns; past the gateway: 50,000 + 6,720 + 2,000
#   + 9.53 = 58,730 ns;
# - the TxPDO read as the datagram's byte 2 of data (its inputs follow the 2 bytes of outputs) leaves the master:
#   (8 + 14 + 2 + 10 + 2) x 80 = 2,880 ns after the send; at the master at the earliest 6,720 - 2,880 + 9.53
#   = 3,849 ns later;
# - the RxPDO copied at the send: at the gateway at the earliest after the wire and the cable, 6,720 + 9.53 = 6,729.
WIRE_NS = 84 * 80
CABLE_NS = 2 / (0.7 * 299_792_458) * 1e9
LATENCY_NS = 50_000 + WIRE_NS + 2_000 + round(2 * CABLE_NS)
PASSED_NS = round(50_000 + WIRE_NS + 2_000 + CABLE_NS)
READ_NS = (8 + 14 + 2 + 10 + 2) * 80
PERIOD_REAL_NS = 1_000_100  # 1 ms on a clock 100 ppm slow (the default clock tolerance)


def test_the_segment_by_hand() -> None:
    assert link.frame_bytes([6]) == 84 and round(CABLE_NS, 2) == 9.53
    report = check(EXAMPLE)
    assert report["ok"], report["errors"]
    ecat = next(b for b in report["buses"] if b["name"] == "ecat0")
    assert ecat["cycle"]["latency_us"] * 1000 == LATENCY_NS == 58_739
    rows = {m["name"]: m for m in ecat["messages"]}
    torque, valve = rows["gw_torque"], rows["gw_valve"]
    # the identifier is the PDO's logical address: outputs first, then inputs (SOEM's IOmap, segment.lay_out)
    assert (valve["id"], torque["id"]) == (0, 2)
    assert (torque["pdo"], torque["direction"], valve["pdo"], valve["direction"]) == (
        "0x1A00", "inputs", "0x1600", "outputs")
    assert torque["read_offset_ns"] == READ_NS == 2_880
    assert torque["best_us"] * 1000 == int(WIRE_NS - READ_NS + CABLE_NS) == 3_849
    assert torque["wcrt_ns"] == LATENCY_NS
    assert valve["best_us"] * 1000 == int(WIRE_NS + CABLE_NS) == 6_729
    assert valve["wcrt_ns"] == PASSED_NS == 58_730
    assert torque["schedulable"] and valve["schedulable"]  # both within their deadline, the 1 ms cycle


def test_the_flows_by_hand() -> None:
    """Both flows' bounds, step by step (the unsynchronised model of netcfg.timing.flows):

    torque_to_control, at the latest: the sensor's task ends 100 us after its start (its WCET, alone on its
    processor); its frame (sent as the task ends) takes 340 us from its queueing (0x181 waits for 0x201's 150 us
    frame already on the bus, then its own 190 us: 95 bits at 2 us); the gateway's copy task samples it within
    one of its 1 ms periods (1,000.1 us in real time at 100 ppm) and ends 80 us later (its WCET, the first of two
    tasks of one rate on the gateway); the TxPDO waits for the next cycle's frame (up to one cycle, 1,000.1 us)
    and reaches the master 58.739 us after that cycle starts; the control task samples it within its period
    (1,000.1 us): 100 + 340 + 1,000.1 + 80 + 1,000.1 + 58.739 + 1,000.1 = 3,579.039 us.
    At the earliest: the task's BCET 30, the frame's nominal 158 us (79 bits, no stuff bits), the copy's BCET 20
    and the PDO's earliest 3.849 us after its read: 211.849 us.

    command_to_valve, at the latest: the control task's 200 us, the next cycle (1,000.1), the RxPDO past the
    gateway 58.73 us into it, the gateway's second copy task sampling it (1,000.1) and ending 160 us later (80 of
    its own after the first task's 80), its frame 0x201 340 us from its queueing (its 150 us after 0x181's 190
    us), and the valve's task starting as it arrives: 200 + 1,000.1 + 58.73 + 1,000.1 + 160 + 340 = 2,758.93 us.
    At the earliest: 50 + 6.729 + 20 + 126 (0x201's 63 bits) = 202.729 us.

    Were a PDO sent as the task before it ends (as a CAN frame is), each maximum would be a cycle shorter."""
    report = check(EXAMPLE)
    flows = {f["name"]: f for f in report["flows"]}
    cycle_wait = PERIOD_REAL_NS
    hi = 100_000 + 340_000 + PERIOD_REAL_NS + 80_000 + cycle_wait + LATENCY_NS + PERIOD_REAL_NS
    assert flows["torque_to_control"]["latency_ns"] == [30_000 + 158_000 + 20_000 + 3_849, hi] == [211_849, 3_579_039]
    hi = 200_000 + cycle_wait + PASSED_NS + PERIOD_REAL_NS + 160_000 + 340_000
    assert flows["command_to_valve"]["latency_ns"] == [50_000 + 6_729 + 20_000 + 126_000, hi] == [202_729, 2_758_930]


def test_no_task_sends_a_pdo() -> None:
    """runtime.json's sent_by: the CAN frames go as their tasks end, the PDOs with the next cycle's frame."""
    cfg = runtime_config(EXAMPLE)
    sent = {m.name: m.sent_by for m in cfg.messages}
    assert sent["torque"] == ("torque_sensor.sample",) and sent["valve_cmd"] == ("gw.to_can",)
    assert not sent["gw_torque"] and not sent["gw_valve"]
    ec = cfg.bus("ecat0").ethercat
    assert ec is not None and ec["messages"] == [
        {"name": "gw_torque", "slave": 0, "direction": "inputs", "read_offset_ns": READ_NS},
        {"name": "gw_valve", "slave": 0, "direction": "outputs", "read_offset_ns": 0},
    ]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_simulator_stays_inside(seed: int) -> None:
    cfg = runtime_config(EXAMPLE)
    for opts in (SimOptions(duration_ns=2_000_000_000, seed=seed),
                 SimOptions(duration_ns=2_000_000_000, seed=seed, random_phase=False, drift_ppm=0.0)):
        _, res = run_once(cfg, opts)
        doc = summary(res)
        assert not doc["violations"], doc["violations"]
        flows = {f["name"]: f for f in doc["flows"]}
        for name in ("torque_to_control", "command_to_valve"):
            f = flows[name]
            assert f["samples"] > 500 and f["within_analysis"], f
        messages = {m["name"]: m for m in doc["messages"]}
        for name in ("gw_torque", "gw_valve"):  # one delivery a cycle, each within the analysis' latest
            assert messages[name]["count"] == 2_000 and messages[name]["within_analysis"]


def test_a_lost_frame_delivers_nothing() -> None:
    from netcfg.sim.faults import Fault

    cfg = runtime_config(EXAMPLE)
    _, res = run_once(cfg, SimOptions(duration_ns=100_000_000, seed=1, faults=(Fault.parse("lose:ecat0@50ms"),)))
    doc = summary(res)
    messages = {m["name"]: m for m in doc["messages"]}
    assert messages["gw_torque"]["count"] == messages["gw_valve"]["count"] == 99  # 100 cycles, one frame lost


# -- a wrong PDO message -----------------------------------------------------------------------------------------
def _example(tmp_path: Path) -> dict[str, Any]:
    (tmp_path / "esi").mkdir(exist_ok=True)
    shutil.copy(SPECS / "esi" / "can_gateway.xml", tmp_path / "esi" / "can_gateway.xml")
    return copy.deepcopy(yaml.safe_load(EXAMPLE.read_text()))


def _message(data: dict[str, Any], name: str) -> dict[str, Any]:
    return next(m for m in data["messages"] if m["name"] == name)


@pytest.mark.parametrize(
    ("change", "code", "says"),
    [
        (lambda m: m.pop("pdo"), "wrong-section", "name one of a slave's assigned PDOs"),
        (lambda m: m["pdo"].update(tpdo=2), "pdo", "has no TPDO 2 (0x1A01) assigned; its assignment holds 0x1A00"),
        (lambda m: m["pdo"].update(map=[0x7000]), "pdo-mapping", "carries 0x6000:0, 0x6001:0, not '28672'"),
        (lambda m: m.update(period="2 ms"), "period", "rides every cycle (1000 us)"),
        (lambda m: m.update(id=5), "wrong-section", "'id' means nothing for a PDO"),
        (lambda m: m["pdo"].update(transmission=1), "wrong-section", "'transmission' is a CANopen PDO setting"),
    ],
)
def test_wrong_pdo_messages(tmp_path: Path, change: Any, code: str, says: str) -> None:
    data = _example(tmp_path)
    change(_message(data, "gw_torque"))
    report = check_data(tmp_path, data)
    assert any(e["code"] == code and says in e["message"] for e in report["errors"]), report["errors"]
    assert all(e["line"] is not None for e in report["errors"])


def test_an_rxpdo_comes_from_the_master(tmp_path: Path) -> None:
    data = _example(tmp_path)
    m = _message(data, "gw_valve")
    m["producer"], m["consumers"] = "gw", ["master"]
    report = check_data(tmp_path, data)
    assert any("RxPDO comes from the segment's master 'master', not 'gw'" in e["message"] for e in report["errors"])


def test_a_wrong_pdo_on_the_command_line(tmp_path: Path) -> None:
    data = _example(tmp_path)
    _message(data, "gw_torque")["pdo"]["tpdo"] = 3
    (tmp_path / "spec.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    out = cli("check", str(tmp_path / "spec.yaml"))
    assert out.returncode == 1 and "Traceback" not in out.stderr + out.stdout
    line = next(x for x in (out.stdout + out.stderr).splitlines() if "has no TPDO 3" in x)
    assert line.startswith(f"{tmp_path / 'spec.yaml'}:") and ": error: " in line


def test_the_read_of_a_byte_in_the_second_frame() -> None:
    """An image of 2,000 bytes goes in two frames (1,486 + 514 bytes of data): logical byte 1,500 is the 15th data
    byte of the second frame, read after the whole first frame (1,538 bytes with preamble and gap), the second's
    preamble and headers (8 + 14 + 2 + 10) and 14 bytes before it: (1,538 + 34 + 14) x 80 ns = 126,880 ns."""
    from netcfg.protocols.ethercat.analysis import cycle_timing
    from netcfg.protocols.ethercat.messages import read_offset_ns

    t = cycle_timing(2000, 100_000_000, [], [])
    assert t.frames == (1486, 514) and t.frame_bytes[0] == 1538
    assert read_offset_ns(t, 1500, 100_000_000) == (1538 + 34 + 14) * 80 == 126_880
    assert read_offset_ns(t, 0, 100_000_000) == 34 * 80


def test_a_slave_that_failed_gets_no_second_error(tmp_path: Path) -> None:
    data = _example(tmp_path)
    (tmp_path / "esi" / "can_gateway.xml").unlink()
    report = check_data(tmp_path, data)
    assert [e["code"] for e in report["errors"]] == ["esi"]
