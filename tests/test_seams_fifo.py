"""FIFO transmit queues where they meet release offsets and dropping queues (seams 07 and 11 in tests/data/seams).

Frame times: a classical standard frame with 8 data bytes is 135 bits in the worst case (Davis et al. 2007, eq. 1:
C = (55 + 10 s) tau, inter-frame space included): 135 us at 1 Mbit/s, 270 us at 500 kbit/s. Node clocks are within
the default +-100 ppm, so a distance of d ns of the sender's clock lasts at least d - ceil(d / 10^4) ns in real time
(netcfg.timing.clocks.shortest_real): 1 ms of it at least 999.9 us.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import yaml
from conftest import ROOT, bus, check, check_data, cli, message

SEAMS = ROOT / "tests" / "data" / "seams"
SEAM_07 = SEAMS / "07-fifo-ignores-offsets.yaml"
SEAM_11 = SEAMS / "11-fifo-drop-accepted.yaml"


def _seam(path: Path) -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(path.read_text(encoding="utf-8"))
    return data


def _wcrt(report: dict[str, Any], name: str) -> float | None:
    value: float | None = message(bus(report, "b"), name)["wcrt_us"]
    return value


def _queue(report: dict[str, Any]) -> dict[str, Any]:
    queue: dict[str, Any] = bus(report, "b")["tx_queues"][0]
    return queue


def _two(offsets: tuple[str, str], tolerance_ppm: int | None = None, **first: Any) -> dict[str, Any]:
    """Seam 07 cut to m0 and m1 (8 bytes at 1 Mbit/s, every 10 ms, alone on the bus) at the given offsets; `first`
    adds keys to m0."""
    data = _seam(SEAM_07)
    data["messages"] = data["messages"][:2]
    for msg, offset in zip(data["messages"], offsets):
        msg["offset"] = offset
    data["messages"][0].update(first)
    data["nodes"][0]["tx_queue"]["depth"] = 10
    if tolerance_ppm is not None:
        data["buses"][0]["clock_tolerance"] = tolerance_ppm
    return data


# --- seam 07: offsets on the FIFO node's own clock -----------------------------------------------------------------


def test_seam_07_offsets_keep_the_fifo_frames_apart() -> None:
    """Seam 07's derivation: host releases m_i at i ms of every 10 ms, each 8-byte frame takes 135 us and nothing
    else is on the bus, so each frame is alone in the queue and on the bus: R = C = 135 us (exact) and a backlog of
    1, which the depth of 2 holds. Before the fix: 1,080 us each and the depth refused."""
    report = check(SEAM_07)
    assert report["ok"], report["errors"]
    assert [e["code"] for e in report["errors"]] == [] and report["warnings"] == []
    for i in range(8):
        assert _wcrt(report, f"m{i}") == 135.0  # within 1.5x of the exact 135 us: exactly it
    queue = _queue(report)
    assert queue["backlog_max"] == 1 and queue["queue_us"] == 135.0 and queue["together"] == ["m0"]


def test_seam_07_simulated_within_the_bound() -> None:
    """The simulator (seam 07's header: every message exactly 135.0 us, never more than one frame queued, nothing
    lost) stays within the new bound, and the queue of depth 2 holds."""
    proc = cli("simulate", str(SEAM_07), "--duration", "1s", "--seed", "1", "--format", "json")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    doc = json.loads(proc.stdout)
    for m in doc["messages"]:
        assert m["response_us"]["max"] == 135.0 and m["within_analysis"] is True
    assert doc["lost"] == 0 and doc["tx_queues"][0]["max_backlog"] == 1


def test_a_frame_still_queued_is_ahead(tmp_path: Path) -> None:
    """m0 at 0, m1 at 100 us: m1 is queued while m0 (135 us on the wire) is still being sent, so m0 is with m1:
    m1 = B + C_m0 + C_m1 = 0 + 135 + 135 = 270 us (Davis on the set {m0, m1}); m0 is released 9.9 ms after m1,
    long after m1 is sent (within 270 us), so m0 is alone: 135 us. m0 left its slot when it started, at once
    (R - C = 0), so m1 finds no frame waiting: a backlog of 1, a depth of 1 is enough. Both at 0 ms: each can be
    queued first, both 270 us, and both wait together: a backlog of 2, a depth of 1 that blocks is refused."""
    report = check_data(tmp_path, _two(("0 ms", "100 us")))
    assert (_wcrt(report, "m0"), _wcrt(report, "m1")) == (135.0, 270.0)
    assert _queue(report)["backlog_max"] == 1
    same = _two(("0 ms", "0 ms"))
    same["nodes"][0]["tx_queue"]["depth"] = 1
    refused = check_data(tmp_path, same, "same.yaml")
    assert (_wcrt(refused, "m0"), _wcrt(refused, "m1")) == (270.0, 270.0)
    assert [e["code"] for e in refused["errors"]] == ["tx-queue"] and "up to 2 frames" in refused["errors"][0][
        "message"
    ]


def test_the_queue_bound_widens_the_window(tmp_path: Path) -> None:
    """Frames still in the queue from earlier: m0 at 0 and m1 at 500 us on host; `drive` sends five 8-byte frames
    above both (ids 0x10..0x14, every 5 ms, no offsets). m0 alone: R = C + 5 C = 810 us (each drive frame once:
    ceil((675 + 1) / 5000) = 1), longer than the 500 us to m1's release, so m0 can still be queued when m1 is:
    m1 = C_m0 + C_m1 + 5 C = 945 us (ceil((810 + 1) / 5000) = 1). Counting m0 only when the release gap is within
    m0's frame time (ignoring m0's own queue bound) would give m1 810 us; m0 is released 9.5 ms after m1, which
    is long sent: 810 us."""
    data = _two(("0 ms", "500 us"))
    data["nodes"].append({"name": "drive", "buses": ["b"]})
    data["messages"] += [
        {"name": f"d{i}", "id": 0x10 + i, "producer": "drive", "consumers": ["rx"], "size": 8, "period": "5 ms"}
        for i in range(5)
    ]
    report = check_data(tmp_path, data)
    assert (_wcrt(report, "m0"), _wcrt(report, "m1")) == (810.0, 945.0)


def test_jitter_and_clock_drift_bring_frames_together(tmp_path: Path) -> None:
    """m0 at 0 with a release jitter J = 999.95 us, m1 at 1 ms of host's clock. m0 is queued by 999.95 us and can
    still be queued when m1 is, so m1 = 135 + 135 = 270 us either way. At 100 ppm the 1 ms lasts at least 999.9 us
    real, less than J: m0 can also be queued after m1 and find it there, m0 = J + 270 = 1,269.95 us. Without clock
    drift (clock_tolerance 0) m1 comes 1,000 us after m0's release, after m0 is queued: m0 = J + 135 = 1,134.95."""
    drift = check_data(tmp_path, _two(("0 ms", "1 ms"), jitter="999950 ns"), "drift.yaml")
    assert (_wcrt(drift, "m0"), _wcrt(drift, "m1")) == (1269.95, 270.0)
    exact = check_data(tmp_path, _two(("0 ms", "1 ms"), 0, jitter="999950 ns"), "exact.yaml")
    assert (_wcrt(exact, "m0"), _wcrt(exact, "m1")) == (1134.95, 270.0)


def test_members_without_offsets_fall_back_to_davis(tmp_path: Path) -> None:
    """Davis et al. 2011 where offsets cannot be used. m7 sporadic (min_interarrival 10 ms): it can be queued at
    any time, so it is with every frame and every frame with it: m7 = 8 x 135 = 1,080 us (every member ahead), the
    others 135 + 135 = 270 us (m7 and itself), a backlog of 8. Unrelated periods (m1 every 9,973 us): the
    hyperperiod has 19,946 releases, more than can_offsets.MAX_JOBS, so all eight share Davis's 1,080 us."""
    sporadic = _seam(SEAM_07)
    sporadic["nodes"][0]["tx_queue"]["depth"] = 10
    m7 = sporadic["messages"][7]
    del m7["period"], m7["offset"]
    m7["min_interarrival"] = "10 ms"
    report = check_data(tmp_path, sporadic, "sporadic.yaml")
    assert [_wcrt(report, f"m{i}") for i in range(8)] == [270.0] * 7 + [1080.0]
    assert _queue(report)["backlog_max"] == 8
    unrelated = _seam(SEAM_07)
    unrelated["nodes"][0]["tx_queue"]["depth"] = 10
    unrelated["messages"][1]["period"] = "9973 us"
    report = check_data(tmp_path, unrelated, "unrelated.yaml")
    assert [_wcrt(report, f"m{i}") for i in range(8)] == [1080.0] * 8


# --- seam 11: a FIFO that drops --------------------------------------------------------------------------------------


def test_seam_11_a_dropped_message_is_an_error() -> None:
    """Seam 11: three 8-byte messages (270 us at 500 kbit/s), one period, no offsets, through a FIFO of depth 2
    that drops: all three can be queued at once (backlog 3), and without offsets any of them can be queued last,
    so each can be dropped (the simulator drops m2 every period, seam 11's header). One error, at the queue
    (line 14, column 40 of the seam: host's tx_queue), naming them; no deadline error besides; no bound."""
    report = check(SEAM_11)
    assert not report["ok"]
    assert [(e["code"], e["line"], e["column"]) for e in report["errors"]] == [("tx-queue", 14, 40)]
    text = report["errors"][0]["message"]
    assert "'m0', 'm1', 'm2' can find it full" in text and "may_be_lost: true" in text
    for name in ("m0", "m1", "m2"):
        row = message(bus(report, "b"), name)
        assert row["wcrt_us"] is None and row["unbounded"] == "dropped"
    proc = cli("check", str(SEAM_11))
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert "11-fifo-drop-accepted.yaml:14:40: error:" in proc.stdout + proc.stderr


def test_messages_that_may_be_lost_have_no_bound_and_no_error(tmp_path: Path) -> None:
    """may_be_lost on all three: no error, no warning, no bound (unbounded: dropped) and no verdict, in check and
    in --explain. On m2 alone: m0 and m1 can still be dropped, the error names those two."""
    data = _seam(SEAM_11)
    for msg in data["messages"]:
        msg["may_be_lost"] = True
    report = check_data(tmp_path, data)
    assert report["ok"] and report["errors"] == [] and report["warnings"] == []
    for name in ("m0", "m1", "m2"):
        row = message(bus(report, "b"), name)
        assert (row["wcrt_us"], row["unbounded"], row["schedulable"]) == (None, "dropped", None)
    explained = cli("check", str(tmp_path / "spec.yaml"), "--explain", "m2")
    assert explained.returncode == 0 and "be dropped: no bound" in explained.stdout  # no verdict to miss
    assert cli("check", str(SEAM_11), "--explain", "m2").returncode == 1  # the seam's m2 is promised delivery
    some = _seam(SEAM_11)
    some["messages"][2]["may_be_lost"] = True
    report = check_data(tmp_path, some, "some.yaml")
    assert [e["code"] for e in report["errors"]] == ["tx-queue"]
    assert "'m0', 'm1' can find it full" in report["errors"][0]["message"]


def test_offsets_say_which_message_is_queued_last(tmp_path: Path) -> None:
    """Seam 11 with offsets 0, 1 and 2 us and a depth of 1. A frame leaves the queue when its transmission starts
    (as the simulator counts it): m0 is queued into an empty queue (the last period's frames left it within their
    bounds, far less than 10 ms before) and starts at once (B = 0: R - C = 0); m1 finds nothing waiting, it waits
    up to R - C = 270 us behind m0; m2 finds m1 waiting: only m2 finds the depth-1 queue full, and the simulator
    drops it every period (100 in 1 s). m2 may be lost: accepted, m0 = 270 us (alone), m1 = 270 + 270 = 540 us,
    m2 no bound. With the seam's depth of 2 none is dropped (the simulator holds at most 2 frames): 810 us."""
    data = _seam(SEAM_11)
    for i, msg in enumerate(data["messages"]):
        msg["offset"] = f"{i} us"
    deep = check_data(tmp_path, data, "deep.yaml")
    assert deep["ok"] and deep["warnings"] == [] and _wcrt(deep, "m2") == 810.0
    data["nodes"][0]["tx_queue"]["depth"] = 1
    report = check_data(tmp_path, data)
    assert [e["code"] for e in report["errors"]] == ["tx-queue"]
    assert "'m2' can find it full" in report["errors"][0]["message"]
    allowed = copy.deepcopy(data)
    allowed["messages"][2]["may_be_lost"] = True
    report = check_data(tmp_path, allowed, "allowed.yaml")
    assert report["ok"] and report["warnings"] == []
    assert (_wcrt(report, "m0"), _wcrt(report, "m1"), _wcrt(report, "m2")) == (270.0, 540.0, None)
    assert _queue(report)["dropped"] == ["m2"]
    proc = cli(
        "simulate", str(tmp_path / "spec.yaml"), "--duration", "1s", "--seed", "0", "--format", "json", "--force"
    )
    doc = json.loads(proc.stdout)
    lost = {m["name"]: m["lost"] for m in doc["messages"]}
    assert lost["m0"] == lost["m1"] == 0 and lost["m2"] == 100


def test_may_be_lost_is_a_can_setting(tmp_path: Path) -> None:
    """On an Ethernet message the key has no meaning: an error at the key."""
    data = {
        "system": "udp",
        "buses": [{"name": "eth", "protocol": "ethernet-udp", "bitrate": "100 Mbit/s"}],
        "nodes": [{"name": "a", "buses": ["eth"]}, {"name": "b", "buses": ["eth"]}],
        "messages": [
            {
                "name": "x",
                "id": 1,
                "producer": "a",
                "consumers": ["b"],
                "size": 8,
                "period": "1 ms",
                "may_be_lost": True,
            }
        ],
    }
    report = check_data(tmp_path, data)
    assert [e["code"] for e in report["errors"]] == ["wrong-section"]
