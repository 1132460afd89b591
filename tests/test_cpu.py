"""Task response times on one processor (netcfg.timing.cpu) against textbook task sets."""

from __future__ import annotations

from pathlib import Path

from conftest import check_data

from netcfg.timing.cpu import CpuTask, analyse

MS = 1_000_000


def test_preemptive_rate_monotonic_textbook_set() -> None:
    """Buttazzo, Hard Real-Time Computing Systems (3rd ed.), the classic RTA example (C, T) = (1, 4), (2, 6),
    (3, 10) in ms, rate-monotonic: R1 = 1; R2 = 2 + ceil(3/4) = 3; R3: 3 + 1 + 2 = 6 -> 3 + 2x1 + 1x2 = 7 ->
    3 + 2x1 + 2x2 = 9 -> 3 + 3x1 + 2x2 = 10 -> 10 (fixed point, = its period)."""
    tasks = [CpuTask("t3", 3 * MS, 10 * MS), CpuTask("t1", 1 * MS, 4 * MS), CpuTask("t2", 2 * MS, 6 * MS)]
    assert analyse(tasks) == {"t1": 1 * MS, "t2": 3 * MS, "t3": 10 * MS}


def test_non_preemptive_adds_lower_priority_blocking() -> None:
    """Same set, non-preemptive (1 ns quantum): t1 can be blocked by t3's 3 ms: R1 = 3 + 1 = 4 ms, as long as its
    period. t3 (lowest) waits for t1 and t2 released with it: w = ceil((w + 1 ns)/4) x 1 + ceil((w + 1 ns)/6) x 2
    = 3 ms, R3 = 3 + 3 = 6 ms."""
    tasks = [CpuTask("t1", 1 * MS, 4 * MS), CpuTask("t2", 2 * MS, 6 * MS), CpuTask("t3", 3 * MS, 10 * MS)]
    r = analyse(tasks, "non-preemptive")
    assert r["t1"] == 4 * MS and r["t3"] == 6 * MS


def test_given_priorities_override_rate_monotonic(tmp_path: Path) -> None:
    """A spec priority 0 on the slow 3 ms task puts it first: the 1 ms task every 4 ms then waits 3 ms: R = 4 ms."""
    spec = {
        "system": "cpu",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": "500 kbit/s"}],
        "nodes": [
            {
                "name": "ecu",
                "buses": ["can0"],
                "tasks": [
                    {"name": "fast", "period": "4 ms", "wcet": "1 ms"},
                    {"name": "slow", "period": "10 ms", "wcet": "3 ms", "priority": 0},
                ],
            },
            {"name": "b", "buses": ["can0"]},
        ],
        "messages": [{"name": "m", "id": 1, "producer": "ecu", "consumers": ["b"], "size": 1, "period": "10 ms"}],
    }
    node = check_data(tmp_path, spec)["nodes"][0]
    assert [(t["name"], t["wcrt_us"]) for t in node["tasks"]] == [("slow", 3000), ("fast", 4000)]


def test_exactly_full_processor_with_jitter_has_no_bound(tmp_path: Path) -> None:
    """ecu runs 5 ms every 10 ms and 5 ms on each arrival of a 10 ms message: exactly 100 %, not over. The
    message arrives with jitter J > 0 (its response varies), so the level-i demand 5 ceil((t + J)/10) +
    5 ceil(t/10) ms exceeds t for every t: the second task has no bounded response, said at its position."""
    spec = {
        "system": "cpu",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": "500 kbit/s"}],
        "nodes": [
            {
                "name": "ecu",
                "buses": ["can0"],
                "tasks": [
                    {"name": "ctrl", "period": "10 ms", "wcet": "5 ms"},
                    {"name": "rx", "on_message": "m", "wcet": "5 ms"},
                ],
            },
            {"name": "b", "buses": ["can0"]},
            {"name": "c", "buses": ["can0"]},
        ],
        "messages": [
            {"name": "m", "id": 2, "producer": "b", "consumers": ["ecu"], "size": 8, "period": "10 ms"},
            {"name": "n", "id": 1, "producer": "c", "consumers": ["b"], "size": 8, "period": "10 ms"},
        ],
    }
    report = check_data(tmp_path, spec)
    assert [e["code"] for e in report["errors"]] == ["task-unbounded"]
    assert "ecu.rx" in report["errors"][0]["message"]
    assert [t["wcrt_us"] for t in report["nodes"][0]["tasks"]] == [5000, None]


def test_a_message_sent_by_a_task_inherits_its_response_variation(tmp_path: Path) -> None:
    """n0.send (every 1 ms, 100..300 us, alone on its processor: R = 300 us) queues 'a' as it finishes, so 'a' is
    released up to 300 - 100 = 200 us late. At 500 kbit/s an 8-byte frame takes 135 bits = 270 us (worst case):
    R_a = J + B + C = 200 + 270 ('b' blocking) + 270 = 740 us (540 us without the jitter). The flow n0.send -> a ->
    n1.use (started by 'a') takes at most 300 (send) + 540 (a, from its actual queueing) = 840 us."""
    spec = {
        "system": "holistic",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": "500 kbit/s"}],
        "nodes": [
            {
                "name": "n0",
                "buses": ["can0"],
                "tasks": [{"name": "send", "period": "1 ms", "wcet": "300 us", "bcet": "100 us"}],
            },
            {
                "name": "n1",
                "buses": ["can0"],
                "tasks": [{"name": "use", "on_message": "a", "wcet": "10 us"}],
            },
            {"name": "n2", "buses": ["can0"]},
        ],
        "messages": [
            {"name": "a", "id": 0x10, "producer": "n0", "consumers": ["n1"], "size": 8, "period": "1 ms"},
            {"name": "b", "id": 0x20, "producer": "n2", "consumers": ["n1"], "size": 8, "period": "1 ms"},
        ],
        "flows": [{"name": "f", "chain": ["n0.send", "a", "n1.use"]}],
    }
    report = check_data(tmp_path, spec)
    a = next(m for m in report["buses"][0]["messages"] if m["name"] == "a")
    assert a["wcrt_us"] == 740
    assert report["flows"][0]["latency_max_us"] == 840
