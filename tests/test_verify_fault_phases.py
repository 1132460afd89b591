"""`netcfg verify` of a drill's log: the fault and the recovery as phases (netcfg.verify.fault_phases), the gaps
inside them not violations; and whose clock stamped the log (netcfg.verify.host_clock).

Sources of the numbers:
- specs/allex2.yaml: six drives on can0 at 1 Mbit/s, SYNC period T = 20 ms, heartbeat 100 ms, consumer heartbeat
  time 300 ms, on_loss stop_node, on_emcy stop_all (default), on_reboot stop_node (default);
  examples/allex2_recover.yaml: the same with on_reboot: recover.
- The simulator's drills act at their instant in virtual time (tests/test_simulate_drills.py); its log's times count
  from its first frame, which ends within a frame time (< 0.2 ms at 1 Mbit/s) of 0: times below are within 1 ms.
- CiA 301: boot-up = heartbeat COB-ID with one byte 0x00 (7.2.8.3.2.1); NMT start = COB-ID 0, bytes 0x01, node id.
- A classical 8-byte frame with an 11-bit identifier has 111 bits without stuff bits (SOF 1, identifier 11, RTR 1,
  IDE 1, r0 1, DLC 4, data 64, CRC 15, delimiter 1, ACK 2, EOF 7, intermission 3): 111 us at 1 Mbit/s, so two such
  frames cannot end less than 111 us apart on the wire.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import ROOT, SPECS, cli

from netcfg.runtime import load
from netcfg.verify.host_clock import HostClock

SPEC = str(SPECS / "allex2.yaml")
MS = 1000  # us


def verify(spec: str, log: Path) -> dict[str, Any]:
    proc = cli("verify", spec, str(log), "--format", "json")
    assert proc.returncode in (0, 1), proc.stderr[-2000:]
    return json.loads(proc.stdout)


def simulated(tmp_path: Path, fault: str | None) -> dict[str, Any]:
    log = tmp_path / "sim.log"
    extra = ["--fault", fault] if fault else []
    proc = cli("simulate", SPEC, "--duration", "2s", "--log", str(log), *extra)
    assert proc.returncode in (0, 1), proc.stderr[-2000:]
    return verify(SPEC, log)


def shape(doc: dict[str, Any]) -> list[tuple[str, str | None, str | None]]:
    return [(p["phase"], p.get("kind"), p.get("node")) for p in doc["phase_sequence"]]


def fault(doc: dict[str, Any]) -> dict[str, Any]:
    (f,) = [p for p in doc["phase_sequence"] if p["phase"] == "fault"]
    return f


def test_a_healthy_simulated_log_is_one_normal_phase(tmp_path: Path) -> None:
    doc = simulated(tmp_path, None)
    assert doc["ok"] and doc["fault_count"] == 0 and shape(doc) == [("normal", None, None)]
    assert doc["timestamps"]["clock"] == "wire" and doc["timestamps"]["too_close"] == 0


def test_reset_reads_as_normal_fault_stopped(tmp_path: Path) -> None:
    """knee_r silent from its last TPDO before 1 s (the SYNC at 0.98 s was the last it answered) to its boot-up at
    1.05 s; on_reboot stop_node: no NMT start after it, so it stays stopped to the end."""
    doc = simulated(tmp_path, "reset:knee_r@1s+50ms")
    assert shape(doc) == [("normal", None, None), ("fault", "reboot", "knee_r"), ("stopped", None, "knee_r")]
    f = fault(doc)
    assert 980 * MS <= f["from_us"] <= 1000 * MS and abs(f["to_us"] - 1050 * MS) <= 1 * MS
    assert doc["violation_count"] == 0 and doc["fault_count"] == 1 and not doc["ok"]
    knee = {m["name"]: m for m in doc["messages"]}
    assert knee["knee_r_state"]["missing"] == 0 and knee["knee_r_state"]["missing_in_faults"] > 0


def test_kill_reads_as_a_loss_to_the_end(tmp_path: Path) -> None:
    """The master's NMT stop of the lost node makes it a master's log: set-up (before the first SYNC) and shut-down
    (after the last SYNC + T) are phases of their own."""
    doc = simulated(tmp_path, "kill:knee_r@1s")
    assert shape(doc) == [
        ("set-up", None, None), ("normal", None, None), ("fault", "lost", "knee_r"), ("shut-down", None, None)
    ]
    assert 980 * MS <= fault(doc)["from_us"] <= 1000 * MS
    assert doc["violation_count"] == 0


def test_emcy_reads_as_the_fault_then_the_safe_stop(tmp_path: Path) -> None:
    """EMCY at 1 s; stop_all: the cycle ends, every node gets NMT enter pre-operational within a period."""
    doc = simulated(tmp_path, "emcy:hip_l@1s")
    assert shape(doc) == [
        ("set-up", None, None), ("normal", None, None), ("fault", "emcy", "hip_l"), ("shut-down", None, None)
    ]
    f = fault(doc)
    assert abs(f["from_us"] - 1000 * MS) <= 1 * MS and f["to_us"] - f["from_us"] <= 20 * MS + 1 * MS
    assert "EMCY 0x2310" in f["detail"] and doc["violation_count"] == 0


@pytest.mark.parametrize("drill", ["stall:1s..1.2s", "bus-off:1s..1.2s"])
def test_a_master_that_sends_nothing_reads_as_normal_no_sync_normal(tmp_path: Path, drill: str) -> None:
    """The last SYNC before 1 s (at most T before it) to the first after 1.2 s (at most T after it); the gaps of
    every message in between are the fault's."""
    doc = simulated(tmp_path, drill)
    assert shape(doc) == [("normal", None, None), ("fault", "no-sync", None), ("normal", None, None)]
    f = fault(doc)
    assert 980 * MS <= f["from_us"] <= 1000 * MS and 1200 * MS <= f["to_us"] <= 1220 * MS + 1 * MS
    assert doc["violation_count"] == 0


def test_run_reset_with_recover_reads_as_fault_recovery_normal(tmp_path: Path) -> None:
    """The live master on simulated drives, wall-clock: the host may add short no-SYNC phases of its own (a loaded
    host, named as such); the drill's phases come in this order whatever the host does."""
    log = tmp_path / "run.log"
    spec = str(ROOT / "examples" / "allex2_recover.yaml")
    cli("run", spec, "--simulated-drives", "--cycles", "60", "--reset", "knee_r@0.5s+50ms", "--log", str(log))
    doc = verify(spec, log)
    mine = [s for s in shape(doc) if s[1] != "no-sync" and s[0] != "normal"]
    assert mine == [
        ("set-up", None, None), ("fault", "reboot", "knee_r"), ("recovery", None, "knee_r"), ("shut-down", None, None)
    ]
    (reboot,) = [p for p in doc["fault_phases"] if p["kind"] == "reboot"]
    rec = reboot["recovery"]
    assert rec["started_us"] is not None and rec["back_us"] > rec["started_us"] > reboot["to_us"]
    assert rec["sdo_frames"] > 0 and rec["took_ms"] == pytest.approx((rec["back_us"] - reboot["to_us"]) / 1000)
    # the gaps are the fault's; what remains is the host's lateness, or the recovery's SDO burst on the bus's load
    assert set(doc["violations_by_kind"]) <= {"host_late", "load"}, doc["violations_by_kind"]
    assert doc["timestamps"]["clock"] == "host"


def test_a_host_clock_is_told_from_frames_closer_than_the_wire_allows() -> None:
    cfg = load(ROOT / "generated" / "allex2" / "runtime.json")
    bus = [b for b in cfg.buses if b.is_can]
    wire, host, glitch = HostClock(bus), HostClock(bus), HostClock(bus)
    n = 20
    flags, length, on = np.zeros(n, np.uint8), np.full(n, 8), np.zeros(n, np.int64)
    wire.take(1000 + 111 * np.arange(n), on, flags, length)  # 111 us apart: possible
    host.take(1000 + 50 * np.arange(n), on, flags, length)  # 50 us apart: not on a wire
    one_off = 1000 + 111 * np.arange(n)
    one_off[10] -= 61  # one frame 50 us after the one before: an edited log, not a host's clock
    glitch.take(one_off, on, flags, length)
    assert wire.report() == {"clock": "wire", "pairs": n - 1, "too_close": 0}
    assert host.report() == {"clock": "host", "pairs": n - 1, "too_close": n - 1, "closest_us": 50, "needed_us": 111}
    assert glitch.report()["clock"] == "wire" and glitch.report()["too_close"] == 1
