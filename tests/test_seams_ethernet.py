"""Seams of switched Ethernet: transmit queues that can fill, and egress ports fed over one input link.

Sources: the seam specs in tests/data/seams (each header says what netcfg printed, what the simulator measured and
the derivation); seed 001, eq. 6.4, for frame times at 100 Mbit/s: a minimum frame (84 bytes on the wire) takes
C = 6.72 us; the simulator's queues hold 64 frames unless the spec says (netcfg.timing.ethernet.QUEUE_FRAMES, the
figure the seam 05 header measured: "max_queue 64").
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import bus, check, check_data, cli, cli_json, message, runtime_config_of

from netcfg import runtime
from netcfg.check import analyse_spec
from netcfg.emit.runtime_json import runtime_document
from netcfg.sim.ethernet import EthernetNetwork
from netcfg.sim.scenario import SimOptions, simulate
from netcfg.spec import schema
from netcfg.timing.ethernet import QUEUE_FRAMES, Input, Queue, fifo_queue

SEAMS = Path(__file__).parent / "data" / "seams"
QUEUE_05 = SEAMS / "05-ethernet-queue-overflow.yaml"
CHAIN_06 = SEAMS / "06-ethernet-switch-chain-pessimism.yaml"
TREE_06B = SEAMS / "06b-ethernet-tree-pessimism.yaml"
C_US = 6.72  # seed 001: (84 x 8) / 100 Mbit/s
MS = 1_000_000


def seam(path: Path) -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(path.read_text(encoding="utf-8"))
    return data


def links(bus_report: dict[str, Any]) -> dict[tuple[str, str], dict[str, Any]]:
    return {(ll["from"], ll["to"]): ll for ll in bus_report["links"]}


def sim_links(cfg: Any, opts: SimOptions) -> dict[tuple[str, str], dict[str, Any]]:
    net = simulate(cfg, opts).protocols["lan"]
    assert isinstance(net, EthernetNetwork)
    return {(r["from"], r["to"]): r for r in net.report()["links"]}


# --- seam 05: a NIC's queue that 70 datagrams released at once overflow --------------------------------------------


def test_05_a_burst_the_nic_cannot_hold_is_refused_where_the_node_is_written() -> None:
    """h0 releases its 70 datagrams at the same instant every 10 ms (seam 05): 70 frames are queued at once in a
    NIC that holds 64, so 6 are dropped every period. check refuses it: one error at h0's entry (line 28, column
    3 of the seam), naming the queue, 70 against 64, and the depth that would do; exit 1 and no traceback."""
    proc = cli("check", str(QUEUE_05))
    assert proc.returncode == 1
    errors = [line for line in proc.stderr.splitlines() if ": error: " in line]
    assert len(errors) == 1 and "Traceback" not in proc.stderr
    assert errors[0].startswith(f"{QUEUE_05}:28:3: error: node 'h0' can have 70 frames at once")
    assert "holds 64: 6 would be dropped" in errors[0] and "'nic_queue: 70'" in errors[0]
    assert errors[0].endswith("[queue-overflow]")


def test_05_backlog_per_link_in_the_json() -> None:
    """The JSON links carry each queue's backlog beside its depth: h0 -> sw holds all 70 at once; sw -> pc receives
    them one per C over a single link and sends one per C, so at most 1 is there (the frame being sent)."""
    code, report = cli_json("check", str(QUEUE_05))
    lan = links(bus(report, "lan"))
    assert code == 1 and [e["code"] for e in report["errors"]] == ["queue-overflow"]
    assert (lan[("h0", "sw")]["backlog_frames"], lan[("h0", "sw")]["queue_frames"]) == (70, QUEUE_FRAMES)
    assert not lan[("h0", "sw")]["ok"]
    assert (lan[("sw", "pc")]["backlog_frames"], lan[("sw", "pc")]["queue_frames"]) == (1, QUEUE_FRAMES)


def test_05_a_deep_enough_nic_is_accepted_and_the_simulator_drops_nothing(tmp_path: Path) -> None:
    """With nic_queue: 70 the spec passes, runtime.json carries the depth and the simulator (which reads only
    runtime.json) holds all 70 frames at once and loses none (the seam measured 600 lost in 1 s at 64)."""
    data = seam(QUEUE_05)
    data["nodes"][0]["nic_queue"] = 70
    report = check_data(tmp_path, data)
    assert report["ok"], report["errors"]
    cfg = runtime_config_of(tmp_path / "spec.yaml", data)
    assert cfg.bus("lan").ethernet is not None and cfg.bus("lan").ethernet.nic_queue("h0") == 70
    port = sim_links(cfg, SimOptions(duration_ns=200 * MS, seed=0))[("h0", "sw")]
    assert (port["max_queue"], port["queue_frames"], port["lost"]) == (70, 70, 0)


def test_05_a_runtime_file_without_depths_gets_the_shared_default(tmp_path: Path) -> None:
    """A runtime.json written before the depths were carried (no `nics`, no port `queue`) is simulated with
    QUEUE_FRAMES everywhere, the depth check holds backlogs against: of 70 frames released together every 10 ms,
    6 are dropped each period; at the critical instant (clock at 0, no drift) 20 periods fall in 200 ms: 120."""
    data = seam(QUEUE_05)
    data["nodes"][0]["nic_queue"] = 70  # accepted, so that a runtime configuration is written
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    model, report = analyse_spec(path)
    assert model is not None and not report["errors"]
    doc = json.loads(json.dumps(runtime_document(model, report)))
    eth = doc["buses"][0]["ethernet"]
    del eth["nics"]
    for sw in eth["switches"]:
        del sw["queue"]
        for p in sw["ports"]:
            del p["queue"]
    cfg = runtime.parse(doc, str(path))
    critical = SimOptions(duration_ns=200 * MS, seed=0, random_phase=False, drift_ppm=0.0)
    port = sim_links(cfg, critical)[("h0", "sw")]
    assert (port["max_queue"], port["queue_frames"], port["lost"]) == (QUEUE_FRAMES, QUEUE_FRAMES, 20 * 6)


def test_05_a_switch_port_two_bursts_overfill_is_refused_at_its_queue(tmp_path: Path) -> None:
    """A second host h1 (port 3) with the same 70 datagrams, both NICs 70 deep. sw -> pc receives one frame per
    C = 6.72 us over each input link and sends one per C: after k C (k < 70) 2 (k + 1) have arrived and k left,
    k + 2 are there; at most 71 at k = 69. A port of 64 is refused at the port's entry; `queue: 71` at the
    switch is enough, and at the critical instant (both clocks at 0) the simulator's port holds exactly 71."""
    data = seam(QUEUE_05)
    h1 = {"name": "h1", "ip": "10.0.0.3", "buses": ["lan"], "nic_queue": 70}
    data["nodes"] = [{**data["nodes"][0], "nic_queue": 70}, data["nodes"][1], h1]
    data["buses"][0]["ethernet"]["switches"][0]["ports"].append({"port": 3, "to": "h1"})
    data["messages"] += [
        {**m, "name": f"n{i}", "producer": "h1", "udp": {"src_port": 7000 + i, "dst_port": 8000 + i}}
        for i, m in enumerate(seam(QUEUE_05)["messages"])
    ]
    report = check_data(tmp_path, data)
    assert [e["code"] for e in report["errors"]] == ["queue-overflow"]
    err = report["errors"][0]
    assert err["message"].startswith("switch 'sw' port 2 (to pc) can have 71 frames at once in its egress queue")
    assert "'queue: 71'" in err["message"]
    spec_lines = (tmp_path / "spec.yaml").read_text(encoding="utf-8").splitlines()
    assert spec_lines[err["line"] - 1].lstrip().startswith("- port: 2")
    data["buses"][0]["ethernet"]["switches"][0]["queue"] = 71
    report = check_data(tmp_path, data)
    assert report["ok"], report["errors"]
    assert links(bus(report, "lan"))[("sw", "pc")]["backlog_frames"] == 71
    cfg = runtime_config_of(tmp_path / "spec.yaml", data)
    critical = SimOptions(duration_ns=50 * MS, seed=0, random_phase=False, drift_ppm=0.0)
    port = sim_links(cfg, critical)[("sw", "pc")]
    assert (port["max_queue"], port["queue_frames"], port["lost"]) == (71, 71, 0)


def test_queue_depth_fields_state_the_simulators_default() -> None:
    """The spec language documents the default depth the analysis and the simulator share."""
    assert schema.Switch.model_fields["queue"].description is not None
    assert f"default {QUEUE_FRAMES}," in schema.Switch.model_fields["queue"].description
    assert f"default {QUEUE_FRAMES}," in (schema.Node.model_fields["nic_queue"].description or "")


# --- seams 06 and 06b: egress ports fed over one input link ----------------------------------------------------


def test_06_a_chain_of_switches_charges_the_burst_once() -> None:
    """Seam 06 (exact): a releases 10 minimum frames at once; the last leaves its NIC after 10 C = 67.2 us, then
    the frames cross every cable one per C, so none waits at an egress port: 10 C + 4 (Tmux 1 us + C) = 98.08 us
    for the last of them, whichever it is (netcfg printed 340.0 us before, 3.47x)."""
    lan = bus(check(CHAIN_06), "lan")
    assert {m["wcrt_us"] for m in lan["messages"]} == {98.08}
    assert all(m["delay_us"]["switch"] == 4.0 for m in lan["messages"])  # 4 x Tmux, no queueing
    assert all(ll["backlog_frames"] == 1 for (src, _), ll in links(lan).items() if src != "a")


def test_06_twenty_datagrams_exact_as_well(tmp_path: Path) -> None:
    """Seam 06 with 20 datagrams (its header): 20 C + 4 (1 + C) = 134.4 + 30.88 = 165.28 us (was 676.2 us)."""
    data = seam(CHAIN_06)
    first = data["messages"][0]
    data["messages"] += [
        {**first, "name": f"m{i}", "id": i + 1, "udp": {"src_port": 5000 + i, "dst_port": 6000 + i}}
        for i in range(10, 20)
    ]
    assert {m["wcrt_us"] for m in bus(check_data(tmp_path, data), "lan")["messages"]} == {165.28}


def test_06_the_simulator_reaches_the_exact_figure_and_never_passes_it() -> None:
    """Seeds 0-2, 2 s each (as the seam): every message inside its bound, the worst one at the exact 98.08 us."""
    code, doc = cli_json("simulate", str(CHAIN_06), "--duration", "2s", "--runs", "3", "--seed", "0", "--jobs", "1")
    assert code == 0 and doc["lost"] == 0 and not doc["exceeds_analysis"]
    assert max(m["response_us"]["max"] for m in doc["messages"]) == pytest.approx(98.08, abs=0.01)


# seam 06b's header: the longest responses netcfg simulate measured (seeds 0-5, 5 s each)
SIMULATED_06B = {"mm": 655.1, "x1": 800.3, "x2": 479.4, "x3": 564.8, "fc": 613.9, "fe": 849.2}


def test_06b_a_tree_within_one_and_a_half_times_the_hand_bound() -> None:
    """Seam 06b: mm's hand bound is about 800 us, so at most 1.5 x 800 = 1,200 us (netcfg printed 5,445.64 us
    before); every bound at least what the simulator measured. x3 (1400-byte datagrams, C = 117.36 us, b -> s1 ->
    s2 -> c) by hand: at b's NIC behind x1 (117.36); on s1 -> s2 behind mm (85.36: a frame from b's link ahead of
    it would have been serialised before it); on s2 -> c nothing, for mm and x3 both come over s1 -> s2, where x3
    ends its reception last; 3 x 117.36 + 117.36 + 85.36 + 2 x Tmux 5 us = 564.8 us, the simulator's 564.8."""
    report = check(TREE_06B)
    assert report["ok"], report["errors"]
    lan = bus(report, "lan")
    assert message(lan, "mm")["wcrt_us"] <= 1_200
    assert message(lan, "x3")["wcrt_us"] == 564.8
    bounds = {m["name"]: m["wcrt_us"] for m in lan["messages"]}
    bounds.update({f["name"]: f["latency_max_us"] for f in report["flows"]})
    assert all(bounds[name] >= measured for name, measured in SIMULATED_06B.items()), bounds


def test_06b_simulated_runs_stay_inside_the_bounds() -> None:
    """Seeds 0-5, 5 s each, as the seam's header, and six more: nothing outside its analysed range."""
    for first in ("0", "6"):
        code, doc = cli_json("simulate", str(TREE_06B), "--duration", "5s", "--runs", "6", "--seed", first, "--jobs=1")
        assert code == 0 and not doc["exceeds_analysis"] and doc["lost"] == 0, doc.get("violations")


def test_backlog_of_small_frames_behind_a_long_one() -> None:
    """A NIC with one 1400-byte datagram (117.36 us, every 10 ms) and a minimum frame every 13.44 us, released
    together: while the long frame is sent (0 .. 117.36 us) the short ones released at 0, 13.44, .., 107.52 us
    queue (9 of them); at 120.96 us the tenth arrives while the first is on the wire: 10 frames at once, the most,
    for after that they leave twice as fast as they come. The busy period: 117.36 + 18 x 6.72 = 238.32 us; the
    longest delay 117.36 + 6.72 = 124.08 us (both released at 0, the short one last). Counting departures only
    at the long frame's pace would say 18."""
    q = fifo_queue([Input(False, ((117_360, 10 * MS, 0), (6_720, 13_440, 0)))])
    assert q == Queue(busy_period_ns=238_320, delay_ns=124_080, backlog=10)


def test_a_nic_queue_off_ethernet_is_flagged_where_it_is_written(tmp_path: Path) -> None:
    """nic_queue describes an Ethernet NIC; on a node only on CAN it does nothing: one warning at the key."""
    data = {
        "system": "can_only",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": "500 kbit/s"}],
        "nodes": [{"name": "c", "buses": ["can0"], "nic_queue": 5}, {"name": "d", "buses": ["can0"]}],
        "messages": [{"name": "m", "id": 0x10, "producer": "c", "consumers": ["d"], "size": 1, "period": "10 ms"}],
    }
    report = check_data(tmp_path, data)
    assert report["ok"] and [w["code"] for w in report["warnings"]] == ["wrong-section"]
    line = (tmp_path / "spec.yaml").read_text(encoding="utf-8").splitlines()[report["warnings"][0]["line"] - 1]
    assert line[report["warnings"][0]["column"] - 1 :].startswith("5")
