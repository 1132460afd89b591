"""An event-driven TPDO written periodically is analysed as periodic only while even a late write comes before its
event timer runs out (CiA 301 7.3.3: the timer is restarted by every send, and a timer send and a late event are
then only an inhibit time apart). Found in review: the rule ignored the message's release jitter."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from conftest import ROOT, bus, check, check_data, message

SEAMS = ROOT / "tests" / "data" / "seams"


def test_a_jittered_write_can_meet_the_timer(tmp_path: Path) -> None:
    """Seam 12's trace: low takes 1,405 us when d1_state goes out twice 1 ms apart (header). Its bound must cover
    that, so the spec is refused for low's 1,300 us deadline."""
    for name in ("12-canopen-event-timer-jitter.yaml", "drive_et.eds"):
        shutil.copy(SEAMS / name, tmp_path / name)
    report = check(tmp_path / "12-canopen-event-timer-jitter.yaml")
    can0 = bus(report, "can0")
    assert message(can0, "d1_state")["interval_us"] == 1_000  # the inhibit time
    assert message(can0, "low")["wcrt_us"] >= 1_405
    assert not report["ok"] and "deadline" in {e["code"] for e in report["errors"]}


def drive_spec(timer: str) -> dict[str, Any]:
    """d1's task runs every 10 ms for 100 us .. 2 ms and writes its TPDO as it ends: the TPDO inherits the task's
    response spread, 2,000 - 100 = 1,900 us, as release jitter (the holistic rule the CAN analysis uses)."""
    return {
        "system": "et_task",
        "buses": [{"name": "can0", "protocol": "canopen", "bitrate": "1 Mbit/s",
                   "canopen": {"sync_period": "100 ms"}}],
        "nodes": [
            {"name": "master", "role": "master", "node_id": 127, "buses": ["can0"],
             "tasks": [{"name": "use", "on_message": "d1_state", "wcet": "50 us"}]},
            {"name": "d1", "node_id": 1, "device": {"eds": "drive_et.eds"}, "buses": ["can0"],
             "tasks": [{"name": "sample", "period": "10 ms", "bcet": "100 us", "wcet": "2 ms"}]},
        ],
        "messages": [
            {"name": "d1_state", "producer": "d1", "consumers": ["master"], "period": "10 ms",
             "pdo": {"tpdo": 1, "transmission": 255, "event_timer": timer, "inhibit": "1 ms",
                     "map": [0x6064, 0x606C]}},
        ],
        "flows": [{"name": "state", "chain": ["d1.sample", "d1_state", "master.use"]}],
    }


def test_a_task_written_tpdo_whose_spread_reaches_the_timer_is_refused(tmp_path: Path) -> None:
    """10 ms + 1,900 us = 11.9 ms: an 11 ms timer can run out before a late write; a 12 ms one cannot."""
    shutil.copy(SEAMS / "drive_et.eds", tmp_path / "drive_et.eds")
    refused = check_data(tmp_path, drive_spec("11 ms"))
    assert [e["code"] for e in refused["errors"]] == ["event-timer"], refused["errors"]
    assert "11.9 ms" in refused["errors"][0]["message"]
    accepted = check_data(tmp_path, drive_spec("12 ms"))
    assert accepted["ok"], accepted["errors"]
    assert message(bus(accepted, "can0"), "d1_state")["interval_us"] == 10_000
