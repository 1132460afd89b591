"""Seam 13 (tests/data/seams/13-canopen-master-jitter-reader.yaml, its header the derivation): a free-running flow
into the master's SYNC task. The task starts anywhere in [offset, offset + master_jitter] after each SYNC instant
(CiA 301 leaves the master's wake-up latency to the master; the spec's master_jitter bounds it), so two of its
starts can be a period and that jitter apart, and data that just missed one start waits that long for the next.

Hand calculation of fb3 (d2_tx1 -> master.control): d2_tx1's worst response 435 us (the check's delivery, itself
held by the simulator), then one SYNC period in real time at the bus's clock tolerance, 16 ms * (1 + 100 ppm) =
16,001.6 us, plus master_jitter 499 us: 435 + 16,001.6 + 499 = 16,935.6 us. The simulator measured 16,476.7 us
where the analysis said 16,436.6 (the period without the jitter)."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import yaml
from conftest import check

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import soundness  # noqa: E402

SEAMS = ROOT / "tests" / "data" / "seams"
SPEC = SEAMS / "13-canopen-master-jitter-reader.yaml"
RUN_SEED = 1844  # the sweep's run seed for this spec (its header)


def _flow(report: dict, name: str) -> dict:
    return next(f for f in report["flows"] if f["name"] == name)


def test_a_flow_into_the_jittered_master_loop_keeps_its_bound() -> None:
    spec = yaml.safe_load(SPEC.read_text(encoding="utf-8"))
    out = soundness.check_spec(spec, RUN_SEED, 500_000_000)
    assert out.accepted
    assert out.violations == []


def test_the_wait_for_the_master_loop_counts_its_jitter(tmp_path: Path) -> None:
    shutil.copy(SEAMS / "drive_et.eds", tmp_path / "drive_et.eds")
    path = tmp_path / "spec.yaml"
    shutil.copy(SPEC, path)
    fb3 = _flow(check(path), "fb3")["unsynchronised"]
    assert fb3["delivery_max_us"] == 435.0
    assert fb3["latency_max_us"] == round(435 + 16_000 * 1.0001 + 499, 3)
    # without the jitter, the period alone: 435 + 16,001.6
    text = path.read_text(encoding="utf-8").replace("master_jitter: 499 us", "master_jitter: 0 us")
    path.write_text(text, encoding="utf-8")
    assert _flow(check(path), "fb3")["unsynchronised"]["latency_max_us"] == round(435 + 16_000 * 1.0001, 3)


def test_without_master_jitter_the_same_flow_keeps_its_bound() -> None:
    """The ingredient: the same spec with master_jitter 0 is simulated inside its bounds."""
    spec = yaml.safe_load(SPEC.read_text(encoding="utf-8"))
    spec["buses"][0]["canopen"]["master_jitter"] = "0 us"
    out = soundness.check_spec(spec, RUN_SEED, 500_000_000)
    assert out.accepted and out.violations == []
