"""End-to-end flows where features meet: a sporadic message whose send a run skips, a join whose items take
different paths, a drive that answers every command (request and response). The specs in tests/data/seams keep
their headers (what netcfg printed, what the simulator measured, the derivation); every figure asserted here is
derived there or in the test's docstring.

Frame times (ISO 11898-1, 11-bit identifier, s data bytes): 47 + 8s bits nominal, 47 + 8s + (34 + 8s - 1) // 4
with worst-case stuffing; an 8-byte frame at 500 kbit/s is 222 us nominal, 270 us at worst. Flows count clocks
within the default 100 ppm: a wait of w ns on a node's clock is w + ceil(w / 10,000) ns of real time.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import check, check_data, runtime_config

from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import summary
from netcfg.sim.scenario import SimOptions

SEAMS = Path(__file__).parent / "data" / "seams"
S = 1_000_000_000


def flow(report: dict[str, Any], name: str) -> dict[str, Any]:
    found: dict[str, Any] = next(f for f in report["flows"] if f["name"] == name)
    return found


def simulated(path: Path, seeds: range) -> list[dict[str, Any]]:
    """`netcfg simulate SPEC --duration 10s --seed N` for each seed, as its JSON document."""
    cfg = runtime_config(path)
    return [summary(run_once(cfg, SimOptions(duration_ns=10 * S, seed=seed))[1]) for seed in seeds]


def measured_max(result: dict[str, Any], name: str) -> float:
    worst: float = next(f for f in result["flows"] if f["name"] == name)["latency_us"]["max"]
    return worst


def test_09_side_input_waits_for_the_run_that_sends() -> None:
    """Seam 09's derivation. m3 (8 bytes, 0x110) waits for one frame of m2 (blocking) and one of m1: 3 x 270 =
    810 us from its release, so it is at gw by 300 (t4's WCET) + 810 = 1,110 us. gw.t2 (5 ms, 100..2000 us) sends
    m2 (sporadic, 5 ms) only when 5 ms have passed since its last send: after a run that sent, ending up to
    2,000 us after its start, run n later ends no sooner than n x 5 ms (less 100 ppm) + 100 us, so it surely
    sends once n x 4,999.5 + 100 >= 2,000 + 5,000: n = 2. m3's data (renewed only every 20 ms) waits up to two
    periods for the start of a run that sends, 10,001 us at 100 ppm, then 2,000 us for it to end; m2 (the lowest
    identifier of three 8-byte frames) takes 810 us: 1,110 + 10,001 + 2,000 + 810 = 13,921 us ("~14 ms").
    The trig flow is not loosened: m1 renews t1's data every 5 ms, so the run that sends reads data at most one
    m1 period (5,000.5 us) old whichever runs skipped: 300 + 540 (m1: m3's blocking and its own frame) + 5,000.5
    + 2,000 + 810 = 8,650.5 us. Simulated, seeds 0-5 (side up to 12,490.1 us, seed 2) stay inside."""
    path = SEAMS / "09-sporadic-send-skip-side-input.yaml"
    report = check(path)
    assert (flow(report, "side")["latency_min_us"], flow(report, "side")["latency_max_us"]) == (644, 13_921)
    assert flow(report, "trig")["latency_max_us"] == 8_650.5
    for result in simulated(path, range(6)):
        assert result["violations"] == []
        assert measured_max(result, "side") <= 13_921


def test_09b_event_gateway_waits_one_more_trigger_interval() -> None:
    """Seam 09b: gw.t2 starts on m1's deliveries, so its runs follow m1: m1 is queued as t1 ends (100..300 us:
    200 us of release spread) and delivered 222..540 us later (318 us more), so n runs apart t2's starts lie
    within n x 5 ms -+ 518 us. After a run that sent, run n later surely sends once n x 4,999.5 - 518 + 100 >=
    2,000 + 5,000: n = 2, so m3's data waits up to 10,000 + 518 us for a sending run, 10,519.052 us at 100 ppm
    (the message-started task's "period" of 0 used to add nothing): 1,110 + 10,519.052 + 2,000 + 810 =
    14,439.052 us. The trig flow starts t2 with its own data, each skipped run's data superseded by the next m1:
    300 + 540 + 2,000 + 810 = 3,650 us. Simulated, seeds 0-5 (side up to 12,725.6 us, seed 4) stay inside."""
    path = SEAMS / "09b-sporadic-send-skip-event-gateway.yaml"
    report = check(path)
    assert flow(report, "side")["latency_max_us"] == pytest.approx(14_439.052)
    assert flow(report, "trig")["latency_max_us"] == 3_650
    for result in simulated(path, range(6)):
        assert result["violations"] == []
        assert measured_max(result, "side") <= 14_439.052


def test_10_join_best_case_counts_each_item_from_its_own_path() -> None:
    """Seam 10's derivation: m1 is at gw 32 (t1's BCET) + 299 (tx_delay) + 222 (its nominal frame) = 553 us after
    t1 starts at the earliest, m3 403 + 63 = 466 us after t4 starts; gw.t2 starts on m1 once m3 is in, and
    dst.t3 starts 67 + 55 us after m1's arrival: the join's age, from the older stamp, is at least 553 + 122 =
    675 us (it was 1,046: m1's path counted from t4's BCET). The single paths keep their best cases: e2e 675 us,
    e2e3 403 + 63 + 67 + 55 = 588 us. Simulated, seeds 0-7 (744.1 us at least, seed 3) stay inside."""
    path = SEAMS / "10-flow-join-best-case.yaml"
    report = check(path)
    assert flow(report, "join")["latency_min_us"] == 675
    assert flow(report, "e2e")["latency_min_us"] == 675
    assert flow(report, "e2e3")["latency_min_us"] == 588
    for result in simulated(path, range(8)):
        assert result["violations"] == []


def test_10_a_task_started_from_outside_counts_its_message_release_spread() -> None:
    """Seam 10's e2e3 (t4 -> m3 -> gw.t2 -> m2 -> dst.t3): gw.t2 reads m3 whenever m1 comes, and m1 is queued as
    t1 ends, 32..98 us after its start: consecutive deliveries of m1 are up to 2,000 + 66 (that release spread)
    + 48 (270 - 222, m1's delivery variation, alone on b0) = 2,114 us apart, 2,114.212 us at 100 ppm. On b1
    (1 Mbit/s) m3 (2 bytes: 75 us at worst) waits for m2 (1 byte: 65 us) and m2 for m3: 140 us each. So
    1,210 (t4's WCET) + 140 + 2,114.212 + 201 (t2's WCET) + 140 = 3,805.212 us (it was 3,739.205, without the
    66 us spread)."""
    report = check(SEAMS / "10-flow-join-best-case.yaml")
    assert flow(report, "e2e3")["latency_max_us"] == pytest.approx(3_805.212)


def test_a_sporadic_message_two_tasks_send_carries_a_skipped_run_s_data_with_the_next_send(tmp_path: Path) -> None:
    """Seam 09 with a second sender of m2 on gw, t5 (5 ms, 100..300 us), the first step of flow `other`
    (t5 -> m2 -> dst.t3). A run of t5 that ends less than 5 ms after t2's last send sends nothing, and its data
    leaves with the next m2, whoever sends it (the message carries gw's freshest output); this was measured up
    to 5,546 us against 3,110. After any send each sender's first run to end 5 ms later sends: t2's starts up to
    5,000 - 100 (its BCET) + 5,000 (a period) after that send and ends 2,000 later, 11,900 us; t5's, behind t2 on
    gw's processor (2,300 us), 12,200 us. So t5 ends by 2,300 us (processor analysis), m2 is released up to
    11,900 us (11,901.19 at 100 ppm) after that and takes 810 us: 2,300 + 11,901.19 + 810 = 15,011.19 us."""
    data = yaml.safe_load((SEAMS / "09-sporadic-send-skip-side-input.yaml").read_text(encoding="utf-8"))
    data["nodes"][2]["tasks"].append({"name": "t5", "period": "5 ms", "wcet": "300 us", "bcet": "100 us"})
    data["flows"].append({"name": "other", "chain": ["gw.t5", "m2", "dst.t3"]})
    report = check_data(tmp_path, data)
    assert flow(report, "other")["latency_max_us"] == pytest.approx(15_011.19)
    cfg = runtime_config(tmp_path / "spec.yaml")
    for seed in range(6):
        result = summary(run_once(cfg, SimOptions(duration_ns=10 * S, seed=seed))[1])
        assert result["violations"] == []


SERVO = """\
system: servo
buses:
  - {name: b, protocol: can, bitrate: 1 Mbit/s}
nodes:
  - name: host
    buses: [b]
    tasks: [{name: control, period: 1 ms, wcet: 100 us, bcet: 50 us}]
  - name: drive
    buses: [b]
    rx_delay: 10 us
    tx_delay: 20 us
    tasks: [{name: apply, on_message: cmd, wcet: 80 us, bcet: 30 us}]
messages:
  - {name: cmd, id: 0x100, producer: host, consumers: [drive], size: 8, period: 1 ms}
  - {name: state, id: 0x180, producer: drive, consumers: [host], size: 8, period: STATE}
flows:
  - {name: loop, chain: [host.control, cmd, drive.apply, state, host.control]}
"""


def test_a_task_a_message_starts_inherits_the_message_s_whole_response_jitter(tmp_path: Path) -> None:
    """Tindell and Clark (1994): a task a message activates inherits the message's response jitter, from its
    nominal release. At 1 Mbit/s an 8-byte frame takes 111 us nominal, 135 at worst; cmd is released as
    host.control ends (50..100 us: 50 us of release jitter), and reaches the drive 111..270 us after that (one
    frame of state may hold it up). So drive.apply starts up to 50 + 270 - 111 = 209 us late, and its response
    from its nominal release is 209 + 80 = 289 us (it was 239: the release jitter control adds was left out)."""
    (tmp_path / "servo.yaml").write_text(SERVO.replace("STATE", "1 ms"), encoding="utf-8")
    report = check(tmp_path / "servo.yaml")
    apply = next(t for n in report["nodes"] for t in n["tasks"] if t["name"] == "apply")
    assert apply["wcrt_us"] == 289


def test_a_drive_answers_every_command_with_the_run_the_command_starts(tmp_path: Path) -> None:
    """The request/response servo loop (a new user's finding): drive.apply runs on cmd (every 1 ms), so it runs at
    cmd's rate, and state, at that rate too and named after it in the flow, is its reply: sent as apply ends,
    tx_delay later (it ran free at its own period, runtime.json sent_by []).
    At 1 Mbit/s an 8-byte frame takes 111 us nominal, 135 at worst. cmd (the higher identifier's priority) is
    released as control ends (50..100 us: 50 us of release jitter) and waits for one frame of state at worst:
    135 + 135 = 270 us from its release, 111 at best. state's release jitter is cmd's response spread from its
    nominal release, 50 + (270 - 111) = 209 us, and apply's variation, 80 - 30 = 50 us: 259 us; its WCRT is
    259 + 135 (one cmd frame) + 135 = 529 us, and apply's from its nominal release 209 + 80 = 289 us. The flow
    counts each delay once, the reply's jitter being its path: the reply is back by 100 + 270 + 10 (rx_delay) +
    80 + 20 (tx_delay) + 270 = 750 us after control starts, and control's next run, one period later on the same
    clock (999.9..1,000.1 us at 100 ppm), reads it: 1,000.1 us at the latest (1,750.1 when control's next start
    was taken as anywhere within a period). Measured, every sample is one period (1,000 us within the simulator's
    50 ppm); running free, state made the loop up to 2 ms."""
    (tmp_path / "servo.yaml").write_text(SERVO.replace("STATE", "1 ms"), encoding="utf-8")
    report = check(tmp_path / "servo.yaml")
    messages = {m["name"]: m for b in report["buses"] for m in b["messages"]}
    assert messages["state"]["wcrt_us"] == 529
    apply = next(t for n in report["nodes"] for t in n["tasks"] if t["name"] == "apply")
    assert apply["wcrt_us"] == 289
    assert (flow(report, "loop")["latency_min_us"], flow(report, "loop")["latency_max_us"]) == (999.9, 1_000.1)
    cfg = runtime_config(tmp_path / "servo.yaml")
    assert cfg.message("state").sent_by == ("drive.apply",)
    for seed in range(3):
        result = summary(run_once(cfg, SimOptions(duration_ns=S, seed=seed))[1])
        assert result["violations"] == []
        latency = next(f for f in result["flows"] if f["name"] == "loop")["latency_us"]
        assert latency["min"] >= 999.95 and latency["max"] <= 1_000.05


def test_a_reply_at_another_rate_still_runs_at_its_own(tmp_path: Path) -> None:
    """The rule is the one for periodic tasks: a message at a rate other than its task's runs at its own (state
    every 2 ms samples apply's latest output); only one at the rate of the command that starts the task is its
    reply."""
    (tmp_path / "servo.yaml").write_text(SERVO.replace("STATE", "2 ms"), encoding="utf-8")
    assert runtime_config(tmp_path / "servo.yaml").message("state").sent_by == ()


TWO_DRIVES = """\
system: servo2
buses:
  - {name: b, protocol: can, bitrate: 1 Mbit/s}
nodes:
  - name: host
    buses: [b]
    tasks:
      - {name: control, period: 1 ms, wcet: 100 us, bcet: 50 us}
      - {name: use, on_message: s1, wcet: 30 us, bcet: 10 us}
  - name: d1
    buses: [b]
    rx_delay: 10 us
    tx_delay: 20 us
    tasks: [{name: apply, on_message: cmd, wcet: 80 us, bcet: 30 us}]
  - name: d2
    buses: [b]
    rx_delay: 10 us
    tx_delay: 20 us
    tasks: [{name: apply, on_message: cmd, wcet: 280 us, bcet: 30 us}]
messages:
  - {name: cmd, id: 0x100, producer: host, consumers: [d1, d2], size: 8, period: 1 ms}
  - {name: s1, id: 0x180, producer: d1, consumers: [host], size: 8, period: 1 ms}
  - {name: s2, id: 0x181, producer: d2, consumers: [host], size: 8, period: 1 ms}
flows:
  - {name: both, chain: [host.control, cmd, [d1.apply, d2.apply], [s1, s2], host.use]}
"""


def test_a_task_one_reply_starts_may_take_the_other_reply_of_the_command_before(tmp_path: Path) -> None:
    """Two drives answer every command; host.use starts on s1 and reads s2 too. s2's reply to this command may
    come after s1's (d2 takes longer), and then use takes s2's reply to the command before, one control period
    older. At 1 Mbit/s (8-byte frames, 135 us at worst), from their releases cmd waits for one reply frame (270
    us), s1 for s2's and cmd's frames and s2 for s1's and cmd's (405 us each). The replies are in by 100 + 270 +
    10 + 280 (d2's apply) + 20 + 405 = 1,085 us, the bound the analysis gave (measured up to 1,479 us), and use
    may take data one period (1,000.1 us at 100 ppm) older: 2,085.1 us."""
    (tmp_path / "two.yaml").write_text(TWO_DRIVES, encoding="utf-8")
    report = check(tmp_path / "two.yaml")
    assert flow(report, "both")["unsynchronised"]["delivery_max_us"] == 1_085
    assert flow(report, "both")["latency_max_us"] == 2_085.1
    cfg = runtime_config(tmp_path / "two.yaml")
    for seed in range(3):
        assert summary(run_once(cfg, SimOptions(duration_ns=2 * S, seed=seed))[1])["violations"] == []


LOSSY = """\
system: lossy
buses:
  - {name: b, protocol: can, bitrate: 1 Mbit/s}
nodes:
  - name: host
    buses: [b]
    tasks: [{name: control, period: 2 ms, wcet: 100 us, bcet: 50 us}]
  - name: d0
    buses: [b]
    tasks: [{name: apply, on_message: cmd, wcet: 600 us, bcet: 10 us}]
  - name: d1
    buses: [b]
    tasks: [{name: apply, on_message: cmd, wcet: 100 us, bcet: 10 us}]
messages:
  - {name: cmd, id: 0x100, producer: host, consumers: [d0, d1], size: 8, period: 2 ms}
  - {name: s0, id: 0x180, producer: d0, consumers: [host], size: 2, min_interarrival: 2 ms}
  - {name: s1, id: 0x181, producer: d1, consumers: [host], size: 2, min_interarrival: 2 ms}
flows:
  - {name: both, chain: [host.control, cmd, [d0.apply, d1.apply], [s0, s1], host.control]}
"""


def test_a_join_whose_item_skipped_a_send_waits_for_its_next(tmp_path: Path) -> None:
    """Two drives answer each command with a sporadic reply (2 ms minimum inter-arrival, the command's period):
    a reply that would come sooner than 2 ms after the last is skipped, so d0 may answer commands k-1 and k+1 and
    d1 k-1 and k: control, reading the oldest of the two replies, then takes command k's data only at its run
    after d0's next reply, two control periods on (measured 4,000 us; analysed 3,195.2 as if each item had every
    stamp). At 1 Mbit/s (8-byte cmd 111..135 us, 2-byte replies 63..75 us), from their releases cmd waits for a
    reply frame (75 + 135 = 210 us) and s0 for s1's and cmd's frames (75 + 135 + 75 = 285 us): the replies are in
    by 100 + 210 + 600 + 285 = 1,195 us. A reply's runs follow cmd's deliveries, 2 ms apart within 50 (control's
    variation) + 99 (210 - 111) = 149 us; after a send, the run n later surely sends once n x 1,999.8 (2 ms less
    100 ppm) - 149 + 10 >= 600 + 2,000: n = 2, so a reply's data is renewed up to 4,149 us apart (4,149.415 at
    100 ppm), and control may take data that much older: 1,195 + 4,149.415 = 5,344.415 us."""
    (tmp_path / "lossy.yaml").write_text(LOSSY, encoding="utf-8")
    report = check(tmp_path / "lossy.yaml")
    assert flow(report, "both")["unsynchronised"]["delivery_max_us"] == 1_195
    assert flow(report, "both")["latency_max_us"] == pytest.approx(5_344.415)
    # the earliest reply is back 234 us after control starts, read by control's next run: one period, less 100 ppm
    assert flow(report, "both")["latency_min_us"] == 1_999.8
    cfg = runtime_config(tmp_path / "lossy.yaml")
    for seed in range(3):
        assert summary(run_once(cfg, SimOptions(duration_ns=2 * S, seed=seed))[1])["violations"] == []
