"""The switched Ethernet/UDP simulator (netcfg.sim.ethernet) against seed 001 and netcfg's own analysis.

Sources of the numbers:
* seed 001, section 6.2.2.12 and eq. 6.4: full-duplex 100 Mbit/s, a minimum frame of 84 bytes on the wire takes
  (84 x 8) / 100e6 = 6.72 us, so one link carries at most f_max = 148.81 kHz of such frames; section 6.3.2: each
  SAHR MCU sends its encoder (message 0x42, 4 bytes + the id byte: still a minimum frame) at 15 kHz;
* specs/ntua_sahr.yaml as built into generated/ntua_sahr/runtime.json (rates, topology, the analysis' wcrt_ns);
* `netcfg check` (netcfg.check.check) for the analysed link utilisations;
* netcfg.timing.flows for the flows' analysed latency ranges (runtime.json flows[].latency_min_ns/max_ns): the
  ntua_sahr flow hip_loop is 81,880 to 310,274 ns.
"""

from __future__ import annotations

import heapq
import json
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import ROOT, SPECS, check, runtime_config

import netcfg.runtime as rt
from netcfg.sim.ethernet import QUEUE_FRAMES, EthernetNetwork
from netcfg.sim.faults import Fault, FaultError
from netcfg.sim.results import collect, summary
from netcfg.sim.scenario import Scenario, SimOptions, simulate

SAHR_RUNTIME = ROOT / "generated" / "ntua_sahr" / "runtime.json"
SECOND = 1_000_000_000
MIN_FRAME_NS = 6_720  # seed 001: (84 x 8) / 100 Mbit/s
ENCODER_HZ = 15_000  # seed 001 section 6.3.2 and specs/ntua_sahr.yaml
PID_HZ = 1_000  # specs/ntua_sahr.yaml: pc.pid every 1 ms, sending hip_pwm as it finishes


def network(sc: Scenario, bus: str = "lan") -> EthernetNetwork:
    net = sc.protocols[bus]
    assert isinstance(net, EthernetNetwork)
    return net


def by_name(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    return {r["name"]: r for r in rows}


def message_rows(sc: Scenario, bus: str = "lan") -> dict[str, dict[str, Any]]:
    """Per message, the run's summary row (count = deliveries, response_us = latency, wcrt_us, lost) with the
    network's own figures beside it (chained, sent, in_flight, processed_us)."""
    doc = summary(collect(sc))
    rows = by_name(doc["messages"])
    return {name: {**rows[name], **row} for name, row in by_name(doc["protocols"][bus][0]["messages"]).items()}


def link_rows(rows: list[dict[str, Any]]) -> dict[tuple[str, str], dict[str, Any]]:
    return {(r["from"], r["to"]): r for r in rows}


@pytest.fixture(scope="module")
def sahr() -> Scenario:
    return simulate(rt.load(SAHR_RUNTIME), SimOptions(duration_ns=SECOND, seed=1))


@pytest.fixture(scope="module")
def sahr_analysis() -> dict[str, Any]:
    report = check(SPECS / "ntua_sahr.yaml")
    assert report["ok"], report["errors"]
    return report["buses"][0]


def test_fifteen_khz_for_one_second(sahr: Scenario) -> None:
    """15 kHz for 1 s: 15,000 encoder frames, +-1 for the MCU's clock phase and drift (a frame released in the
    last ~20 us is still on its way); none lost on a 20 % loaded network. spring_encoder is free-running at its
    exact rate; hip_encoder is chained to mcu_hip.sample (flow hip_loop: the task before it runs on its producer at
    its rate, netcfg.timing.flows._sent_by_producer), so each is released as a sample run ends."""
    net = network(sahr)
    rep = message_rows(sahr)
    for name in ("hip_encoder", "spring_encoder"):
        row = rep[name]
        assert abs(row["sent"] - ENCODER_HZ) <= 1, row
        assert abs(row["count"] - ENCODER_HZ) <= 1, row
        assert row["lost"] == 0
        assert row["count"] + row["in_flight"] == row["sent"]
    assert rep["hip_encoder"]["chained"] and not rep["spring_encoder"]["chained"]
    hip = next(r for name, r, _ in net.records() if name == "hip_encoder")
    sample_ends = {end for _, end in sahr.task_runs["mcu_hip.sample"]}
    assert set(hip.tolist()) <= sample_ends  # tx_delay is 0 in the spec
    assert len(hip) >= len(sample_ends) - 1
    rel = next(r for name, r, _ in net.records() if name == "spring_encoder")
    assert len(rel) == rep["spring_encoder"]["count"]
    # the exact rate (1e9 / 15,000 = 66,666.67 ns, not a rounded period) on a clock within SimOptions' default
    # +-50 ppm: consecutive releases 66,666 or 66,667 ns apart, give or take 50e-6 x 66,667 ns = 3.3 ns
    gaps = np.diff(np.sort(rel))
    assert gaps.min() >= 66_666 - 4 and gaps.max() <= 66_667 + 4
    assert (rel.max() - rel.min()) / (len(rel) - 1) == pytest.approx(SECOND / ENCODER_HZ, rel=50e-6)


def test_link_utilisation_matches_the_analysis(sahr: Scenario, sahr_analysis: dict[str, Any]) -> None:
    """sw1 -> pc carries both encoders: 2 x 15,000 frames/s x 84 bytes x 8 bit / 100 Mbit/s = 0.2016 (seed 001's
    figures), which is what `netcfg check` reports for that link. Every link's measured busy time over the run
    is within 1 % of the analysed utilisation."""
    analysed = {(r["from"], r["to"]): r["utilization"] for r in sahr_analysis["links"]}
    assert analysed[("sw1", "pc")] == pytest.approx(2 * ENCODER_HZ * 84 * 8 / 100e6)
    measured = link_rows(network(sahr).report()["links"])
    assert set(measured) == set(analysed)
    for key, util in analysed.items():
        assert measured[key]["utilization"] == pytest.approx(util, rel=0.01), key
        assert measured[key]["utilization_offered"] == pytest.approx(util, abs=1e-6), key


def test_latencies_within_the_analysed_wcrt(sahr: Scenario) -> None:
    """Every message's simulated worst latency stays within its analysed wcrt_ns (runtime.json); the best case is
    two store-and-forward hops of a minimum frame with no cable, switch or node delay (seed 001, eq. 6.3/6.4)."""
    cfg = sahr.cfg
    seen = 0
    for name, rel, end in network(sahr).records():
        wcrt = cfg.message(name).wcrt_ns
        assert wcrt is not None
        lat = end - rel
        assert len(lat) > 0
        assert int(lat.max()) <= wcrt, (name, int(lat.max()), wcrt)
        assert int(lat.min()) == 2 * MIN_FRAME_NS, name
        seen += 1
    assert seen == 3


def overloaded_sahr(rate_hz: int) -> rt.RuntimeConfig:
    data = json.loads(SAHR_RUNTIME.read_text(encoding="utf-8"))
    for m in data["messages"]:
        if m["name"] in ("hip_encoder", "spring_encoder"):
            m["rate_hz"] = [rate_hz, 1]
            m["period_ns"] = m["interval_ns"] = round(SECOND / rate_hz)
            # the sampling tasks keep their 15 kHz, so they no longer send the encoders as they finish
            # (netcfg.timing.flows.sending_tasks: same rate only): the encoders run free at the new rate
            m["sent_by"] = []
    return rt.parse(data)


def test_eighty_khz_overloads_the_pc_port(tmp_path: Path) -> None:
    """At 80 kHz per MCU the pc port must carry 160 kHz > f_max = 148.81 kHz (seed 001: f_transm < f_max / n, n = 2):
    the analysis says 107.5 %. The port's FIFO fills to its capacity and the excess is lost and counted. A
    saturated port sends at most duration / 6.72 us frames; everything else sent is lost or, at most one queue's
    worth, still held when the run ends."""
    spec = yaml.safe_load((SPECS / "ntua_sahr.yaml").read_text(encoding="utf-8"))
    for m in spec["messages"]:
        if m["name"].endswith("_encoder"):
            m["rate"] = "80 kHz"
    path = tmp_path / "sahr80.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    link = {(r["from"], r["to"]): r for r in check(path)["buses"][0]["links"]}[("sw1", "pc")]
    assert link["utilization"] == pytest.approx(1.0752) and not link["ok"]

    duration = SECOND // 5
    sc = simulate(overloaded_sahr(80_000), SimOptions(duration_ns=duration, seed=2))
    port = link_rows(network(sc).report()["links"])[("sw1", "pc")]
    msgs = message_rows(sc)
    encoders = [msgs["hip_encoder"], msgs["spring_encoder"]]
    assert port["max_queue"] == QUEUE_FRAMES
    assert port["lost"] > 0
    assert port["lost"] == sum(m["lost"] for m in encoders)
    for m in encoders:
        assert m["lost"] > 0
        assert m["lost"] + m["count"] + m["in_flight"] == m["sent"], m
        # the analysis' bound assumed < 100 %
        assert m["wcrt_us"] is not None and m["response_us"]["max"] > m["wcrt_us"] and m["within_analysis"] is False
    sent = sum(m["sent"] for m in encoders)
    capacity = duration // MIN_FRAME_NS
    assert abs(port["lost"] - (sent - capacity)) <= QUEUE_FRAMES + 4
    assert port["utilization"] > 0.99
    # a queue of 64 minimum frames ahead: about 64 x 6.72 us = 430 us of delay (seed 001: "unwanted latency ...
    # equal to the time required to empty the respective buffers")
    assert max(m["response_us"]["max"] for m in encoders) == pytest.approx(QUEUE_FRAMES * MIN_FRAME_NS / 1000, rel=0.05)


def test_queue_capacity_is_a_parameter() -> None:
    """A smaller egress buffer (the options' eth_queue_frames) loses more and never holds more."""
    cfg = overloaded_sahr(80_000)
    duration = SECOND // 20
    small = simulate(cfg, SimOptions(duration_ns=duration, seed=2, eth_queue_frames=8))
    big = simulate(cfg, SimOptions(duration_ns=duration, seed=2))
    p_small = link_rows(network(small).report()["links"])[("sw1", "pc")]
    p_big = link_rows(network(big).report()["links"])[("sw1", "pc")]
    assert p_small["max_queue"] == 8 and p_big["max_queue"] == QUEUE_FRAMES
    assert p_small["lost"] > p_big["lost"]


def test_pc_processing_is_a_separate_latency(sahr: Scenario) -> None:
    """The PC consuming frames one at a time, 20..30 us each (this test's parameter): 30,000 frames/s x 25 us mean
    = 75 % busy. Every frame is processed at least 20 us after its delivery, in FIFO order; the delivery instants
    (what the analysis bounds) do not change."""
    service = (20_000, 30_000)
    sc = simulate(rt.load(SAHR_RUNTIME), SimOptions(duration_ns=SECOND, seed=1, eth_processing_ns={"pc": service}))
    net = network(sc)
    rep = net.report()
    assert rep["receivers"]["pc"]["utilization"] == pytest.approx(2 * ENCODER_HZ * 25e-6, abs=0.02)
    delivered = {n: (r, e) for n, r, e in net.records()}
    base = {n: (r, e) for n, r, e in network(sahr).records()}
    processed = {n: (r, e) for n, r, e in net.processed_records()}
    for name in ("hip_encoder", "spring_encoder"):
        assert np.array_equal(delivered[name][1], base[name][1])
        rel_d, end_d = delivered[name]
        rel_p, end_p = processed[name]
        done = dict(zip(rel_p.tolist(), end_p.tolist()))
        gaps = [done[r] - e for r, e in zip(rel_d.tolist(), end_d.tolist()) if r in done]
        assert len(gaps) >= len(rel_d) - 2
        assert min(gaps) >= service[0]


def test_crashed_sender_stops() -> None:
    """crash:NODE@t (netcfg.sim.faults: "the node stops: it sends nothing more"): about half of 15,000 frames in 1 s
    when the spring MCU crashes at 500 ms; nothing of it is delivered later than one worst-case delay after that."""
    crash = SECOND // 2
    sc = simulate(
        rt.load(SAHR_RUNTIME), SimOptions(duration_ns=SECOND, seed=1, faults=(Fault.parse("crash:mcu_spring@500ms"),))
    )
    rep = message_rows(sc)
    assert abs(rep["spring_encoder"]["sent"] - ENCODER_HZ // 2) <= 1
    assert abs(rep["hip_encoder"]["sent"] - ENCODER_HZ) <= 1
    _, _, end = next(r for r in network(sc).records() if r[0] == "spring_encoder")
    assert int(end.max()) <= crash + sc.cfg.message("spring_encoder").wcrt_ns  # type: ignore[operator]


TWO_SWITCHES = """
system: two_switches
buses:
  - name: lan
    protocol: ethernet-udp
    bitrate: 100 Mbit/s
    ethernet:
      switches:
        - name: sw1
          latency: 2 us
          ports:
            - {port: 1, to: a, cable: 20}
            - {port: 2, to: b, cable: 20}
            - {port: 3, to: sw2, cable: 50}
        - name: sw2
          latency: 2 us
          ports:
            - {port: 1, to: pc, cable: 10}
            - {port: 2, to: logger, cable: 10}
nodes:
  - {name: a, ip: 10.0.0.1, buses: [lan], tx_delay: 3 us}
  - {name: b, ip: 10.0.0.2, buses: [lan]}
  - {name: pc, ip: 10.0.0.3, buses: [lan], rx_delay: 4 us}
  - {name: logger, ip: 10.0.0.4, buses: [lan]}
messages:
  - {name: a_state, id: 0x10, producer: a, consumers: [pc, logger], size: 30, rate: 10 kHz}
  - {name: b_state, id: 0x11, producer: b, consumers: [pc], size: 4, rate: 20 kHz}
  - {name: pc_cmd, id: 0x20, producer: pc, consumers: [a, b], size: 1, rate: 1 kHz}
"""


def test_two_switches_multicast_against_the_analysis(tmp_path: Path) -> None:
    """Cables, switch latency, Tpre/Tpost, a switch-to-switch link and multicast, compiled by netcfg itself: every
    message within its analysed wcrt_ns, every link within 1 % of its analysed utilisation, a multicast crossing
    sw1 -> sw2 once per frame (netcfg.timing.ethernet: "a switch forwards a multicast once per egress port") and
    reaching both consumers."""
    from netcfg.check import analyse_spec
    from netcfg.emit.runtime_json import runtime_document

    path = tmp_path / "two.yaml"
    path.write_text(TWO_SWITCHES, encoding="utf-8")
    model, report = analyse_spec(path)
    assert model is not None and report["ok"], report["errors"]
    cfg = rt.parse(json.loads(json.dumps(runtime_document(model, report))))
    sc = simulate(cfg, SimOptions(duration_ns=SECOND // 2, seed=5))
    net = network(sc)
    for name, rel, end in net.records():
        wcrt = cfg.message(name).wcrt_ns
        assert wcrt is not None and len(rel) > 0
        assert int((end - rel).max()) <= wcrt, (name, int((end - rel).max()), wcrt)
    # eq. 6.3 with Twait = Tqueue = 0, from the spec: Tpre + hops x Tframe + Tprop + 2 x Tmux + Tpost, Tprop for
    # 20 + 50 + 10 m at 0.7 c rounded per cable (95 + 238 + 48 ns); a_state is 30 + 1 bytes: 97 on the wire
    prop = 95 + 238 + 48
    lowest = {name: int((end - rel).min()) for name, rel, end in net.records()}
    assert lowest["pc_cmd"] == 3 * MIN_FRAME_NS + prop + 2 * 2_000 == cfg.message("pc_cmd").wcrt_ns
    assert lowest["a_state"] == 3_000 + 3 * 97 * 80 + prop + 2 * 2_000  # to the logger, which has no Tpost
    assert lowest["b_state"] == 3 * MIN_FRAME_NS + prop + 2 * 2_000 + 4_000  # to the pc, Tpost 4 us
    rep = net.report()
    links = link_rows(rep["links"])
    for row in report["buses"][0]["links"]:
        assert links[(row["from"], row["to"])]["utilization"] == pytest.approx(row["utilization"], rel=0.01)
    a_state = message_rows(sc)["a_state"]
    assert a_state["count"] + a_state["in_flight"] == 2 * a_state["sent"]
    from_a = links[("a", "sw1")]["frames"]
    assert abs(links[("sw2", "logger")]["frames"] - from_a) <= 1
    assert abs(links[("sw1", "sw2")]["frames"] - from_a - links[("b", "sw1")]["frames"]) <= 2


# -- chained sends, FIFO order against a plain reference, faults ------------------------------------------------


def test_hip_loop_within_the_analysed_range(sahr: Scenario) -> None:
    """hip_loop (mcu_hip.sample -> hip_encoder -> pc.pid -> hip_pwm -> mcu_hip.apply_pwm) measured as data age stays
    inside the analysis' range, runtime.json flows[]: 81,880 ns = sample BCET 5 us + 2 x 6.72 us + pid BCET 50 us
    + 2 x 6.72 us (both messages chained, so no sampling wait for them), 310,274 ns = sample WCET 10 us + hip_encoder
    wcrt 20.16 us + pid's sampling wait (the encoder's refresh, 66,667 ns, on a node clock up to 100 ppm slow:
    + ceil(66,667 x 100e-6) = 7 ns) + pid WCET 200 us + hip_pwm wcrt 13.44 us. One sample per pid run: 1,000 in 1 s,
    +-1 for the PC's clock phase and drift."""
    flow = sahr.cfg.flows[0]
    assert flow.name == "hip_loop"
    assert (flow.latency_min_ns, flow.latency_max_ns) == (81_880, 310_274)
    assert flow.latency_min_ns == 5_000 + 2 * MIN_FRAME_NS + 50_000 + 2 * MIN_FRAME_NS
    assert flow.latency_max_ns == 10_000 + 20_160 + (66_667 + 7) + 200_000 + 13_440
    tracker = next(tr for tr in sahr.flows if tr.name == "hip_loop")
    samples = np.asarray(tracker.latency.samples)
    assert abs(len(samples) - PID_HZ) <= 1
    assert flow.latency_min_ns <= int(samples.min()) and int(samples.max()) <= flow.latency_max_ns
    # hip_pwm is chained to pc.pid: released as a pid run ends, delivered 2 x 6.72 us later (nothing shares its links)
    net = network(sahr)
    rel, end = next((r, e) for name, r, e in net.records() if name == "hip_pwm")
    assert set(rel.tolist()) <= {e for _, e in sahr.task_runs["pc.pid"]}
    assert set((end - rel).tolist()) == {2 * MIN_FRAME_NS}
    # and mcu_hip.apply_pwm starts on each delivery (message-activated, rx_delay 0)
    starts = {s for s, _ in sahr.task_runs["mcu_hip.apply_pwm"]}
    assert set(end.tolist()) <= starts


def reference_deliveries(
    frames: dict[str, list[int]],
    paths: dict[str, list[list[str]]],
    frame_ns: dict[str, int],
    prop_ns: dict[tuple[str, str], int],
    tx_ns: dict[str, int],
    switch_ns: dict[str, int],
    rx_ns: dict[str, int],
) -> dict[str, list[tuple[int, int]]]:
    """A plain frame-by-frame model of the same network, written independently for this test: every link a FIFO
    served in order of arrival, a frame handed to its producer's link tx_delay after release, passed on after the
    cable and the switch's latency (once per link, however many consumers lie behind it), delivered rx_delay after
    the last link. -> message: sorted (release, end), one per consumer."""
    nxt: dict[tuple[str, tuple[str, str]], set[tuple[str, str]]] = {}  # (message, link) -> next links
    for name, ps in paths.items():
        for path in ps:
            hops = list(pairwise(path))
            for a, b in pairwise(hops):
                nxt.setdefault((name, a), set()).add(b)
    events: list[tuple[int, int, str, int, tuple[str, str]]] = []  # (arrival, seq, message, release, link)
    seq = 0
    for name, releases in frames.items():
        first = (paths[name][0][0], paths[name][0][1])
        for r in releases:
            seq += 1
            heapq.heappush(events, (r + tx_ns.get(first[0], 0), seq, name, r, first))
    free: dict[tuple[str, str], int] = {}
    out: dict[str, list[tuple[int, int]]] = {name: [] for name in frames}
    consumers = {name: {path[-1] for path in ps} for name, ps in paths.items()}
    while events:
        t, _, name, r, link = heapq.heappop(events)
        end = max(t, free.get(link, 0)) + frame_ns[name]
        free[link] = end
        recv = end + prop_ns.get(link, 0)
        if link[1] in consumers[name]:
            out[name].append((r, recv + rx_ns.get(link[1], 0)))
        for b in sorted(nxt.get((name, link), ())):
            seq += 1
            heapq.heappush(events, (recv + switch_ns.get(link[1], 0), seq, name, r, b))
    return {name: sorted(v) for name, v in out.items()}


def compare_with_reference(net: EthernetNetwork, expected: dict[str, list[tuple[int, int]]], before: int) -> int:
    """Every delivery of a frame released before `before` as the reference has it; -> how many were queued."""
    queued = 0
    for name, rel, end in net.records():
        got = sorted(zip(rel.tolist(), end.tolist()))
        want = [x for x in expected[name] if x[0] < before]
        assert [x for x in got if x[0] < before] == want, name
        lowest = min(e - r for r, e in want)
        queued += sum(1 for r, e in want if e - r > lowest)
    return queued


def test_chained_and_free_running_frames_share_a_port_in_fifo_order(sahr: Scenario) -> None:
    """sw1 -> pc carries hip_encoder (chained: submitted as mcu_hip.sample ends, frame by frame) and spring_encoder
    (free-running: computed a chunk ahead). Recomputed from the releases alone by reference_deliveries, every
    delivery is the same to the nanosecond, so no frame was served out of arrival order on the shared port; the two
    encoders slide against each other (different clocks), so frames do queue there. Frames released in the last
    2 ms are left out (ones still on their way at the end are not in the records)."""
    net = network(sahr)
    frames = {name: sorted(set(rel.tolist())) for name, rel, _ in net.records()}
    paths = {
        "hip_encoder": [["mcu_hip", "sw1", "pc"]],
        "spring_encoder": [["mcu_spring", "sw1", "pc"]],
        "hip_pwm": [["pc", "sw1", "mcu_hip"]],
    }
    expected = reference_deliveries(frames, paths, dict.fromkeys(paths, MIN_FRAME_NS), {}, {}, {}, {})
    queued = compare_with_reference(net, expected, SECOND - 2_000_000)
    assert queued > 0


TWO_SWITCHES_CHAINED = (
    TWO_SWITCHES.replace(
        "  - {name: a, ip: 10.0.0.1, buses: [lan], tx_delay: 3 us}",
        "  - {name: a, ip: 10.0.0.1, buses: [lan], tx_delay: 3 us,\n"
        "     tasks: [{name: ctl, period: 100 us, wcet: 20 us, bcet: 5 us}]}",
    ).replace(
        "  - {name: pc, ip: 10.0.0.3, buses: [lan], rx_delay: 4 us}",
        "  - {name: pc, ip: 10.0.0.3, buses: [lan], rx_delay: 4 us,\n"
        "     tasks: [{name: use, on_message: a_state, wcet: 5 us, bcet: 2 us}]}",
    )
    + """flows:
  - name: a_to_pc
    chain: [a.ctl, a_state, pc.use]
"""
)


def test_two_switches_with_a_chained_multicast(tmp_path: Path) -> None:
    """The two-switch network with a_state chained to a.ctl (every 100 us, the message's 10 kHz): a_state crosses
    sw1 -> sw2 with free-running b_state and sw2 -> pc with free-running-path traffic, then fans out to pc and the
    logger. Against reference_deliveries (cables 20 + 50 + 10 m: 95, 238 and 48 ns, as in the test above; switch
    latency 2 us; tx_delay 3 us at a, rx_delay 4 us at the pc; a_state 31 bytes -> 97 on the wire, 7.76 us) every
    delivery matches; the flow stays within its analysed range."""
    path = tmp_path / "two.yaml"
    path.write_text(TWO_SWITCHES_CHAINED, encoding="utf-8")
    cfg = runtime_config(path)
    duration = SECOND // 2
    sc = simulate(cfg, SimOptions(duration_ns=duration, seed=5))
    net = network(sc)
    assert net.report()["messages"][0]["chained"]
    frames = {name: sorted(set(rel.tolist())) for name, rel, _ in net.records()}
    paths = {
        "a_state": [["a", "sw1", "sw2", "pc"], ["a", "sw1", "sw2", "logger"]],
        "b_state": [["b", "sw1", "sw2", "pc"]],
        "pc_cmd": [["pc", "sw2", "sw1", "a"], ["pc", "sw2", "sw1", "b"]],
    }
    cable = {("a", "sw1"): 95, ("b", "sw1"): 95, ("sw1", "sw2"): 238, ("sw2", "pc"): 48, ("sw2", "logger"): 48}
    prop = {**cable, **{(b, a): ns for (a, b), ns in cable.items()}}
    sizes = {"a_state": 97 * 80, "b_state": MIN_FRAME_NS, "pc_cmd": MIN_FRAME_NS}
    expected = reference_deliveries(
        frames, paths, sizes, prop, {"a": 3_000}, {"sw1": 2_000, "sw2": 2_000}, {"pc": 4_000}
    )
    queued = compare_with_reference(net, expected, duration - 2_000_000)
    assert queued > 0
    flow = sc.cfg.flows[0]
    samples = np.asarray(sc.flows[0].latency.samples)
    assert len(samples) > 0 and flow.latency_max_ns is not None
    assert flow.latency_min_ns <= int(samples.min()) and int(samples.max()) <= flow.latency_max_ns


def test_lose_on_ethernet() -> None:
    """lose:MESSAGE@T (netcfg.sim.faults: "the first instance of MESSAGE queued at or after that instant is lost")
    for a free-running message (spring_encoder, every 66.67 us) and a chained one (hip_pwm, as pc.pid ends, every
    1 ms +- the pid's 50..200 us run): one instance each is lost and counted, and the releases delivered show
    one gap of about two periods around T."""
    at = 100_000_000
    faults = (Fault.parse("lose:spring_encoder@100ms"), Fault.parse("lose:hip_pwm@100ms"))
    sc = simulate(rt.load(SAHR_RUNTIME), SimOptions(duration_ns=SECOND // 5, seed=1, faults=faults))
    net = network(sc)
    rep = message_rows(sc)
    assert net.lost_by_message() == {"hip_encoder": 0, "spring_encoder": 1, "hip_pwm": 1}
    for name, period in (("spring_encoder", SECOND / ENCODER_HZ), ("hip_pwm", SECOND / PID_HZ)):
        row = rep[name]
        assert row["lost"] == 1 and row["count"] + row["in_flight"] + row["lost"] == row["sent"]
        rel = next(r for n, r, _ in net.records() if n == name)
        gaps = np.diff(rel)
        wide = np.flatnonzero(gaps > 1.5 * period)
        assert len(wide) == 1, name
        assert rel[wide[0]] < at < rel[wide[0] + 1]
    with pytest.raises(FaultError, match="no CAN or Ethernet message named 'nothing'"):
        Scenario(rt.load(SAHR_RUNTIME), SimOptions(faults=(Fault.parse("lose:nothing@1ms"),)))


@pytest.mark.parametrize("text", ["ber=1e-6:lan", "bit-error@1ms:lan"])
def test_bit_errors_are_can_only(text: str) -> None:
    """Bit errors are modelled on CAN buses only: naming an Ethernet bus says so."""
    with pytest.raises(FaultError, match="bus 'lan' is Ethernet; bit errors are simulated on CAN buses only"):
        Scenario(rt.load(SAHR_RUNTIME), SimOptions(faults=(Fault.parse(text),)))
    with pytest.raises(FaultError, match="CAN only"):
        Scenario(rt.load(SAHR_RUNTIME), SimOptions(faults=(Fault.parse(text.split(":")[0]),)))


def test_crashed_chained_sender_and_consumer() -> None:
    """crash:mcu_hip@500ms: its sample task stops, so hip_encoder goes out about 15,000 x 0.5 = 7,500 times; the
    hip_pwm frames the PC still sends to it (1 kHz x 0.5 s = 500) are lost, and the loop ends then."""
    crash = SECOND // 2
    sc = simulate(
        rt.load(SAHR_RUNTIME), SimOptions(duration_ns=SECOND, seed=1, faults=(Fault.parse("crash:mcu_hip@500ms"),))
    )
    rep = message_rows(sc)
    assert abs(rep["hip_encoder"]["sent"] - ENCODER_HZ // 2) <= 1
    assert abs(rep["hip_pwm"]["sent"] - PID_HZ) <= 1
    assert abs(rep["hip_pwm"]["lost"] - PID_HZ // 2) <= 1
    assert rep["hip_pwm"]["count"] + rep["hip_pwm"]["lost"] + rep["hip_pwm"]["in_flight"] == rep["hip_pwm"]["sent"]
    assert max(s for s, _ in sc.task_runs["mcu_hip.apply_pwm"]) < crash


def test_only_chained_messages_are_submitted(sahr: Scenario) -> None:
    """A free-running message is sent by its own stream; submitting it is a mistake, said so."""
    with pytest.raises(ValueError, match="free-running"):
        network(sahr).submit("spring_encoder")
