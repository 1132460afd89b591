"""A seeded simulation is a function of its configuration: each case of scripts/sim_fingerprints.py, run afresh,
measures exactly what tests/data/sim_fingerprints.json recorded (every frame's response time, every flow sample,
the counters and protocol reports, as digests), so a speed-up that moves one simulated instant fails here.

The recorded file is the simulator's own earlier output, not figures copied by hand; a change meant to alter what a
run measures rewrites it (`make generated`) and says why in its commit.
"""

from __future__ import annotations

import json
import sys
from typing import Any

import pytest
from conftest import ROOT

sys.path.insert(0, str(ROOT / "scripts"))

from sim_fingerprints import CASES, OUT, fingerprint

RECORDED = json.loads(OUT.read_text(encoding="utf-8"))


def test_every_case_is_recorded() -> None:
    assert sorted(RECORDED) == sorted(label for label, _, _ in CASES), "run scripts/sim_fingerprints.py"


@pytest.mark.parametrize(("label", "system", "options"), CASES, ids=[c[0] for c in CASES])
def test_seeded_run_matches_its_fingerprint(label: str, system: str, options: dict[str, Any]) -> None:
    fresh = fingerprint(system, options)
    recorded = RECORDED[label]
    moved = {
        f"{table}.{name}"
        for table in ("messages", "flows")
        for name in set(fresh[table]) | set(recorded[table])
        if fresh[table].get(name) != recorded[table].get(name)
    }
    assert not moved, f"{label}: simulated figures changed for {sorted(moved)[:10]}"
    assert fresh == recorded


def test_a_different_seed_moves_the_fingerprint() -> None:
    """The digests do see the simulation: another seed of the first case gives other figures."""
    label, system, options = CASES[0]
    assert fingerprint(system, {**options, "seed": options["seed"] + 1}) != RECORDED[label]
