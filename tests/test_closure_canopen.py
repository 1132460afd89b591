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
