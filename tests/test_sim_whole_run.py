"""The whole-run paths (netcfg.sim.whole_run for Ethernet, netcfg.protocols.ftt.sim_whole_run for FTT-CAN) give, for the
same seed, exactly what the event path gives, on every system they cover: every frame's release and delivery,
every flow sample, the counters, the per-link and per-receiver reports and the task runs. The event path is the
reference (SimOptions(whole_run=False)); nothing here is a recorded figure, both paths run afresh on each case.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import soundness
from conftest import ROOT, load_spec, runtime_config_of
from hypothesis import HealthCheck, given, settings

import netcfg.runtime as rt
from netcfg.protocols.ftt import sim_whole_run as ftt_whole_run
from netcfg.runtime.config import FlowStep
from netcfg.sim import flows, whole_run
from netcfg.sim.can_trace import trace_frames
from netcfg.sim.ethernet import CHUNK_NS
from netcfg.sim.faults import Fault
from netcfg.sim.flows import Stream, Undecided, measure_streams
from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import RunResult, summary
from netcfg.sim.scenario import Scenario, SimOptions

MS = 1_000_000


def generated(system: str) -> rt.RuntimeConfig:
    return rt.load(ROOT / "generated" / system / "runtime.json")


def both(cfg: rt.RuntimeConfig, opts: SimOptions) -> tuple[tuple[Scenario, RunResult], tuple[Scenario, RunResult]]:
    return run_once(cfg, opts), run_once(cfg, replace(opts, whole_run=False))


def assert_identical(a: tuple[Scenario, RunResult], b: tuple[Scenario, RunResult]) -> None:
    (sa, ra), (sb, rb) = a, b
    for table in ("response", "flow_latency", "flow_delivery"):
        x, y = getattr(ra, table), getattr(rb, table)
        assert sorted(x) == sorted(y), table
        for name in x:
            assert np.array_equal(x[name], y[name]), f"{table} of {name}"
    assert (ra.frames, ra.sent, ra.lost) == (rb.frames, rb.sent, rb.lost)
    assert json.dumps(ra.protocols, sort_keys=True) == json.dumps(rb.protocols, sort_keys=True)
    assert sa.task_runs == sb.task_runs
    doc_a, doc_b = summary(ra), summary(rb)
    doc_a.pop("speed"), doc_b.pop("speed")  # wall-clock figures
    assert doc_a == doc_b


def compiled(spec: dict[str, Any], path: Path) -> rt.RuntimeConfig:
    """The runtime configuration of a spec written as a dict (which check must accept)."""
    return runtime_config_of(path, spec)


def count_builds(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """A list that grows by one each time a scenario is built: twice for a run that fell back to the event path."""
    builds: list[int] = []
    build = Scenario._build
    monkeypatch.setattr(Scenario, "_build", lambda sc: (builds.append(1), build(sc))[1])
    return builds


@pytest.mark.parametrize(
    ("system", "options"),
    [
        ("ntua_sahr", {"seed": 1}),
        ("ntua_sahr", {"seed": 2, "duration_ns": 2000 * MS}),
        ("ntua_treadmill", {"seed": 3}),
        # every clock at 0 without drift: the 15 kHz encoders of both boards reach the PC's port on the same
        # nanoseconds, so ties between free-running and chained frames decide the order
        ("ntua_sahr", {"seed": 4, "random_phase": False, "drift_ppm": 0.0}),
        # one frame per port: tail drops on the PC's port (the frame-by-frame twin of Lindley's recursion)
        ("ntua_sahr", {"seed": 5, "eth_queue_frames": 1}),
        ("ntua_sahr", {"seed": 6, "eth_processing_ns": {"pc": (2_000, 30_000), "mcu_hip": (1_000, 4_000)}}),
    ],
)
def test_seed_systems_identical_both_ways(system: str, options: dict[str, Any]) -> None:
    cfg = generated(system)
    opts = SimOptions(**{"duration_ns": 1000 * MS, **options})
    assert whole_run.covers(Scenario(cfg, opts))
    a, b = both(cfg, opts)
    assert_identical(a, b)
    if options.get("eth_queue_frames") == 1:
        assert sum(b[1].lost.values()) > 0, "the case is meant to drop frames"


def random_specs_identical_both_ways(protocol: str, examples: int, duration_ns: int, covers: Any) -> None:
    """benchmarks/soundness.py's random specs of one protocol, each at random phases and at the critical instant:
    every run `covers` admits must be identical both ways, and some must be admitted."""
    covered = []

    @settings(max_examples=examples, deadline=None, database=None, suppress_health_check=list(HealthCheck))
    @given(soundness.strategy(protocol))
    def run(spec: dict[str, Any]) -> None:
        cfg = soundness.runtime_config(spec)
        if cfg is None:
            return
        for opts in (
            SimOptions(duration_ns=duration_ns, seed=len(covered)),
            SimOptions(duration_ns=duration_ns, seed=len(covered), random_phase=False, drift_ppm=0.0),
        ):
            if covers(Scenario(cfg, opts)):
                covered.append(spec["system"])
                assert_identical(*both(cfg, opts))

    run()
    assert covered, "no random spec was covered: the test no longer compares anything"


def test_random_ethernet_specs_identical_both_ways(monkeypatch: pytest.MonkeyPatch) -> None:
    """Random switched networks (1-3 switches, jitter, flows with periodic and message-driven consumers); computed
    15 ms at a time, so that frames, activations and jitter draws cross window edges."""
    monkeypatch.setattr(whole_run, "WINDOW_NS", 3 * CHUNK_NS)
    random_specs_identical_both_ways("ethernet-udp", 12, 150 * MS, whole_run.covers)


def test_a_multicast_flow_identical_both_ways(tmp_path: Path) -> None:
    """NTUA SAHR with the hip encoder also sent to the spring board, which starts a task on it: one flow's message
    step now holds both consumers' deliveries (often on the same nanosecond), and a second flow ends in the
    message-activated task."""
    spec = load_spec("ntua_sahr.yaml")
    hip = next(m for m in spec["messages"] if m["name"] == "hip_encoder")
    hip["consumers"] = ["pc", "mcu_spring"]
    spring = next(n for n in spec["nodes"] if n["name"] == "mcu_spring")
    spring["tasks"].append({"name": "follow", "on_message": "hip_encoder", "wcet": "3 us", "bcet": "1 us"})
    spec["flows"].append({"name": "hip_to_spring", "chain": ["mcu_hip.sample", "hip_encoder", "mcu_spring.follow"]})
    cfg = compiled(spec, tmp_path / "multicast.yaml")
    opts = SimOptions(duration_ns=1000 * MS, seed=9)
    assert whole_run.covers(Scenario(cfg, opts))
    a, b = both(cfg, opts)
    assert_identical(a, b)
    assert len(b[1].flow_latency["hip_to_spring"]) > 10_000  # 15 kHz for a second, after the warm-up


@pytest.mark.parametrize("critical", [False, True])
def test_ethernet_flows_with_several_items_per_step_identical_both_ways(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, critical: bool
) -> None:
    """NTUA SAHR with both 15 kHz boards in one flow's steps ([both samples], [both encoders], the PID, ...), and a
    second flow ending in two PC tasks together (the PID and a 2 kHz logger): the PC's tasks read the older of the
    two encoders' stamps, and the second flow's sample waits for both tasks. At the critical instant both boards
    sample on the same nanoseconds."""
    spec = load_spec("ntua_sahr.yaml")
    pc = next(n for n in spec["nodes"] if n["name"] == "pc")
    pc["tasks"].append({"name": "log", "period": "500 us", "wcet": "20 us", "bcet": "5 us"})
    samples, encoders = ["mcu_hip.sample", "mcu_spring.sample"], ["hip_encoder", "spring_encoder"]
    spec["flows"] = [
        {"name": "both_loop", "chain": [samples, encoders, "pc.pid", "hip_pwm", "mcu_hip.apply_pwm"]},
        {"name": "both_encoders", "chain": [samples, encoders, ["pc.pid", "pc.log"]]},
    ]
    cfg = compiled(spec, tmp_path / "both.yaml")
    opts = SimOptions(duration_ns=300 * MS, seed=11)
    if critical:
        opts = replace(opts, random_phase=False, drift_ppm=0.0)
    assert whole_run.covers(Scenario(cfg, opts))
    builds = count_builds(monkeypatch)
    a = run_once(cfg, opts)
    assert len(builds) == 1, "computed whole, not fallen back to the event path"
    b = run_once(cfg, replace(opts, whole_run=False))
    assert_identical(a, b)
    # the boards sample at 15 kHz for 0.3 s (4,500 times, less the warm-up): the floor says both flows were measured
    assert len(b[1].flow_latency["both_loop"]) > 100 and len(b[1].flow_latency["both_encoders"]) > 100


def test_what_the_whole_run_does_not_cover_runs_event_by_event() -> None:
    sahr = generated("ntua_sahr")
    assert not whole_run.covers(Scenario(sahr, SimOptions(faults=(Fault.parse("lose:hip_pwm@20ms"),))))
    assert not whole_run.covers(Scenario(generated("cambada"), SimOptions()))  # FTT-CAN: ftt_whole_run


@pytest.mark.parametrize(
    "options",
    [
        {"seed": 1},
        {"seed": 2, "duration_ns": 7_000 * MS + 17},  # past several of the asynchronous streams' chunks
        # the master's and every node's clock at 0 without drift: the sporadic resets and the periodic battery
        # status are released on the same nanoseconds, and on EC starts
        {"seed": 3, "random_phase": False, "drift_ppm": 0.0},
        {"seed": 4, "stuffing": "none"},
        {"seed": 5, "drift_ppm": 100_000.0},
        {"seed": 6, "trace": True},  # every frame's end and payload, the TMs' schedules among them
    ],
)
def test_cambada_identical_both_ways(options: dict[str, Any]) -> None:
    """CAMBADA (seed 002): FTT-CAN with triggered tasks, a message-activated task, asynchronous periodic and
    sporadic traffic, and flows whose steps hold several items (three wheels' tasks and encoders, the pose's two
    messages), computed whole by netcfg.protocols.ftt.sim_whole_run."""
    cfg = generated("cambada")
    opts = SimOptions(**{"duration_ns": 2000 * MS, **options})
    assert ftt_whole_run.plan(Scenario(cfg, opts)) is not None
    a, b = both(cfg, opts)
    assert a[0].protocols["lowlevel"]._got_tm == -1, "the event path ran: the master heard no TM in the whole run"
    assert_identical(a, b)
    assert all(len(v) for v in b[1].flow_latency.values())
    assert b[1].sent["battery_status"] and b[1].sent["reset_motor1"], "the asynchronous traffic ran"
    if opts.trace:
        frames = trace_frames(b[0])
        assert trace_frames(a[0]) == frames
        assert len(frames) == b[1].frames and len({f.data for f in frames if f.can_id == 0}) > 1, "TM schedules"


def _tied_ftt_spec(windows: str, rx_delay: str, triggered: bool) -> dict[str, Any]:
    """One 1 Mbit/s FTT-CAN bus, EC 2 ms: a.send (triggered every EC) -> m0 (every EC) -> b.use, triggered every
    EC or started by m0, on a node whose rx_delay puts its start on the very nanosecond an m0 frame is received."""
    use: dict[str, Any] = {"name": "use", "wcet": "40 us", "bcet": "10 us"}
    triggers = [{"name": "t_send", "ftt_id": 5, "bus": "bus", "period": "1 EC", "tasks": ["a.send"]}]
    if triggered:
        triggers.append({"name": "t_use", "ftt_id": 6, "bus": "bus", "period": "1 EC", "tasks": ["b.use"]})
    else:
        use["on_message"] = "m0"
    return {
        "system": "tied",
        "buses": [{"name": "bus", "protocol": "ftt-can", "bitrate": "1 Mbit/s",
                   "ftt": {"ec": "2 ms", "tm_size": 2, "windows": windows}}],
        "nodes": [
            {"name": "master", "role": "master", "buses": ["bus"]},
            {"name": "a", "buses": ["bus"], "tasks": [{"name": "send", "wcet": "50 us", "bcet": "20 us"}]},
            {"name": "b", "buses": ["bus"], "rx_delay": rx_delay, "tasks": [use]},
        ],
        "messages": [
            {"name": "m0", "ftt_id": 1, "producer": "a", "consumers": ["b"], "size": 2, "period": "1 EC"},
            {"name": "as0", "id": 0x300, "window": "async", "producer": "a", "consumers": ["b"], "size": 1,
             "period": "3 ms"},
        ],
        "triggers": triggers,
        "flows": [{"name": "f0", "chain": ["a.send", "m0", "b.use"]}],
    }


@pytest.mark.parametrize(
    ("windows", "rx_delay", "triggered"),
    [
        # the TM and m0 take 75 us each at 1 Mbit/s (2 bytes and 2 bytes, worst-case stuffing, ISO 11898-1):
        # sync-first, m0 ends 150 us into the EC, b.use starts at the TM's end (75 us) + 75 us
        ("sync-first", "75 us", True),
        # async-first, m0 is the last frame of the EC (ends at 2 ms): 75 us + 1925 us
        ("async-first", "1925 us", True),
        # b.use on m0 with rx_delay one period: each start falls on the next m0 frame's reception
        ("async-first", "2 ms", False),
        ("async-first", "0 us", False),  # started from inside m0's delivery: it reads that frame
    ],
)
def test_a_task_starting_as_its_frame_is_received_identical_both_ways(
    tmp_path: Path, windows: str, rx_delay: str, triggered: bool
) -> None:
    """A task that starts on the nanosecond a frame it reads is received: the event path decides by the order its
    events were queued in (a trigger's start is queued at the TM's reception, an rx_delay'd start at the earlier
    frame's delivery: both before that frame's delivery; a periodic task after every delivery; a task without
    rx_delay inside its frame's delivery), and the whole run must read the same frame."""
    cfg = compiled(_tied_ftt_spec(windows, rx_delay, triggered), tmp_path / "tied.yaml")
    opts = SimOptions(duration_ns=50 * MS, seed=1)
    assert ftt_whole_run.plan(Scenario(cfg, opts)) is not None
    a, b = both(cfg, opts)
    assert a[0].protocols["bus"]._got_tm == -1, "computed whole, not fallen back to the event path"
    assert_identical(a, b)
    assert len(b[1].flow_latency["f0"]) > 10  # 25 ECs of 2 ms in 50 ms: the floor says the flow was measured


@pytest.mark.parametrize("rx_delay", ["0 us", "150 us"])
def test_cambada_with_a_task_sending_asynchronous_frames_identical_both_ways(tmp_path: Path, rx_delay: str) -> None:
    """CAMBADA with its kick sent by the gateway's pose task (every 50 ms, started by a synchronous frame) rather
    than free-running: the 1 s minimum inter-arrival lets one send in twenty through, the frames go through the
    asynchronous window, and a kicker task started by each (after the kicker's rx_delay) ends a flow."""
    spec = load_spec("cambada.yaml")
    kicker = next(n for n in spec["nodes"] if n["name"] == "kicker")
    kicker["tasks"] = [{"name": "fire", "on_message": "kick", "wcet": "300 us", "bcet": "100 us"}]
    kicker["rx_delay"] = rx_delay
    spec["flows"].append({"name": "kick", "chain": ["gateway.rx_pose", "kick", "kicker.fire"]})
    cfg = compiled(spec, tmp_path / "kick.yaml")
    opts = SimOptions(duration_ns=5000 * MS, seed=12)
    assert ftt_whole_run.plan(Scenario(cfg, opts)) is not None
    a, b = both(cfg, opts)
    assert a[0].protocols["lowlevel"]._got_tm == -1, "computed whole, not fallen back to the event path"
    assert_identical(a, b)
    # rx_pose runs every 50 ms from 25 ms; a send needs 1 s since the last, so the k-th comes between 25 + 1,000k
    # and 25 + 1,050k ms: five in 5 s. The flow measures those after the warm-up (the last of its nodes' clock
    # phases), which the first may precede.
    assert b[1].sent["kick"] == 5
    assert len(b[1].flow_latency["kick"]) in (4, 5)


def test_random_ftt_specs_identical_both_ways() -> None:
    """Random FTT-CAN buses (either window order, synchronous and asynchronous traffic, triggered, periodic and
    message-activated tasks)."""
    random_specs_identical_both_ways("ftt-can", 15, 700 * MS, lambda sc: ftt_whole_run.plan(sc) is not None)


@pytest.mark.parametrize(
    "options",
    [
        {"faults": (Fault.parse("master-fail@1s"),)},
        {"stuffing": "exact"},  # random payloads, drawn from the generator the asynchronous frames share
        {"mode": "unsync"},
    ],
)
def test_what_the_ftt_whole_run_does_not_cover_runs_event_by_event(options: dict[str, Any]) -> None:
    cfg = generated("cambada")
    opts = SimOptions(duration_ns=2000 * MS, seed=1, **options)
    assert ftt_whole_run.plan(Scenario(cfg, opts)) is None
    sc, res = run_once(cfg, opts)
    assert res.frames > 0
    if options.get("mode") != "unsync":
        assert sc.protocols["lowlevel"]._got_tm >= 0  # the master ran event by event


@pytest.mark.parametrize("system", ["ntua_sahr", "cambada"])
def test_a_tie_it_cannot_decide_falls_back_to_the_event_path(monkeypatch: pytest.MonkeyPatch, system: str) -> None:
    cfg = generated(system)
    opts = SimOptions(duration_ns=300 * MS, seed=8)
    reference = run_once(cfg, replace(opts, whole_run=False))
    builds = count_builds(monkeypatch)

    def undecided(*_: object) -> None:
        raise Undecided("forced")

    monkeypatch.setattr(flows, "measure_streams", undecided)
    assert_identical(run_once(cfg, opts), reference)
    assert len(builds) == 2, "built again for the event path"


def test_a_task_starting_as_the_data_it_reads_is_written_is_undecided() -> None:
    """Two periodic tasks on one node chained in a flow, the first with no execution time, both starting at 1 ms:
    which reads what depends on which event was queued first, so the stream computation declines."""
    cfg = generated("ntua_sahr")
    steps = (FlowStep(kind="task", refs=("a.first",)), FlowStep(kind="task", refs=("a.second",)))
    tracker = flows.FlowTracker(cfg, replace(cfg.flows[0], steps=steps))
    at = np.array([1 * MS], dtype=np.int64)
    with pytest.raises(Undecided):
        measure_streams(tracker, {"a.first": Stream(True, at, at), "a.second": Stream(True, at, at + 5)})
    later = at + 1  # a nanosecond later it reads the first task's output, one sample of 1 ns
    measure_streams(tracker, {"a.first": Stream(True, at, at), "a.second": Stream(True, later, later + 5)})
    assert tracker.latency.samples == [1]


def test_a_flow_whose_frames_are_all_dropped_has_no_samples() -> None:
    """Every hip_encoder frame lost (a full port): the PID never reads a stamp, so nothing reaches the motor."""
    cfg = generated("ntua_sahr")
    tracker = flows.FlowTracker(cfg, cfg.flows[0])
    at = np.arange(1, 6, dtype=np.int64) * MS
    none = np.empty(0, dtype=np.int64)
    measure_streams(tracker, {
        "mcu_hip.sample": Stream(True, at, at + 5_000),
        "hip_encoder": Stream(False, none, none),
        "pc.pid": Stream(True, at + 100, at + 200),
        "hip_pwm": Stream(False, at + 200, at + 300),
        "mcu_hip.apply_pwm": Stream(True, at + 300, at + 400, "hip_pwm"),
    })
    assert tracker.latency.samples == []


def test_two_items_reaching_different_stamps_at_one_instant_is_undecided() -> None:
    """A final step of two items, each reading its own node's item of the step before: where they reach
    different stamps at one instant, which comes first may decide which stamp finishes, so the stream computation
    declines (cautiously: here neither order would finish one); a nanosecond apart, it gives what the tracker,
    called event by event as the event path calls it, gives."""
    cfg = generated("ntua_sahr")
    steps = (FlowStep(kind="task", refs=("a.first", "b.first")), FlowStep(kind="task", refs=("a.second", "b.second")))
    flow = replace(cfg.flows[0], steps=steps)

    def runs(*starts: int) -> Stream:
        at = np.array(starts, dtype=np.int64)
        return Stream(True, at, at + 10)

    streams = {"a.first": runs(1 * MS, 4 * MS), "b.first": runs(1 * MS, 2 * MS, 4 * MS)}
    streams["a.second"] = runs(3 * MS, 5 * MS)
    with pytest.raises(Undecided):
        measure_streams(flows.FlowTracker(cfg, flow), {**streams, "b.second": runs(3 * MS)})
    streams["b.second"] = runs(3 * MS + 1, 5 * MS + 1)
    tracker = flows.FlowTracker(cfg, flow)
    measure_streams(tracker, streams)
    reference = flows.FlowTracker(cfg, flow)
    events = sorted((int(t), ref, int(e)) for ref, s in streams.items() for t, e in zip(s.first, s.end))
    for t, ref, e in events:
        reference.task_started(ref, t, e)
    # at 3 ms a.second reads stamp 1 ms and b.second 2 ms: neither finishes; at 5 ms both read 4 ms, which the
    # later of them finishes: 5 ms + 1 ns - 4 ms
    assert tracker.latency.samples == reference.latency.samples == [1 * MS + 1]


@pytest.mark.parametrize("drift_ppb", [-99_000_000, 100_000_000, 50_000])
def test_activations_follow_the_node_clock_at_the_largest_drift(drift_ppb: int) -> None:
    """A periodic task's activations computed as an array are the event path's NodeClock.to_global(k * period),
    instant for instant, over 100 s at --drift's limit (100,000 ppm): local * drift there passes 2^63 after 92 s of
    local time, where an int64 product had wrapped round and cut the task's activations 16 s short."""
    from netcfg.sim.engine import NodeClock

    until, period, phase = 100_000 * MS, 1 * MS, 12_345
    clock = NodeClock(phase, drift_ppb)
    expected = []
    k = 0
    while (t := clock.to_global(k * period)) < until:
        expected.append(t)
        k += 1
    got = whole_run.clock_activations(phase, drift_ppb, 0, period, until)
    assert got.tolist() == expected
