"""A synchronised CANopen flow walks the pattern of its own TPDOs, not every TPDO's of the bus: found by the soundness
generator, a bus with TPDOs every 19, 240, 172, 170 and 174 SYNCs (least common multiple 10,113,840) kept check
walking 2 x that many cycles."""

from __future__ import annotations

import json
import subprocess
import sys

from conftest import ROOT, cli

SPEC = ROOT / "tests" / "data" / "canopen" / "long_tpdo_pattern.yaml"


def test_a_long_tpdo_pattern_is_analysed_and_holds() -> None:
    """The flow [d0_a, master.control]: d0_a samples at SYNC's reception, the master computes 5 ms after SYNC
    is queued (its SYNC task's offset, no master_jitter). The SYNC frame, 0 data bytes, arrives 47 us after it is
    queued at the earliest (its 47 bits without stuff bits at 1 Mbit/s, ISO 11898-1), so the data is
    at most 5,000 - 47 = 4,953 us old when the task starts; the simulator's figure lies inside the bound."""
    proc = subprocess.run(  # a time-out, not a hang, if the walk comes back
        [sys.executable, "-m", "netcfg", "check", str(SPEC), "--format", "json"],
        capture_output=True, text=True, timeout=120, cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stderr
    flow = json.loads(proc.stdout)["flows"][0]
    assert flow["mode"] == "synchronised" and flow["latency_max_us"] == 5_000 - 47
    sim = json.loads(cli("simulate", str(SPEC), "--duration", "5s", "--format", "json").stdout)
    measured = next(f for f in sim["flows"] if f["name"] == "fb")["latency_us"]
    assert flow["latency_min_us"] <= measured["min"] and measured["max"] <= flow["latency_max_us"]
