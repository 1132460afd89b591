"""CAN FD end to end: the spec (protocol can-fd, data_bitrate, fd, brs, padding), the analysis with FD frame times,
and the three variants of the 9-joint arm.

Hand figures used below (ISO 11898-1:2015 field counts, worked out in tests/test_frames_canfd.py's docstring):
  an 8-byte FD frame, base format, worst case: 34 bits at the nominal rate + 113 bits at the data rate;
  at 1 Mbit/s / 5 Mbit/s: 34 us + 113 / 5 us = 34 + 22.6 = 56.6 us
  a 64-byte FD frame: 34 nominal + 678 data bits: 34 + 135.6 = 169.6 us
  a classical 8-byte frame (Davis et al. 2007, eq. 1): 55 + 80 = 135 bits, 135 us at 1 Mbit/s
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tests.conftest import ROOT, SPECS, bus, check, check_data, cli, message

EXAMPLES = ROOT / "examples"
FD8_US = 34 + 113 / 5  # 56.6
FD64_US = 34 + 678 / 5  # 169.6
CLASSICAL8_US = 135.0


def fd_spec(messages: list[dict[str, Any]], data_bitrate: str = "5 Mbit/s") -> dict[str, Any]:
    return {
        "system": "fd",
        "buses": [{"name": "can0", "protocol": "can-fd", "bitrate": "1 Mbit/s", "data_bitrate": data_bitrate}],
        "nodes": [{"name": "a", "buses": ["can0"]}, {"name": "b", "buses": ["can0"]}],
        "messages": [
            {"producer": "a", "consumers": ["b"], "period": "1 ms", **m} for m in messages
        ],
    }


def test_arm_variants_loads_and_verdicts() -> None:
    """The issue's figures: 18 classical frames of 135 us per ms = 243 %; 18 FD frames of 56.6 us = 101.88 %;
    one 64-byte FD frame + nine 8-byte ones = 169.6 + 9 * 56.6 = 679.0 us per ms = 67.9 %."""
    classical = check(EXAMPLES / "arm_classical.yaml")
    per_joint = check(EXAMPLES / "arm_canfd_per_joint.yaml")
    shared = check(SPECS / "arm_canfd.yaml")
    assert bus(classical, "arm")["utilization"] == pytest.approx(18 * CLASSICAL8_US / 1000)
    assert bus(per_joint, "arm")["utilization"] == pytest.approx(18 * FD8_US / 1000)
    assert bus(shared, "arm")["utilization"] == pytest.approx((FD64_US + 9 * FD8_US) / 1000)
    assert [classical["ok"], per_joint["ok"], shared["ok"]] == [False, False, True]
    for report in (classical, per_joint):
        assert any(e["code"] == "overload" for e in report["errors"])


def test_arm_canfd_response_times_by_hand() -> None:
    """Davis et al. (2007) RTA with FD frame times, each frame released once per ms, all at once:
    arm_command (highest priority) waits for one lower-priority 8-byte FD frame: 56.6 + 169.6 = 226.2 us;
    joint k's state waits for the command, k - 1 higher states, one lower state, then sends:
    169.6 + (k - 1) * 56.6 + 56.6 + 56.6; joint 9 has nothing below it: 169.6 + 9 * 56.6 = 679.0 us."""
    b = bus(check(SPECS / "arm_canfd.yaml"), "arm")
    assert b["protocol"] == "can-fd" and b["bitrate"] == 1_000_000 and b["data_bitrate"] == 5_000_000
    cmd = message(b, "arm_command")
    assert (cmd["size"], cmd["frame_size"], cmd["fd"], cmd["brs"]) == (56, 64, True, True)
    assert cmd["frame_us_worst"] == pytest.approx(FD64_US)
    assert cmd["frame_bits_worst"] == 34 + 678 and cmd["frame_bits_worst_data_phase"] == 678
    assert cmd["wcrt_us"] == pytest.approx(FD8_US + FD64_US)
    for k in range(1, 9):
        assert message(b, f"joint{k}_state")["wcrt_us"] == pytest.approx(FD64_US + (k + 1) * FD8_US)
    assert message(b, "joint9_state")["wcrt_us"] == pytest.approx(FD64_US + 9 * FD8_US)


def test_padding_warning_names_the_padding(tmp_path: Path) -> None:
    """ISO 11898-1:2015 DLC table: 9..12 bytes go in a 12-byte frame; 56 bytes in a 64-byte one."""
    report = check_data(tmp_path, fd_spec([{"name": "m", "id": 1, "size": 10}]))
    assert report["ok"]
    (w,) = report["warnings"]
    assert w["code"] == "fd-padding" and "12-byte frame with 2 padding bytes" in w["message"]
    lines = (tmp_path / "spec.yaml").read_text(encoding="utf-8").splitlines()
    assert lines[w["line"] - 1].strip() == "size: 10"  # reported at the size key


def test_classical_frame_and_no_brs_on_an_fd_bus(tmp_path: Path) -> None:
    """fd: false -> a classical frame: 135 bits at 1 Mbit/s = 135 us. brs: false -> the whole FD frame at the
    nominal rate: (34 + 113) bits = 147 us. A frame with BRS: 56.6 us. The lowest-priority frame is blocked by
    the longest other one, the classical frame (135 us)."""
    report = check_data(
        tmp_path,
        fd_spec(
            [
                {"name": "classic", "id": 1, "size": 8, "fd": False},
                {"name": "slow", "id": 2, "size": 8, "brs": False},
                {"name": "fast", "id": 3, "size": 8},
            ]
        ),
    )
    b = bus(report, "can0")
    classic, slow, fast = (message(b, n) for n in ("classic", "slow", "fast"))
    assert "fd" not in classic and classic["frame_us_worst"] == CLASSICAL8_US
    assert slow["brs"] is False and slow["frame_us_worst"] == 147.0
    assert fast["frame_us_worst"] == pytest.approx(FD8_US)
    assert classic["wcrt_us"] == 147.0 + CLASSICAL8_US  # blocked by 'slow', the longest lower-priority frame
    assert fast["wcrt_us"] == pytest.approx(CLASSICAL8_US + 147.0 + FD8_US)


def test_data_bitrate_uses_the_unit_grammar(tmp_path: Path) -> None:
    """data_bitrate reads like bitrate (one unit grammar): 8-byte FD frame = 34 us + 113 / 2 us = 90.5 us."""
    for text in ("2 Mbit/s", "2000 kbit/s", "2 Mbps"):
        b = bus(check_data(tmp_path, fd_spec([{"name": "m", "id": 1, "size": 8}], text)), "can0")
        assert b["data_bitrate"] == 2_000_000 and message(b, "m")["frame_us_worst"] == 90.5


def test_check_text_shows_the_data_rate() -> None:
    proc = cli("check", "specs/arm_canfd.yaml")
    assert proc.returncode == 0, proc.stderr
    assert "67.9%" in proc.stdout and "5 Mbit/s" in proc.stdout
