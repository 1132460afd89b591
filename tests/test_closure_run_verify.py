"""`netcfg run --log` -> `netcfg verify`: verify judges the master's cyclic phase and reports its set-up and its
shut-down as phases of their own (before, the SDO set-up read as a 105 % load peak and the silence after the safe
stop as missing periods of every message)."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import SPECS, cli

DRIVES = ("hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r")  # ALLEX-2's EPOS4 drives, node ids 1-6 (seed 000)


def test_a_run_log_is_judged_in_its_cyclic_phase(tmp_path: Path) -> None:
    """The run: set-up over SDO, then NMT start of each of the six drives (CiA 301 7.2.8.3.1.1: command 0x01 to a
    node id) before the first SYNC; 50 SYNC cycles of 20 ms; the safe stop over SDO and NMT pre-operational after
    the last. The cyclic phase spans the 50 SYNCs: 49 periods and one more, 50 x 20 ms = 1 s (within the wall
    clock's slack of one period). What the analysis bounds on a bus (load, periods) holds there; the drives are
    threads of this process in wall-clock time, so the log's timestamps are a host's (frames closer together than
    a 1 Mbit/s wire can carry them: netcfg.verify.host_clock) and what the host's latency adds is named so
    ('host_late'), not a bus violation; a host that runs late by more than half a period leaves a no-SYNC fault
    phase of the master, never one of a drive."""
    log = tmp_path / "run.log"
    run = cli("run", str(SPECS / "allex2.yaml"), "--simulated-drives", "--cycles", "50", "--log", str(log))
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    proc = cli("verify", str(SPECS / "allex2.yaml"), str(log), "--format", "json")
    doc = json.loads(proc.stdout)
    assert set(doc["violations_by_kind"]) <= {"host_late"}, doc["violations_by_kind"]
    assert doc["timestamps"]["clock"] == "host"
    assert {p["kind"] for p in doc["fault_phases"]} <= {"no-sync"}
    phases = doc["phases"]
    starts = [c["node"] for c in phases["setup"]["nmt_commands"] if c["command"] == "start"]
    assert sorted(starts) == sorted(DRIVES)
    assert phases["setup"]["sdo_frames"] > 0 and phases["shutdown"]["sdo_frames"] > 0
    cyclic = phases["cyclic"]["to_us"] - phases["cyclic"]["from_us"]
    assert abs(cyclic - 50 * 20_000) <= 20_000
    assert next(m for m in doc["messages"] if m["name"] == "can0_SYNC")["count"] == 50
