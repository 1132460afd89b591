"""`netcfg simulate --fault KIND:ARG`: the drills of `netcfg run --KIND ARG`, in one grammar, played on the simulated
bus's live master in virtual time, each with its expected sequence of events.

Sources of the numbers:
- specs/allex2.yaml (generated/allex2/runtime.json): six drives, node ids 1-6, SYNC period T = 20 ms, heartbeat
  100 ms, the master's consumer heartbeat time 300 ms, on_loss: stop_node, on_emcy not given (default stop_all),
  on_reboot not given (default stop_node).
- The master reads the bus in each cycle and checks supervision after it, so a frame sent at t is reported at a
  time in [t, t + T]; a drill on the master (stall, bus-off) acts after the first cycle that ends at or after its
  instant, so within [T_drill, T_drill + T]. Virtual time: no host slack.
- CiA 301 7.2.8.3.2.1: a rebooted node sends its boot-up message (heartbeat COB-ID 0x700 + node id, one byte
  0x00) and is PRE-OPERATIONAL (no PDO). 7.2.8.3.1.1: NMT "enter pre-operational" is COB-ID 0x000, bytes
  0x80, node id.
- SYNCs answered before a drive goes silent at 1 s: the SYNC instants 0, 20, ..., 980 ms, 1000 / 20 = 50.
"""

from __future__ import annotations

import itertools
from dataclasses import replace
from typing import Any

import pytest
from conftest import ROOT, cli

import netcfg.runtime as rt
from netcfg.runtime.drills import DrillError, parse_drill
from netcfg.sim.can_trace import trace_frames
from netcfg.sim.faults import Fault, FaultError
from netcfg.sim.montecarlo import run_once
from netcfg.sim.scenario import SimOptions
from netcfg.sim.trace import TraceFrame

T_S = 0.020
CONSUMER_S = 0.300
HEARTBEAT_S = 0.100


@pytest.fixture(scope="module")
def cfg() -> rt.RuntimeConfig:
    return rt.load(ROOT / "generated" / "allex2" / "runtime.json")


def simulate(cfg: rt.RuntimeConfig, fault: str, seconds: float = 2.0) -> tuple[dict[str, Any], list[TraceFrame]]:
    opts = SimOptions(duration_ns=round(seconds * 1e9), seed=0, faults=(Fault.parse(fault),), trace=True)
    sc, _ = run_once(cfg, opts)
    return sc.protocols["can0"].report(), trace_frames(sc)


def events(rep: dict[str, Any]) -> list[tuple[str, str, str]]:
    return [(e["node"], e["kind"], e["action"]) for e in rep.get("supervision", [])]


def test_one_grammar_for_run_and_simulate() -> None:
    for kind, arg in (
        ("reset", "knee_r@1s+50ms"), ("emcy", "hip_l@0.5s=0x3210"), ("stall", "0.3s..0.5s"),
        ("bus-off", "300 ms..0.5 s"),
    ):
        assert Fault.parse(f"{kind}:{arg}").drill == parse_drill(kind, arg)
    assert Fault.parse("kill:knee_r@1s") == Fault("crash", "knee_r", 10**9, drill=parse_drill("kill", "knee_r@1s"))
    # the same refusal, naming the option as each command writes it
    with pytest.raises(DrillError, match=r"--reset 'knee_r@1s': write NODE@TIME\+OUTAGE"):
        parse_drill("reset", "knee_r@1s")
    with pytest.raises(FaultError, match=r"fault 'reset:knee_r@1s': write NODE@TIME\+OUTAGE"):
        Fault.parse("reset:knee_r@1s")
    run = cli("run", "specs/allex2.yaml", "--simulated-drives", "--cycles", "1", "--reset", "knee_r@1s")
    sim = cli("simulate", "specs/allex2.yaml", "--duration", "20ms", "--fault", "reset:knee_r@1s")
    assert (run.returncode, sim.returncode) == (2, 2)
    assert run.stderr.split(": write ")[1] == sim.stderr.split(": write ")[1]


def test_reset_is_a_boot_up_then_stop_node(cfg: rt.RuntimeConfig) -> None:
    """Silent from 1 s, boot-up at 1.05 s; on_reboot stop_node: its RxPDOs stop, it stays PRE-OPERATIONAL. Its
    heartbeat comes back at 100 ms (< the 300 ms consumer time): no loss."""
    rep, trace = simulate(cfg, "reset:knee_r@1s+50ms")
    assert rep["drills"] == [{"time_s": 1.0, "text": "knee_r reboots, silent for 50 ms"}]
    assert events(rep) == [("knee_r", "boot-up", "stop_node")]
    boot = rep["supervision"][0]["time_s"]
    assert 1.05 <= boot <= 1.05 + T_S
    assert rep["drives"]["knee_r"]["samples"] == 50
    beats = [f for f in trace if f.can_id == 0x705 and f.t_ns >= 1.05e9]
    assert bytes(beats[0].data) == b"\x00" and {bytes(f.data) for f in beats[1:]} == {b"\x7f"}
    gaps = [b.t_ns - a.t_ns for a, b in itertools.pairwise(beats)]
    assert gaps and all(g == HEARTBEAT_S * 1e9 for g in gaps)
    assert "violations" not in rep


def test_emcy_with_the_default_stop_all_ends_the_cycle(cfg: rt.RuntimeConfig) -> None:
    """EMCY 0x2310 at 0.5 s: reported within a period, the cycle ends (stop_all) and every drive gets NMT
    enter pre-operational (6 frames 0x000: 0x80, node id 1..6)."""
    rep, trace = simulate(cfg, "emcy:hip_l@0.5s")
    assert events(rep) == [("hip_l", "emcy", "stop_all")]
    assert 0.5 <= rep["supervision"][0]["time_s"] <= 0.5 + T_S
    assert rep["ended_by"].startswith("stop_all: hip_l: EMCY 0x2310")
    assert 0.5 / T_S <= rep["cycles"] <= 0.5 / T_S + 2  # the cycles to 0.5 s, and the one that saw it
    nmt = [bytes(f.data) for f in trace if f.can_id == 0]
    assert nmt == [bytes([0x80, n]) for n in range(1, 7)]
    emcy = [bytes(f.data) for f in trace if f.can_id == 0x81]
    assert emcy == [bytes([0x10, 0x23, 0x01, 0, 0, 0, 0, 0])]  # CiA 301 7.2.7.3.1: code LE, register, 5 bytes


def test_emcy_with_stop_node_stops_that_drive_alone(cfg: rt.RuntimeConfig) -> None:
    nodes = tuple(replace(n, on_emcy="stop_node") if n.role == "slave" else n for n in cfg.nodes)
    stop_node = replace(cfg, nodes=nodes)
    rep, trace = simulate(stop_node, "emcy:hip_l@0.5s")
    assert events(rep) == [("hip_l", "emcy", "stop_node")]
    assert rep["ended_by"] is None and rep["cycles"] == 2.0 / T_S
    nmt = [f for f in trace if f.can_id == 0]
    assert [bytes(f.data) for f in nmt] == [bytes([0x80, 1])]
    after = [f for f in trace if f.can_id in (0x181, 0x281) and f.t_ns > nmt[0].t_ns]
    assert after == []  # its TPDOs stopped when the command reached it
    assert rep["drives"]["hip_l"]["samples"] < rep["drives"]["knee_l"]["samples"] == 2.0 / T_S


def test_kill_is_a_loss_after_the_consumer_time(cfg: rt.RuntimeConfig) -> None:
    """The last heartbeat came within 100 ms before 1 s; lost 300 ms after it, seen within a period."""
    rep, _ = simulate(cfg, "kill:knee_r@1s")
    assert rep["drills"] == [{"time_s": 1.0, "text": "knee_r killed"}]
    assert events(rep) == [("knee_r", "lost", "stop_node")]
    assert 1.0 - HEARTBEAT_S + CONSUMER_S <= rep["supervision"][0]["time_s"] <= 1.0 + CONSUMER_S + T_S


def test_stall_reports_the_sync_instants_it_missed(cfg: rt.RuntimeConfig) -> None:
    """The loop sleeps from the cycle after 0.3 s to 0.5 s: one gap in the SYNCs from the last one before 0.3 s
    (within a period) to the first after 0.5 s, the instants between it missed; the cycle goes on on its grid."""
    rep, _ = simulate(cfg, "stall:0.3s..0.5s")
    assert events(rep) == [("master", "missed-sync", "continue")]
    (gap,) = rep["sync_gaps"]
    assert 0.3 - T_S <= gap["from_s"] <= 0.3 and 0.5 <= gap["to_s"] <= 0.5 + T_S
    assert gap["missed"] == round((gap["to_s"] - gap["from_s"]) / T_S) - 1 >= (0.5 - 0.3) / T_S - 1
    assert "violations" not in rep


def test_bus_off_holds_the_cycle_and_measures_the_recovery(cfg: rt.RuntimeConfig) -> None:
    rep, trace = simulate(cfg, "bus-off:0.3s..0.5s")
    assert events(rep) == [
        ("master", "bus-off", "hold"), ("master", "bus-on", "continue"), ("master", "missed-sync", "continue")
    ]
    (off,) = rep["bus_offs"]
    assert 0.3 <= off["detected_s"] <= 0.3 + T_S and off["back_s"] == 0.5  # virtual time: the drill's own end
    assert 0 <= off["recovery_ms"] <= 1e3 * T_S
    sent = [f.t_ns for f in trace if f.can_id == 0x80]
    assert not [t for t in sent if 0.3e9 < t < 0.5e9]  # no SYNC while the controller was off


def test_sdo_abort_is_refused_with_where_to_drill_it() -> None:
    proc = cli("simulate", "specs/allex2.yaml", "--duration", "20ms", "--fault", "sdo-abort:knee_r:0x1017")
    assert proc.returncode == 2
    assert "netcfg run --simulated-drives --sdo-abort knee_r:0x1017" in proc.stderr


def test_a_drill_needs_a_canopen_bus() -> None:
    proc = cli("simulate", "specs/arm_canfd.yaml", "--duration", "20ms", "--fault", "stall:1ms..2ms")
    assert proc.returncode == 2 and "CANopen" in proc.stderr
