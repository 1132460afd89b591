"""Fingerprints of seeded simulation runs: what a run measured, frame by frame, as digests.

The simulator's speed work must not change a single simulated figure: for a fixed seed a run is a function of its
configuration alone. tests/test_sim_fingerprints.py runs each case below afresh and compares it with
tests/data/sim_fingerprints.json, which this script writes from the current simulator:

    .venv/bin/python scripts/sim_fingerprints.py        # rewrite tests/data/sim_fingerprints.json (make generated)

Only what the simulation produced is fingerprinted (response times of every frame, flow samples, counters,
protocol reports), not the analysis' figures runtime.json carries, so a change to the analysis leaves the
fingerprints alone while any change to a simulated instant shows, named by message or flow.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from netcfg import runtime
from netcfg.sim.faults import Fault
from netcfg.sim.montecarlo import run_once
from netcfg.sim.scenario import SimOptions

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "data" / "sim_fingerprints.json"
MS = 1_000_000

# (label, generated system, options): every protocol driver, both CANopen masters, exact stuffing, faults, traces;
# short runs, so the test stays a few seconds
CASES: list[tuple[str, str, dict[str, Any]]] = [
    ("allex2 pdo", "allex2", {"duration_ns": 2000 * MS, "seed": 3}),
    ("allex2 sdo", "allex2", {"duration_ns": 1000 * MS, "seed": 1, "canopen": "sdo"}),
    ("allex2 faults", "allex2", {"duration_ns": 1500 * MS, "seed": 2, "faults": ("ber=1e-4", "crash:knee_r@700ms")}),
    ("cambada", "cambada", {"duration_ns": 3000 * MS, "seed": 5}),
    ("cambada unsync", "cambada", {"duration_ns": 2000 * MS, "seed": 6, "mode": "unsync"}),
    ("cambada faults", "cambada", {
        "duration_ns": 2000 * MS, "seed": 4, "faults": ("master-fail@700ms", "lose:encoder1@300ms")}),
    ("ntua_sahr", "ntua_sahr", {"duration_ns": 300 * MS, "seed": 7}),
    ("ntua_treadmill", "ntua_treadmill", {"duration_ns": 300 * MS, "seed": 8}),
    ("large_plant", "large_plant", {"duration_ns": 500 * MS, "seed": 9}),
    ("large_plant babble", "large_plant", {
        "duration_ns": 300 * MS, "seed": 11, "faults": ("babble:axis03@100ms..150ms",)}),
    ("ntua_sahr lose", "ntua_sahr", {
        "duration_ns": 100 * MS, "seed": 12, "faults": ("lose:hip_pwm@20ms", "crash:pc@80ms")}),
    ("allex2_ethercat faults", "allex2_ethercat", {
        "duration_ns": 1000 * MS, "seed": 13, "faults": ("lose:ecat0@100ms", "crash:knee_r@600ms")}),
    ("arm_canfd exact trace", "arm_canfd", {"duration_ns": 500 * MS, "seed": 10, "stuffing": "exact", "trace": True}),
]


def _digest(values: Any) -> str:
    return hashlib.sha256(np.asarray(values, dtype=np.int64).tobytes()).hexdigest()[:16]


def fingerprint(system: str, options: dict[str, Any]) -> dict[str, Any]:
    """One seeded run of generated/<system>/runtime.json, as digests of what it measured."""
    opts = dict(options)
    opts["faults"] = tuple(Fault.parse(f) for f in opts.get("faults", ()))
    cfg = runtime.load(ROOT / "generated" / system / "runtime.json")
    sc, res = run_once(cfg, SimOptions(**opts))
    out: dict[str, Any] = {
        "frames": res.frames,
        "error_frames": res.error_frames,
        "unsent_at_end": res.unsent_at_end,
        "messages": {
            name: [len(r), _digest(r), res.lost.get(name, 0), res.retransmissions.get(name, 0)]
            for name, r in sorted(res.response.items())
        },
        "flows": {
            name: [len(s), _digest(s), _digest(res.flow_delivery.get(name, ()))]
            for name, s in sorted(res.flow_latency.items())
        },
        "protocols": hashlib.sha256(json.dumps(res.protocols, sort_keys=True).encode()).hexdigest()[:16],
    }
    if opts.get("trace"):
        ends = [e for can in sc.can.values() for e in can.record.end]
        data = b"".join(d or b"" for can in sc.can.values() for d in can.record.data)
        out["trace"] = [_digest(ends), hashlib.sha256(data).hexdigest()[:16]]
    return out


def all_fingerprints() -> dict[str, Any]:
    return {label: fingerprint(system, options) for label, system, options in CASES}


def render(prints: dict[str, Any]) -> str:
    """JSON with one line per message or flow, so a change reads as a short diff naming what moved."""
    cases = []
    for label, fp in sorted(prints.items()):
        parts = []
        for key, value in sorted(fp.items()):
            if isinstance(value, dict):
                rows = ",\n".join(f"   {json.dumps(k)}: {json.dumps(v)}" for k, v in sorted(value.items()))
                parts.append(f"  {json.dumps(key)}: {{\n{rows}\n  }}" if rows else f"  {json.dumps(key)}: {{}}")
            else:
                parts.append(f"  {json.dumps(key)}: {json.dumps(value)}")
        cases.append(f" {json.dumps(label)}: {{\n" + ",\n".join(parts) + "\n }")
    return "{\n" + ",\n".join(cases) + "\n}\n"


def main() -> int:
    OUT.write_text(render(all_fingerprints()), encoding="utf-8")
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
