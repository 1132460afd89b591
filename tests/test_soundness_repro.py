"""Minimal reproductions of unsound or hanging analyses, each held to the correct answer.

The specs in tests/data/soundness keep their headers: the command, what the analysis used to print, and the
correct figure with its derivation. Every figure asserted here is derived in that header or in the docstring.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import soundness  # the sweep's own runs, as tests/test_soundness.py uses them
import yaml
from conftest import bus, check, check_data, cli, cli_json, load_spec, message, runtime_config

from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import summary
from netcfg.sim.scenario import SimOptions

DATA = Path(__file__).parent / "data" / "soundness"


def spec(name: str) -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(next(DATA.glob(f"{name}-*.yaml")).read_text(encoding="utf-8"))
    return data


def codes(report: dict[str, Any]) -> list[str]:
    return [e["code"] for e in report["errors"]]


def test_01_exactly_full_bus_with_a_blocker_is_unbounded_at_once() -> None:
    """Ten frames of 135 us every 1350 us load the bus exactly 100 %; the 65 us blocker means the level-m9 busy
    period t = 65 + sum ceil(t / 1350) * 135 never ends, so m9 has no bound (it used to loop forever)."""
    report = check(next(DATA.glob("01-*.yaml")))
    m9 = message(bus(report, "can0"), "m9")
    assert m9["wcrt_us"] is None and m9["schedulable"] is False
    assert not report["ok"] and "deadline" in codes(report)
    assert "reaches 100%" in report["errors"][0]["message"]
    # m8 sees nine frames and m9's blocking: 135 (B) + 9 x 135 = 1350 us, within its 1350 us period
    assert message(bus(report, "can0"), "m8")["wcrt_us"] == 1350


def test_02_load_a_hair_under_one_says_the_step_limit_was_reached(tmp_path: Path) -> None:
    """U = 1080000 / 1080001 < 1 with exact clocks (clock_tolerance 0, as the repro means it): the busy period
    spans about 1e6 instances. The analysis gives up after its stated number of steps and says so, instead of
    claiming the load reaches 100 %. With the default 100 ppm the fastest clocks ask for U / (1 - 1e-4) > 1 of
    the bus: then the load, not the step limit, is the verdict."""
    data = spec("02")
    data["buses"][0]["clock_tolerance"] = 0
    report = check_data(tmp_path, data)
    fast = message(bus(report, "can0"), "fast")
    assert fast["wcrt_us"] is None and fast.get("unbounded") == "iterations"
    text = report["errors"][0]["message"]
    assert "steps of the analysis" in text and "reaches 100%" not in text
    drifting = check(next(DATA.glob("02-*.yaml")))
    assert "reaches 100%" in drifting["errors"][0]["message"]


def test_11_full_load_has_one_verdict_in_any_order(tmp_path: Path) -> None:
    """U = 0.20 + 0.36 + 0.34 + 0.10 = 1 exactly: not over capacity whatever the list order, with exact clocks
    (clock_tolerance 0, as the repro means it). u10 (lowest priority, no blocking, tau = 1 us):
    w = ceil(676/250)*85 + ceil(676/375)*135 + ceil(676/375)*75 = 255 + 270 + 150 = 675 us, R = 675 + 75 = 750 us
    <= its 750 us period. (With the default 100 ppm the fastest clocks overload it: test_clocks.py.)"""
    data = spec("11")
    data["buses"][0]["clock_tolerance"] = 0
    reports = [check_data(tmp_path, data, "a.yaml")]
    data["messages"] = data["messages"][2:] + data["messages"][:2]
    reports.append(check_data(tmp_path, data, "b.yaml"))
    for report in reports:
        assert report["ok"], report["errors"]
        assert message(bus(report, "can0"), "u10")["wcrt_us"] == 750
        assert bus(report, "can0")["utilization"] == 1.0


def test_03_async_message_counts_its_own_load() -> None:
    """Each 5 ms EC leaves 5000 - 420 (TM) - 6 x 540 (sync) = 1340 us of asynchronous window, 800 us once the
    inserted idle time of one 540 us frame is taken off: 0.16 of the bus. 'as' alone needs 540 / 1800 = 0.30:
    unbounded. With the TM the bus carries 6 x 540 / 5000 + 540 / 1800 + 420 / 5000 = 1.032: refused."""
    report = check(next(DATA.glob("03-*.yaml")))
    assert message(bus(report, "bus"), "as")["wcrt_us"] is None
    assert bus(report, "bus")["utilization_with_tm"] == 1.032
    assert sorted(codes(report)) == ["deadline", "overload"]


def test_04_async_windows_at_the_fastest_admissible_periods() -> None:
    """At 1 EC (inside [1 EC, 2 EC]) s1-s6 fill every EC, leaving 800 us of usable asynchronous window: lo's
    demand 3 x 540 = 1620 us needs 3 windows, 15000 + 420 + 20 - 1220 = 14220 us > its 10 ms deadline."""
    report = check(next(DATA.glob("04-*.yaml")))
    lo = message(bus(report, "bus"), "lo")
    assert lo["wcrt_us"] == 14220 and lo["schedulable"] is False


def test_05_lsw_checked_at_every_period_inside_the_range() -> None:
    """ma at 3 EC (inside [2 EC, 4 EC]) is due in EC 3 with mb: 540 + 540 = 1080 us > LSW 1000 us."""
    report = check(next(DATA.glob("05-*.yaml")))
    assert codes(report) == ["lsw"]
    assert "EC 3" in report["errors"][0]["message"] and "1080 us" in report["errors"][0]["message"]


def test_07_unsynchronised_refresh_is_the_slowest_period() -> None:
    """t_pack and enc may run at 4 EC (nominal and slowest of [1 EC, 4 EC]): the data reaching c.use is renewed
    every 20 ms, so it may be 100 (pack) + 340 (enc's frame) + 20000 = 20440 us old; without the range the same.
    On a node clock 100 ppm slow (the analysis' clock tolerance) those 20 ms last 2 us more: 20442 us."""
    flow = check(next(DATA.glob("07-*.yaml")))["flows"][0]
    assert flow["unsynchronised"]["latency_max_us"] == 20442


def test_08_node_over_its_processor_is_an_error_and_its_flow_unbounded() -> None:
    """ecu runs two tasks of 7 ms every 10 ms: 14 / 10 = 140 % of its processor."""
    report = check(next(DATA.glob("08-*.yaml")))
    assert codes(report) == ["cpu-overload"] and "140.0%" in report["errors"][0]["message"]
    assert report["flows"][0]["latency_max_us"] is None
    ecu = next(n for n in report["nodes"] if n["name"] == "ecu")
    assert ecu["utilization"] == 1.4 and [t["wcrt_us"] for t in ecu["tasks"]] == [7000, None]


def test_10_a_slow_message_does_not_silence_its_node(tmp_path: Path) -> None:
    """'fast' (10 ms) of a node that also sends an hourly message: about 10 s / 10 ms = 1000 frames in 10 s
    (one fewer when the clock's phase falls late in the first period)."""
    code, doc = cli_json("simulate", str(next(DATA.glob("10-*.yaml"))), "--duration", "10s", "--seed", "0")
    fast = next(m for m in doc["messages"] if m["name"] == "fast")
    assert code == 0 and 999 <= fast["count"] <= 1000


def test_simulate_exits_1_with_one_line_per_measured_range_outside_the_analysis(tmp_path: Path) -> None:
    """A runtime configuration whose analysed bound is below what the bus can do: 'fast' is an 8-byte frame of
    at least 111 bits (270 us worst) at 500 kbit/s, so a stated wcrt of 100 us must be exceeded by every frame."""
    assert cli("build", str(next(DATA.glob("10-*.yaml"))), "-o", str(tmp_path / "out")).returncode == 0
    runtime = tmp_path / "out" / "runtime.json"
    doc = json.loads(runtime.read_text(encoding="utf-8"))
    next(m for m in doc["messages"] if m["name"] == "fast")["wcrt_ns"] = 100_000
    runtime.write_text(json.dumps(doc), encoding="utf-8")
    proc = cli("simulate", str(runtime), "--duration", "1s", "--format", "json")
    out = json.loads(proc.stdout)
    assert proc.returncode == 1 and out["exceeds_analysis"] == ["fast"]
    assert next(m for m in out["messages"] if m["name"] == "fast")["within_analysis"] is False
    assert proc.stderr.splitlines() == [out["violations"][0].join(("netcfg: outside the analysis: ", ""))]


def test_06_ethernet_jitter_propagates_across_switches() -> None:
    """x_a (6.72 us every 33.6 us) shares swa -> sw with b_a1 and b_a2 (123.04 us each, released together but
    serialised by ba's own link, so the second arrives 123.04 us after the first). A frame arriving at a of a busy
    period waits for what arrived in [0, a]: 6.72 x (floor(a / 33.6) + 1) + min(246.08, a + 123.04) - a, largest
    (149.92 us) for a in [100.8, 123.04], so x_a may wait 149.92 - 6.72 = 143.2 us there: its jitter on sw -> r.
    x_a and x_b each bring at most min(6.72 x (floor((a + 143.2) / 33.6) + 1), a + 6.72) (one link each), v one
    frame: 2 x min(...) + 6.72 - a peaks at a = 33.6 with 2 x 40.32 + 6.72 - 33.6 = 53.76 us. So v waits at most
    53.76 - 6.72 = 47.04 us and takes 2 x 6.72 + 47.04 = 60.48 us; x_a 3 x 6.72 + 143.2 + 47.04 = 210.4 us.
    Without the upstream jitter v would be 2 x 6.72 + 13.44 = 26.88 us, below the 32.6 us the simulator measures."""
    lan = bus(check(next(DATA.glob("06-*.yaml"))), "lan")
    assert message(lan, "v")["wcrt_us"] == 60.48
    x_a = message(lan, "x_a")
    assert x_a["wcrt_us"] == 210.4 and x_a["delay_us"]["switch"] == 190.24  # 143.2 + 47.04


MULTI_RATE = {
    "system": "multi_rate",
    "buses": [{"name": "can0", "protocol": "can", "bitrate": "500 kbit/s"}],
    "nodes": [
        {"name": "s", "buses": ["can0"]},
        {"name": "c", "buses": ["can0"], "tasks": [{"name": "t", "period": "10 ms", "wcet": "1 ms", "bcet": "500 us"}]},
        {"name": "d", "buses": ["can0"], "tasks": [{"name": "use", "period": "100 ms", "wcet": "1 ms"}]},
    ],
    "messages": [
        {"name": "slow", "id": 0x10, "producer": "s", "consumers": ["c"], "size": 8, "period": "20 ms"},
        {"name": "fast", "id": 0x11, "producer": "s", "consumers": ["c"], "size": 8, "period": "10 ms"},
        {"name": "out", "id": 0x20, "producer": "c", "consumers": ["d"], "size": 8, "period": "20 ms"},
    ],
    "flows": [{"name": "f", "chain": [["slow", "fast"], "c.t", "out", "d.use"]}],
}


def test_a_stamp_renews_no_faster_than_the_slowest_step_before_it(tmp_path: Path) -> None:
    """large_plant's axis_feedback ran outside its bound: a 10 ms task passes on data whose oldest part (a 20 ms
    message in a parallel step) is renewed only every 20 ms, so a later 20 ms sampler may first see a stamp up to
    20 ms after it appeared, not 10. By hand (500 kbit/s, 8-byte frames 135 bits = 270 us, Davis 2007 eq. 1):
    slow 270 + 270 = 540 us, fast 270 + 270 + 270 = 810 us, out 270 + 270 + 270 = 810 us; step 0 delivered by
    810 us; c.t waits up to 10,000 us + 1 us (100 ppm) and runs 1,000 us: 11,811; out waits 20,000 + 2 and takes
    810: 32,623; d.use waits min(100 ms, 20 ms) + 2 us: starts by 52,625 us. Before the fix the two 20 ms waits
    were taken as 10 ms (32,623 us in all)."""
    report = check_data(tmp_path, MULTI_RATE)
    assert report["ok"], report["errors"]
    assert [message(bus(report, "can0"), n)["wcrt_us"] for n in ("slow", "fast", "out")] == [540, 810, 810]
    flow = report["flows"][0]
    assert flow["latency_max_us"] == 52_625
    rc, sim = cli_json("simulate", str(tmp_path / "spec.yaml"), "--duration", "3s", "--runs", "3")
    assert rc == 0, sim.get("violations")
    measured = next(f for f in sim["flows"] if f["name"] == "f")
    assert measured["within_analysis"] is True, measured


RX_CAN = """\
system: rx_can
buses: [{name: can0, protocol: can, bitrate: 500 kbit/s}]
nodes:
  - {name: a, buses: [can0], tasks: [{name: send, period: 10 ms, wcet: 100 us, bcet: 50 us}]}
  - {name: b, buses: [can0], rx_delay: RX, tasks: [{name: use, on_message: m, wcet: 50 us, bcet: 20 us}]}
messages:
  - {name: m, id: 0x100, producer: a, consumers: [b], size: 8, period: 10 ms}
flows:
  - {name: f, chain: [a.send, m, b.use]}
"""

RX_FTT = """\
system: rx_ftt
buses: [{name: bus, protocol: ftt-can, bitrate: 1 Mbit/s, ftt: {ec: 2 ms, tm_size: 2, windows: sync-first}}]
nodes:
  - {name: master, role: master, buses: [bus]}
  - {name: a, buses: [bus], tasks: [{name: send, wcet: 50 us, bcet: 20 us}]}
  - {name: b, buses: [bus], rx_delay: RX, tasks: [{name: use, wcet: 40 us, bcet: 10 us}]}
messages:
  - {name: m, ftt_id: 1, producer: a, consumers: [b], size: 2, period: 2 EC, offset: 0 EC}
triggers:
  - {name: t_send, ftt_id: 5, bus: bus, period: 2 EC, offset: 0 EC, tasks: [a.send]}
  - {name: t_use, ftt_id: 6, bus: bus, period: 2 EC, offset: 1 EC, tasks: [b.use]}
flows:
  - {name: f, chain: [a.send, m, b.use]}
"""


def _allex2_rx(rx: str) -> str:
    doc = load_spec("allex2.yaml")
    next(n for n in doc["nodes"] if n["name"] == "hip_l")["rx_delay"] = rx
    return yaml.safe_dump(doc, sort_keys=False)


@pytest.mark.parametrize(
    ("text", "flow"),
    [
        (RX_CAN.replace, "f"),  # plain CAN: b.use, the last step, starts rx_delay after m's reception
        (RX_FTT.replace, "f"),  # FTT-CAN: b.use, triggered, rx_delay after its TM's reception
        (lambda _old, rx: _allex2_rx(rx), "joint_command"),  # CANopen: hip_l.apply, rx_delay after the SYNC's
    ],
    ids=["can", "ftt-can", "canopen"],
)
def test_a_task_a_can_frame_starts_runs_its_node_rx_delay_later(tmp_path: Path, text: Any, flow: str) -> None:
    """The simulator starts a task its node's rx_delay (300 us here) after the CAN frame that starts it (its
    message, its trigger message, its SYNC); the flow analysis started it at the frame's end, so a consumer with an
    rx_delay ran past its flow's bound. Here only the flow's last task moves, so its latency range moves by exactly
    rx_delay (in FTT-CAN the frame it reads is in an earlier EC, so it still makes the same activation)."""
    ranges, rx_us = [], 300
    for rx in ("0 us", f"{rx_us} us"):
        (tmp_path / rx).mkdir()
        report = check_data(tmp_path / rx, yaml.safe_load(text("RX", rx)))
        assert report["ok"], report["errors"]
        ranges.append(next((f["latency_min_us"], f["latency_max_us"]) for f in report["flows"] if f["name"] == flow))
    (lo0, hi0), (lo1, hi1) = ranges
    assert (lo1, hi1) == (pytest.approx(lo0 + rx_us), pytest.approx(hi0 + rx_us))
    rc, sim = cli_json("simulate", str(tmp_path / f"{rx_us} us" / "spec.yaml"), "--duration", "2s", "--runs", "2")
    assert rc == 0, sim.get("violations")


TRIGGERED_TO_ASYNC = {
    "system": "triggered_to_async",
    "buses": [
        {"name": "bus", "protocol": "ftt-can", "bitrate": "1 Mbit/s", "ftt": {"ec": "3 ms", "tm_size": 3},
         "errors": {"burst": 2, "interval": "40 ms"}},
    ],
    "nodes": [
        {"name": "master", "role": "master", "buses": ["bus"]},
        {"name": "a", "buses": ["bus"], "tasks": [{"name": "send", "wcet": "187 us", "bcet": "93 us"}]},
        {"name": "b", "buses": ["bus"], "tasks": [
            {"name": "use", "on_message": "m", "wcet": "228 us", "bcet": "5 us"},
        ]},
    ],
    "messages": [
        {"name": "m", "id": 0x301, "window": "async", "producer": "a", "consumers": ["b"], "size": 4,
         "period": "PERIOD"},
    ],
    "triggers": [{"name": "t_send", "ftt_id": 1, "bus": "bus", "period": "2 EC", "tasks": ["a.send"]}],
    "flows": [{"name": "f", "chain": ["a.send", "m", "b.use"]}],
}


@pytest.mark.parametrize("period", ["6 ms", "10 ms"])
def test_a_flow_from_a_triggered_task_through_an_asynchronous_message(tmp_path: Path, period: str) -> None:
    """a.send, triggered every 2 EC (6 ms), -> m, asynchronous -> b.use, started by m; the bus has an error model,
    so a trigger message may end up to 348 us late, resent: (burst 2 + 1) errors x (31-bit error frame + 85-bit
    TM of 3 bytes) at 1 Mbit/s. The chain alone takes 172 us: a.send's bcet 93 + m's unstuffed frame (11-bit
    identifier, 4 bytes: 79 bits). Sent at a.send's rate (6 ms), m goes as a.send ends: every step follows its
    predecessor, the end moves with the start, and the lower bound is the chain's 172 us (the analysis had taken
    the TM's lateness off it: 172 - 348 us, below zero, and runtime.json then failed to load). At its own rate
    (10 ms), m is free-running and keeps its own time, so a late start makes the flow shorter: the analysis takes
    the 348 us off and stops at zero (sound, though no run goes below the chain's 172 us). The data may wait up
    to one of m's periods for its next frame, which the analysis of synchronised flows left out (measured up to
    4.4 ms against a bound of 1.2 ms)."""
    spec = json.loads(json.dumps(TRIGGERED_TO_ASYNC).replace("PERIOD", period))
    report = check_data(tmp_path, spec)
    assert report["ok"], report["errors"]
    lo, hi = report["flows"][0]["latency_min_us"], report["flows"][0]["latency_max_us"]
    if period == "6 ms":
        assert lo == 93 + 79
    else:
        assert lo == 0
        assert hi >= 10_000  # one period of m at least
    rc, sim = cli_json("simulate", str(tmp_path / "spec.yaml"), "--duration", "3s", "--runs", "2")
    assert rc == 0, sim.get("violations")


JOINED = {
    "system": "joined",
    "buses": [{"name": "bus", "protocol": "ftt-can", "bitrate": "250 kbit/s",
               "ftt": {"ec": "3 ms", "tm_size": 4, "windows": "sync-first"}}],
    "nodes": [
        {"name": "master", "role": "master", "buses": ["bus"]},
        {"name": "a", "buses": ["bus"]},
        {"name": "b", "buses": ["bus"], "tasks": [
            {"name": "join", "on_message": "m0", "wcet": "174 us", "bcet": "4 us"},
        ]},
    ],
    "messages": [
        {"name": "m0", "ftt_id": 1, "producer": "a", "consumers": ["b"], "size": 1, "period": "1 EC", "offset": "0 EC"},
        {"name": "m3", "ftt_id": 4, "producer": "a", "consumers": ["b"], "size": 4, "period": "2 EC", "offset": "0 EC"},
    ],
    "flows": [{"name": "fj", "chain": [["m0", "m3"], "b.join"]}],
}


@pytest.mark.parametrize("variant", ["after-its-frame", "rx-delay", "late-trigger-message"])
def test_a_task_joining_two_synchronous_messages(tmp_path: Path, variant: str) -> None:
    """b.join, started by m0 (every EC), reads m0 and m3 (every other EC, or every fourth), sent in one window
    (m0 first: identifier order), and takes the older of their data. Each was found outside its bound by the
    wider random FTT-CAN specs (`benchmarks/soundness.py --protocol ftt-can-wide`):
    - started by m0, b.join starts before that window's m3 is in, so the data of an m3 frame is first used an EC
      later: the analysis started the task once the whole step was in (measured above the bound);
    - with a 503 us rx_delay, m3 is in before b.join starts, so it is used at once (measured below the bound);
    - with a bit-error model the trigger message may be resent, and with the synchronous window right after it
      both frames are queued that much later, which shortens the data's age (measured below the bound).
    The analysis now takes each item of a first step as the start in turn (the one whose data is the oldest
    used), starts a task started by one item at that item's first frame once the others' are in (later in the
    window or by time), and takes a late trigger message off the lower bound of flows starting with a
    synchronous message when the window follows the TM."""
    spec = json.loads(json.dumps(JOINED))
    if variant == "rx-delay":
        spec["nodes"][2]["rx_delay"] = "503 us"
    if variant == "late-trigger-message":
        spec["buses"][0]["errors"] = {"burst": 1, "interval": "35 ms"}
        spec["messages"][1] |= {"period": "4 EC", "offset": "3 EC"}
    report = check_data(tmp_path, spec)
    assert report["ok"], report["errors"]
    assert report["flows"][0]["mode"] == "synchronised"
    rc, sim = cli_json("simulate", str(tmp_path / "spec.yaml"), "--duration", "3s", "--runs", "2")
    assert rc == 0, sim.get("violations")


JOIN_OF_TWO_PRODUCERS = """\
system: join_of_two_producers
buses: [{name: can0, protocol: can, bitrate: 500 kbit/s}]
nodes:
  - {name: p, buses: [can0]}
  - {name: q, buses: [can0]}
  - {name: r, buses: [can0], tasks: [{name: t, period: 10 ms, wcet: 1 ms, bcet: 500 us}]}
messages:
  - {name: ma, id: 0x10, producer: p, consumers: [r], size: 8, period: 20 ms}
  - {name: mb, id: 0x11, producer: q, consumers: [r], size: 8, period: 20 ms, offset: 19 ms}
flows:
  - {name: f, chain: [[ma, mb], r.t]}
"""


def _critical_instant(spec_path: Path, duration_ns: int, **options: Any) -> dict[str, Any]:
    """One run with every clock at 0 and no drift, so that the offsets are as written (options: SimOptions')."""
    cfg = runtime_config(spec_path)
    opts = SimOptions(duration_ns=duration_ns, random_phase=False, drift_ppm=0.0, **options)
    result: dict[str, Any] = summary(run_once(cfg, opts)[1])
    return result


def test_a_join_waits_for_its_other_streams_newer_data(tmp_path: Path) -> None:
    """r.t takes the older of ma's and mb's data, which two nodes send every 20 ms. Data of ma released at 0 is the
    older one used only once mb's next frame, released 19 ms later, is in; r.t, every 10 ms, then reads it at 20 ms,
    before ma's next frame is in: 20,000 us of age. Found by `benchmarks/soundness.py --protocol ftt-can-wide`
    (joins of messages from different producers); the analysis gave 540 + 10,001 = 10,541 us, as if r.t waited only
    for its own period. By hand (500 kbit/s, 8-byte frames 135 bits = 270 us, Davis 2007): ma 270 + 270 (mb's
    blocking) = 540 us, mb 270 + 270 (ma) = 540 us; the step is in by 540 us. The oldest data r.t takes waits for
    the other message's next frame, up to its whole period at the slowest clock (20,000 + 2 us at 100 ppm), and
    r.t's own period after that; but never longer than the older message's own renewal, 20,002 us (r.t would read
    its newer data instead): 540 + min(20,002 + 10,001, 20,002) = 20,542 us."""
    (tmp_path / "spec.yaml").write_text(JOIN_OF_TWO_PRODUCERS, encoding="utf-8")
    report = check(tmp_path / "spec.yaml")
    assert [message(bus(report, "can0"), n)["wcrt_us"] for n in ("ma", "mb")] == [540, 540]
    assert report["flows"][0]["latency_max_us"] == 20_542
    flow = next(f for f in _critical_instant(tmp_path / "spec.yaml", 2_000_000_000)["flows"] if f["name"] == "f")
    assert flow["latency_us"]["max"] == pytest.approx(20_000, abs=1), flow  # above the old 10,541
    assert flow["within_analysis"] is True
    rc, sim = cli_json("simulate", str(tmp_path / "spec.yaml"), "--duration", "3s", "--runs", "3")
    assert rc == 0, sim.get("violations")


def test_one_producers_messages_keep_their_distance_in_a_join(tmp_path: Path) -> None:
    """The same join, both messages sent by one node on its one clock: mb always comes 19 ms after ma, and ma 1 ms
    after mb, so r.t's oldest data waits at most 19,001.9 us (19 ms at 100 ppm) for the other's, and never more
    than one renewal: 540 + min(19,001.9 + 10,001, 20,002) = 20,542 us; with mb 1 ms after ma instead,
    540 + max(min(1,000.1 + 10,001, 20,002), min(19,001.9 + 10,001, 20,002)) is the same 20,542 us. With both at one
    offset, neither waits for the other: 540 + 10,001 = 10,541 us, as for one message."""
    data = yaml.safe_load(JOIN_OF_TWO_PRODUCERS)
    data["messages"][1]["producer"] = "p"
    bounds = []
    for offset in ("19 ms", "1 ms", "0 ms"):
        data["messages"][1]["offset"] = offset
        (tmp_path / offset).mkdir()
        bounds.append(check_data(tmp_path / offset, data)["flows"][0]["latency_max_us"])
    assert bounds == [20_542, 20_542, 10_541]
    rc, sim = cli_json("simulate", str(tmp_path / "0 ms" / "spec.yaml"), "--duration", "3s", "--runs", "3")
    assert rc == 0, sim.get("violations")


def test_a_can_message_a_task_sends_is_queued_its_tx_delay_after_the_task(tmp_path: Path) -> None:
    """netcfg.sim queues a CAN message a task sends as it ends its node's tx_delay later; the flow analysis queued
    it at the task's end, so the latency ran past the bound by up to tx_delay (found by the wide FTT-CAN specs,
    under --mode unsync). By hand: a.send 50-100 us, tx_delay 165 us, m alone on the bus, its 8-byte frame 111 bits
    unstuffed (222 us) to 135 stuffed (270 us, 500 kbit/s): b.use starts 50 + 165 + 222 = 437 us at the earliest and
    100 + 165 + 270 = 535 us at the latest (it was 272-370 us)."""
    text = RX_CAN.replace("RX", "0 us").replace("{name: a,", "{name: a, tx_delay: 165 us,")
    (tmp_path / "spec.yaml").write_text(text, encoding="utf-8")
    flow = check(tmp_path / "spec.yaml")["flows"][0]
    assert (flow["latency_min_us"], flow["latency_max_us"]) == (437, 535)
    rc, sim = cli_json("simulate", str(tmp_path / "spec.yaml"), "--duration", "2s", "--runs", "2")
    assert rc == 0, sim.get("violations")
    assert next(f for f in sim["flows"] if f["name"] == "f")["latency_us"]["min"] >= 437


@pytest.mark.parametrize(
    ("name", "seed"),
    [
        ("12", 745),
        ("13", 397),
        ("14", 1217),
        ("15", 1447),
        ("16", 115),
        ("17", 1307),
        ("18", 1011),
        ("19", 1089),
        ("20", 106),
    ],
)
def test_wide_ftt_can_specs_stay_inside_their_bounds(name: str, seed: int) -> None:
    """Specs the wider FTT-CAN generator found outside a bound (each file's header says what netcfg printed, what
    was measured and why): run as the sweep ran them (random phases, the critical instant, free-running CAN, with
    the bus's errors hitting as hard as its model allows), nothing may leave its bound."""
    out = soundness.check_spec(spec(name), seed=seed, duration_ns=500_000_000)
    assert out.accepted
    assert out.violations == [], out.violations


def test_a_first_task_started_by_a_message_counts_from_its_start(tmp_path: Path) -> None:
    """Spec 14's header: the age counts from n1.as0's start, after n1's rx_delay, so af0's earliest is bcet 63 us +
    a0's unstuffed frame (29-bit identifier, 8 bytes: 131 bits, 262 us at 500 kbit/s) + n0's rx_delay 7.001 us."""
    report = check(next(DATA.glob("14-*.yaml")))
    flow = next(f for f in report["flows"] if f["name"] == "af0")
    assert flow["latency_min_us"] == pytest.approx(63 + 262 + 7.001)


def test_a_late_tm_starts_the_ec_it_was_sent_for() -> None:
    """Spec 20's header: bit errors only delay a TM (ISO 11898-1 retransmits it), so a TM resent past its EC's
    asynchronous-first window start still starts that EC: no EC goes without its TM and no frame is lost."""
    faults = soundness.error_pattern(spec("20"), 500_000_000, 106)
    # EC 28 starts at 28 x 3 ms; its TM (6 bytes: 115 bits at 250 kbit/s, 460 us) is hit, and resent after the
    # error frame (31 bits, 124 us) it ends past the window's start, 460 + 356 us (its asynchronous window) in
    (hit,) = [f.at_ns for f in faults if 84_000_000 <= f.at_ns < 84_460_000]
    assert hit + 124_000 + 460_000 > 84_000_000 + 460_000 + 356_000
    result = _critical_instant(next(DATA.glob("20-*.yaml")), 500_000_000, seed=106, faults=faults)
    assert result["protocols"]["bus"][0]["ecs_without_tm"] == 0
    assert [m["lost"] for m in result["messages"]] == [0] * len(result["messages"])


@pytest.mark.parametrize(
    ("name", "flow", "analysis", "expected"),
    [
        ("12", "af2", "unsynchronised.latency_max_us", 14_201.2),  # its header: 11,200.9 + 12,001.2 - 9,000.9 us
        ("15", "fj", "latency_min_us", 6_320),  # its header: 14,586 - 7,270 - 996 us
        # its header's 8,000 + 95 + 1 + 126 - 95 us, and the start's TM up to 16 us early (4 bytes, ISO 11898-1: 79
        # bits without stuff bits, 95 at worst, at 1 Mbit/s): the start may come that much sooner
        ("16", "af1", "latency_max_us", 8_127 + 16),
        ("17", "fj", "unsynchronised.latency_min_us", 550),  # its header: 47 + 503 us
        # its header's 2,000 + 340 - 532 - (340 + 464 - 532) us, less join's TM up to 56 us early (3 bytes: 71 bits
        # without stuff bits, 85 at worst, at 250 kbit/s): the flow's last start may come that much sooner
        ("18", "fj", "latency_min_us", 1_536 - 56),
        # its header's 8,353 + 928 - 341 us, and s0's TM up to 56 us early (3 bytes at 250 kbit/s, as spec 18's)
        ("19", "f0", "latency_max_us", 8_940 + 56),
    ],
)
def test_wide_ftt_can_specs_figures(name: str, flow: str, analysis: str, expected: float) -> None:
    """The figures each spec's header derives (`analysis`: the key in the flow's report, "a.b" one level down)."""
    got = next(f for f in check(next(DATA.glob(f"{name}-*.yaml")))["flows"] if f["name"] == flow)
    for key in analysis.split("."):
        got = got[key]
    assert got == pytest.approx(expected)
