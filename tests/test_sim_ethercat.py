"""The simulated EtherCAT segment (netcfg.sim.ethercat): its cycle against a hand calculation of the model, its
figures against the analysis' bounds in runtime.json, a lost frame and a lost slave as working-counter mismatches,
and a SYNC0 that comes before the frame has passed."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

from netcfg.runtime import RuntimeConfig
from netcfg.sim.faults import Fault
from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import summary
from netcfg.sim.scenario import SimOptions
from tests.conftest import cli, runtime_config_of
from tests.test_ethercat import spec

C = 0.7 * 299_792_458  # cables at 0.7 c (netcfg.timing.ethernet)
AXIS = [{"index": 0x1600, "map": [0x6040, 0x607A]}, {"index": 0x1A00, "map": [0x6041, 0x6064]}]  # 6 bytes each way

# Two CiA 402 axes, 6 bytes out and 6 in each: a 24-byte image in one LRW datagram. Ethernet header 14 + EtherCAT
# header 2 + datagram 10 + 24 + working counter 2 + FCS 4 = 56 bytes, padded to 64; with preamble and SFD 8 and the
# inter-frame gap 12, 84 bytes on the wire, 6,720 ns at 80 ns a byte.
WIRE_NS = 84 * 80
CABLES_M = (10.0, 20.0)
PROP_NS = [m / C * 1e9 for m in CABLES_M]  # 47.65 and 95.30 ns
FWD_NS = 2 * 1000  # a CoE drive without an ESI: an RJ45 slave, EK1101's "propagation delay 1 us typ." out and back
# the analysis (no jitter): back at the master after the wire, both slaves and the cables both ways; the frame has
# passed the second slave after the wire, both slaves' delays and the cables out to it
LATENCY_BOUND = round(WIRE_NS + 2 * FWD_NS + 2 * sum(PROP_NS))  # 11,006 ns
PASSED_BOUND = round(WIRE_NS + 2 * FWD_NS + sum(PROP_NS))  # 10,863 ns
# the simulator: each slave's delay split in half out and back, each pass shorter by up to one 40 ns receive clock
LATENCY_RANGE = (WIRE_NS + 2 * FWD_NS - 4 * 40 + 2 * sum(PROP_NS), LATENCY_BOUND)
PASSED_RANGE = (WIRE_NS + FWD_NS - 2 * 40 + sum(PROP_NS), WIRE_NS + FWD_NS + sum(PROP_NS))  # 8.78-8.86 us
WKC = 2 * (2 + 1)  # LRW: +2 per slave whose outputs are written, +1 per slave whose inputs are read


def two_axes(tmp_path: Path, **ethercat: Any) -> RuntimeConfig:
    slaves = [
        {"node": f"d{i}", "profile": "cia402", "pdos": AXIS, "cable": m} for i, m in enumerate(CABLES_M)
    ]
    return runtime_config_of(tmp_path / "spec.yaml", spec(tmp_path, slaves, sync0_shift="500 us", **ethercat))


def simulate(cfg: RuntimeConfig, *faults: str, seed: int = 1) -> dict[str, Any]:
    opts = SimOptions(duration_ns=1_000_000_000, seed=seed, faults=tuple(Fault.parse(f) for f in faults))
    return summary(run_once(cfg, opts)[1])


def segment(doc: dict[str, Any]) -> dict[str, Any]:
    (rep,) = doc["protocols"]["ecat"]
    return rep  # type: ignore[no-any-return]


def with_section(cfg: RuntimeConfig, change: Any) -> RuntimeConfig:
    (bus,) = cfg.buses
    section = json.loads(json.dumps(bus.ethercat))
    change(section)
    return dataclasses.replace(cfg, buses=(dataclasses.replace(bus, ethercat=section),))


def test_the_runtime_section_carries_the_bounds(tmp_path: Path) -> None:
    ec = two_axes(tmp_path).buses[0].ethercat
    assert ec is not None
    assert ec["frames"] == [{"data_bytes": 24, "wire_bytes": 84}]
    assert ec["latency_ns"] == LATENCY_BOUND and ec["slaves"][1]["frame_passed_ns"] == PASSED_BOUND
    assert [s["cable_m"] for s in ec["slaves"]] == list(CABLES_M)
    assert [s["forwarding_ns"] for s in ec["slaves"]] == [FWD_NS, FWD_NS]


def test_the_cycle_as_calculated(tmp_path: Path) -> None:
    doc = simulate(two_axes(tmp_path))
    rep = segment(doc)
    assert rep["cycles"] == 1000 and rep["lost_frames"] == 0 and rep["wkc_mismatches"] == 0
    assert rep["expected_wkc"] == WKC and doc["frames"] == 1000
    lat = rep["latency_us"]
    assert LATENCY_RANGE[0] / 1000 <= lat["min"] <= lat["max"] <= LATENCY_RANGE[1] / 1000
    assert lat["analysed"] == LATENCY_BOUND / 1000
    passed = rep["slaves"]["d1"]["frame_passed_us"]
    assert PASSED_RANGE[0] / 1000 <= passed["max"] <= PASSED_RANGE[1] / 1000
    assert passed["analysed"] == PASSED_BOUND / 1000
    # SYNC0 at 500 us, within distributed clocks' 100 ns of the reference: at least 500 - 0.1 - 8.863 us after
    dc = rep["slaves"]["d1"]
    assert -100 <= dc["sync0_error_ns"]["min"] <= dc["sync0_error_ns"]["max"] <= 100
    assert dc["sync0_margin_us"] >= (500_000 - 100 - PASSED_RANGE[1]) / 1000
    assert doc["violations"] == [] and "findings" not in doc
    assert rep["mailbox_room_us"] >= (1_000_000 - LATENCY_BOUND) / 1000


def test_the_masters_jitter_moves_the_frames(tmp_path: Path) -> None:
    rep = segment(simulate(two_axes(tmp_path, master_jitter="20 us")))
    lat = rep["latency_us"]
    assert lat["analysed"] == (LATENCY_BOUND + 20_000) / 1000 and lat["max"] <= lat["analysed"]
    assert lat["max"] - lat["min"] > 15  # 1,000 draws in [0, 20 us]: the spread covers most of it


def test_same_seed_same_run(tmp_path: Path) -> None:
    cfg = two_axes(tmp_path, master_jitter="20 us")
    assert segment(simulate(cfg, seed=4)) == segment(simulate(cfg, seed=4))
    assert segment(simulate(cfg, seed=4)) != segment(simulate(cfg, seed=5))


def test_a_lost_frame_and_a_lost_slave(tmp_path: Path) -> None:
    doc = simulate(two_axes(tmp_path), "lose:ecat@100ms", "crash:d1@500ms")
    rep = segment(doc)
    # one lost frame (cycle 100), then from cycle 500 on the line ends at d0: 1 + 500 mismatches
    assert rep["lost_frames"] == 1 and doc["lost"] == 1 and rep["wkc_mismatches"] == 1 + 500
    first, second = rep["mismatches"][:2]
    assert first == {"time_us": 100_000.0, "wkc": 0, "why": "frame lost"}
    assert second == {"time_us": 500_000.0, "wkc": 3, "why": "slaves missing: d1"}
    assert any("working-counter mismatch" in f for f in doc["findings"])
    assert doc["violations"] == []  # the analysis assumes no loss: findings, not violations of its bounds


def test_a_crashed_master_sends_no_more_cycles(tmp_path: Path) -> None:
    doc = simulate(two_axes(tmp_path), "crash:pc@250ms")
    rep = segment(doc)
    assert rep["cycles"] == 250 and rep["wkc_mismatches"] == 0  # cycles 0..249 start before 250 ms
    assert any("the master 'pc' crashed" in f for f in doc["findings"])


def test_figures_beyond_the_bounds_are_violations(tmp_path: Path) -> None:
    def tighter(section: dict[str, Any]) -> None:  # bounds below what the cycle takes
        section["latency_ns"] = WIRE_NS
        section["slaves"][1]["frame_passed_ns"] = WIRE_NS

    doc = simulate(with_section(two_axes(tmp_path), tighter))
    assert doc["exceeds_analysis"] == ["ecat.cycle"]
    assert len(doc["violations"]) == 2 and "analysed 6.72 us" in doc["violations"][0]


def test_sync0_before_the_frame_has_passed(tmp_path: Path) -> None:
    def early(section: dict[str, Any]) -> None:  # d1 latches 7.5 us in, before the frame has passed it (8.78 us on)
        section["slaves"][1]["dc"]["sync0_shift_ns"] = 7_500

    doc = simulate(with_section(two_axes(tmp_path), early))
    rep = segment(doc)
    assert rep["slaves"]["d1"]["sync0_margin_us"] < 0
    # the analysis did not promise this shift (7.5 us - 0.1 < 10.863 us): a finding, not a violation of it
    assert doc["violations"] == [] and any("SYNC0 fired before the frame had passed" in f for f in doc["findings"])

    def promised(section: dict[str, Any]) -> None:  # a bound that would have let it pass: now the analysis is wrong
        early(section)
        section["slaves"][1]["frame_passed_ns"] = 7_000

    doc = simulate(with_section(two_axes(tmp_path), promised))
    assert any("analysed in time" in v for v in doc["violations"])


def test_the_command(tmp_path: Path) -> None:
    two_axes(tmp_path)
    done = cli("simulate", str(tmp_path / "spec.yaml"), "--duration", "200ms", "--fault", "lose:ecat@50ms")
    assert done.returncode == 1, done.stderr  # a lost frame
    assert "1 frames lost, 1 working-counter mismatches (expected 6)" in done.stdout
    assert "working counter 0: frame lost" in done.stdout
    bad = cli("simulate", str(tmp_path / "spec.yaml"), "--fault", "lose:ecatx@50ms")
    assert bad.returncode == 2 and "message named 'ecatx', nor an EtherCAT bus" in bad.stderr
