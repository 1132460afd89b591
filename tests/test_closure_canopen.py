"""simulate -> verify on a CANopen bus: what the simulated nodes say of themselves is what a started node says."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import SPECS, cli


def test_simulated_heartbeats_say_operational(tmp_path: Path) -> None:
    """A simulated run is the cyclic phase, after the nodes were started: CiA 301 7.2.8.3.2.4 has a started node's
    heartbeat carry 0x05 (operational), not 0x00 (boot-up, sent once on power-up). ALLEX-2's six drives beat every
    100 ms: 20 heartbeats each in 2 s."""
    log = tmp_path / "run.log"
    assert cli("simulate", str(SPECS / "allex2.yaml"), "--duration", "2s", "--log", str(log)).returncode == 0
    proc = cli("verify", str(SPECS / "allex2.yaml"), str(log), "--format", "json")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr
    beats = json.loads(proc.stdout)["buses"][0]["canopen"]["heartbeats"]
    assert sorted(beats) == sorted(["hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r"])
    assert all(b == {"count": 20, "state": "operational"} for b in beats.values()), beats


def test_simulate_supervises_heartbeats_as_run_does(tmp_path: Path) -> None:
    """knee_r crashes at 1 s; its heartbeat comes every 100 ms and the master's consumer time is 300 ms (ALLEX-2, 3 x
    the producer time). Its last heartbeat came at most 100 ms before the crash, so the master, checking once a 20 ms
    cycle, reports it lost between 1 + 0.3 - 0.1 = 1.2 s and 1 + 0.3 + 0.02 = 1.32 s, silent over 300 ms, with the
    spec's on_loss (stop_node); no other drive is reported."""
    proc = cli("simulate", str(SPECS / "allex2.yaml"), "--duration", "2s", "--fault", "crash:knee_r@1s",
               "--format", "json")
    doc = json.loads(proc.stdout)
    events = [e for reps in doc["protocols"].values() for rep in reps for e in rep.get("supervision", ())]
    assert [(e["node"], e["kind"], e["action"]) for e in events] == [("knee_r", "lost", "stop_node")]
    assert 1.2 <= events[0]["time_s"] <= 1.32
    silent_ms = float(events[0]["text"].split("no heartbeat for ")[1].split(" ms")[0])
    assert silent_ms > 300
