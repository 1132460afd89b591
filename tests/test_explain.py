"""netcfg check SPEC --explain MESSAGE reproduces a hand-worked derivation, in text and JSON."""

from __future__ import annotations

import json

from conftest import ROOT, cli

WRONG_ORDER = ROOT / "examples" / "wrong_order.yaml"


def test_explain_reproduces_the_hand_worked_bound() -> None:
    """ecu_pwm in examples/wrong_order.yaml, by hand (Davis et al. 2007): an 8-byte standard frame is 47 + 64 = 111
    bits plus up to floor((34 + 64 - 1) / 4) = 24 stuff bits, 135 bits = 270 us at 500 kbit/s (tau 2 us). It has
    the largest identifier (0x160): no blocking. Its 16 higher-priority messages each hit once in
    w0 = 16 * 270 = 4320 us; then the two 2 ms messages hit ceil(4322 / 2000) = 3 times: w = 5400; then the two
    5 ms messages ceil(5402 / 5000) = 2 times: w = 5940, which is stable (ceil(5942 / 2000) = 3,
    ceil(5942 / 5000) = 2, every other period > 5942). R = 0 + 5940 - 0 + 270 = 6210 us > 1000 us.
    The fix: any free identifier below 0x100 puts it on top: R = B + C = 270 + 270 = 540 us; 0x0FF is the
    largest such."""
    run = cli("check", str(WRONG_ORDER), "--explain", "ecu_pwm", "--format", "json")
    assert run.returncode == 1
    doc = json.loads(run.stdout)
    assert doc["frame"] == {"size": 8, "bits_nominal": 111, "stuff_bits_worst": 24, "bits_worst": 135, "c_us": 270.0}
    assert doc["blocking"] == {"by": None, "us": 0.0}
    hits = {x["name"]: x["hits"] for x in doc["interferers"]}
    assert len(hits) == 16
    assert hits["ecu_current_set"] == hits["motor_phase"] == 3
    assert hits["ecu_speed_set"] == hits["motor_position"] == 2
    assert sum(hits.values()) == 12 + 2 * 2 + 2 * 3
    assert doc["w_us"] == 5940.0 and doc["wcrt_us"] == 6210.0 and doc["slack_us"] == -5210.0
    assert doc["error_term_us"] is None
    assert doc["fix"]["kind"] == "identifier" and doc["fix"]["id"] == 0x0FF and doc["fix"]["wcrt_us"] == 540.0
    text = cli("check", str(WRONG_ORDER), "--explain", "ecu_pwm").stdout
    assert "24 stuff bits" in text and "= 6210 us" in text and "identifier 0x0FF" in text


def test_explain_unknown_message_is_a_usage_error() -> None:
    run = cli("check", str(WRONG_ORDER), "--explain", "ecu_pw")
    assert run.returncode == 2 and "did you mean 'ecu_pwm'" in run.stderr and "Traceback" not in run.stderr


def test_explain_uses_the_release_jitter_check_uses() -> None:
    """arm_canfd's arm_command is sent by the 1 kHz control task as it finishes, so check releases it with that
    task's spread as jitter: WCET 150 - BCET 50 = 100 us. By hand (tests/test_canfd.py): R = 100 + 56.6 (one
    joint state frame blocking) + 169.6 (its own 64-byte frame) = 326.2 us; --explain must say the same."""
    proc = cli("check", str(ROOT / "specs" / "arm_canfd.yaml"), "--explain", "arm_command", "--format", "json")
    doc = json.loads(proc.stdout)
    assert doc["jitter_us"] == 100
    assert doc["wcrt_us"] == 326.2
