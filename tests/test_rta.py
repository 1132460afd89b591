"""CAN response-time analysis (Davis, Burns, Bril, Lukkien 2007): a counter-example to the original analysis,
properties against a brute-force simulation, and the spec-level plumbing."""

from __future__ import annotations

import heapq
import random
from dataclasses import replace
from math import lcm
from pathlib import Path

import pytest
from conftest import bus, check_data, message
from hypothesis import given, settings
from hypothesis import strategies as st

from netcfg.timing import can_rta
from netcfg.timing.can_rta import CanFrame, analyse, tindell_1994

MS = 1_000_000


def test_revised_analysis_catches_what_the_original_misses() -> None:
    """Davis et al. 2007, section 3, with numbers of our own: 125 kbit/s (8 us per bit), 7-byte frames of
    55 + 70 = 125 bits = 1 ms each. A: id 1, T = 2.5 ms; B: id 2, T = 3.5 ms; C: id 3, T = 3.5 ms, D = 3.25 ms.

    Original analysis (first instance only) for C: B_C = 0, w = ceil((w+tau)/2.5) + ceil((w+tau)/3.5) ms:
    w = 2 ms -> R = w + C = 3 ms <= 3.25: "schedulable".
    Revised: busy period t = ceil(t/2.5) + 2 ceil(t/3.5): 3 -> 4 -> 6 -> 7 -> 7 ms, so Q = ceil(7/3.5) = 2.
    q = 0: w = 2 ms, R = 3 ms. q = 1: w = C + ceil((w+tau)/2.5) + ceil((w+tau)/3.5): 3 -> 4 -> 5 -> 6 -> 6 ms,
    R = 6 - 3.5 + 1 = 3.5 ms > 3.25 ms: not schedulable. The brute-force simulation of the synchronous release
    below confirms it: C's second instance, queued at 3.5 ms, waits for B and A and ends at 7 ms.
    """
    c, tau = 1 * MS, 8_000
    frames = [
        CanFrame("A", 1, False, c, 2_500_000),
        CanFrame("B", 2, False, c, 3_500_000),
        CanFrame("C", 3, False, c, 3_500_000, d_ns=3_250_000),
    ]
    original = tindell_1994(frames, tau)
    revised = analyse(frames, tau)
    assert original["C"] == 3 * MS
    assert revised["C"].wcrt_ns == 3_500_000
    assert revised["C"].busy_period_ns == 7 * MS and revised["C"].instances == 2 and revised["C"].worst_instance == 1
    assert revised["C"].schedulable(3_250_000) is False
    simulated = simulate([(1, 125, 312.5), (2, 125, 437.5), (3, 125, 437.5)], [0, 0, 0], 10_000, scale=8000)
    assert simulated[2] == 3_500_000


def test_unbounded_when_higher_priority_load_reaches_one() -> None:
    """A and B fill the bus (0.5 + 0.5): B's busy period never ends, C has no bound."""
    frames = [
        CanFrame("A", 1, False, 500, 1000),
        CanFrame("B", 2, False, 500, 1000),
        CanFrame("C", 3, False, 100, 10_000),
    ]
    r = analyse(frames, 1)
    assert r["A"].wcrt_ns == 500 + 500  # blocked by one frame, then sent
    assert r["B"].wcrt_ns is None and r["C"].wcrt_ns is None


def test_extended_frame_loses_to_standard_frame_with_the_same_base_id() -> None:
    """ISO 11898-1 arbitration: an extended frame sends SRR and IDE recessive where a standard data frame sends
    RTR and IDE dominant, so at an equal 11-bit base identifier the standard frame wins."""
    std = CanFrame("std", 0x123, False, 135, 10_000)
    ext = CanFrame("ext", 0x123 << 18, True, 160, 10_000)
    low_ext = CanFrame("low", 0x122 << 18 | 0x3FFFF, True, 160, 10_000)  # lower base id: wins over both
    r = analyse([std, ext, low_ext], 1)
    assert r["low"].blocking_ns == 160 and r["std"].blocking_ns == 160 and r["ext"].blocking_ns == 0
    assert r["low"].wcrt_ns == 160 + 160
    assert r["std"].wcrt_ns == 160 + 160 + 135
    assert r["ext"].wcrt_ns == 160 + 135 + 160


def simulate(msgs: list[tuple[int, int, float]], offsets: list[int], horizon: int, scale: int = 1) -> list[int]:
    """Non-preemptive fixed-priority CAN, in bit times: msgs are (id, C, T); at every bus-idle instant the
    lowest id among the queued frames wins. Returns each message's largest response time (times `scale`)."""
    releases: list[tuple[float, int]] = []
    for i, (_, _, period) in enumerate(msgs):
        k = 0
        while offsets[i] + k * period < horizon:
            releases.append((offsets[i] + k * period, i))
            k += 1
    releases.sort()
    worst = [0] * len(msgs)
    queued: list[tuple[int, float, int]] = []
    t, r = 0.0, 0
    while r < len(releases) or queued:
        while r < len(releases) and releases[r][0] <= t:
            at, i = releases[r]
            heapq.heappush(queued, (msgs[i][0], at, i))
            r += 1
        if not queued:
            t = releases[r][0]
            continue
        _, at, i = heapq.heappop(queued)
        t += msgs[i][1]
        worst[i] = max(worst[i], round((t - at) * scale))
    return worst


PERIODS = [400, 500, 800, 1000, 2000, 2500, 4000, 5000]
message_sets = st.lists(
    st.tuples(st.integers(0, 8), st.sampled_from(PERIODS), st.integers(0, 4999)), min_size=2, max_size=7
)


def frames_of(spec: list[tuple[int, int, int]]) -> tuple[list[CanFrame], list[tuple[int, int, float]], list[int]]:
    frames, sims, offsets = [], [], []
    for n, (size, period, offset) in enumerate(spec):
        c = 55 + 10 * size  # worst-case frame length in bits (tau = 1 bit, so ns below are bit times)
        frames.append(CanFrame(f"m{n}", n, False, c, period))
        sims.append((n, c, period))
        offsets.append(offset % period)
    return frames, sims, offsets


@settings(max_examples=150, deadline=None, derandomize=True)
@given(message_sets)
def test_no_simulated_response_exceeds_the_analysis(spec: list[tuple[int, int, int]]) -> None:
    frames, sims, offsets = frames_of(spec)
    result = analyse(frames, 1)
    assert any(r.wcrt_ns is not None for r in result.values())  # something is compared: not an empty check
    horizon = max(offsets) + 3 * lcm(*(p for _, _, p in sims))
    for phase in (offsets, [0] * len(sims), [1] * (len(sims) - 1) + [0]):  # random, synchronous, blocked release
        simulated = simulate(sims, phase, horizon)
        for f, s in zip(frames, simulated):
            bound = result[f.name].wcrt_ns
            assert bound is None or s <= bound, (f.name, s, bound, spec)


@settings(max_examples=150, deadline=None, derandomize=True)
@given(message_sets, st.data())
def test_removing_a_message_never_makes_another_worse(spec: list[tuple[int, int, int]], data: st.DataObject) -> None:
    frames, _, _ = frames_of(spec)
    gone = data.draw(st.integers(0, len(frames) - 1))
    before = analyse(frames, 1)
    after = analyse(frames[:gone] + frames[gone + 1 :], 1)
    for name, r in after.items():
        if before[name].wcrt_ns is not None:
            assert r.wcrt_ns is not None and r.wcrt_ns <= before[name].wcrt_ns


def test_spec_level_response_times_and_deadline_errors(tmp_path: Path) -> None:
    """Three frames on a 125 kbit/s bus as in the first test; the low one with a 3.25 ms deadline must fail
    with file, line and the margin (3.5 - 3.25 = 0.25 ms). The example's clocks are exact (clock_tolerance 0):
    the default 100 ppm would let 'fast' repeat 0.35 us sooner (test_clocks.py)."""
    spec = {
        "system": "rta_demo",
        "buses": [{"name": "can1", "protocol": "can", "bitrate": "125 kbit/s", "clock_tolerance": 0}],
        "nodes": [{"name": "a", "buses": ["can1"]}, {"name": "b", "buses": ["can1"]}],
        "messages": [
            {"name": "fast", "id": 1, "producer": "a", "consumers": ["b"], "size": 7, "period": "2.5 ms"},
            {"name": "mid", "id": 2, "producer": "a", "consumers": ["b"], "size": 7, "period": "3.5 ms"},
            {
                "name": "slow",
                "id": 3,
                "producer": "b",
                "consumers": ["a"],
                "size": 7,
                "period": "3.5 ms",
                "deadline": "3.25 ms",
            },
        ],
    }
    report = check_data(tmp_path, spec)
    can1 = bus(report, "can1")
    assert message(can1, "slow")["wcrt_us"] == 3500.0
    assert message(can1, "slow")["schedulable"] is False
    assert message(can1, "fast")["wcrt_us"] == 2000.0  # blocked by one 1 ms frame, then 1 ms of its own
    assert not report["ok"]
    err = report["errors"][0]
    assert err["code"] == "deadline" and "250 us past its deadline" in err["message"] and err["line"] > 1


def test_many_distinct_periods_give_the_same_bound_either_way(monkeypatch: pytest.MonkeyPatch) -> None:
    """A bus of more than MANY_CLASSES distinct (period, jitter) pairs sums eq. 10 and 12's interference with numpy
    per message instead of per class in Python: both are the same integer sum taken in another order, so every
    figure of every response must be equal (600 messages, distinct periods, jitters, one-shots, 100 ppm clocks)."""
    rng = random.Random(22)
    frames = []
    for k in range(600):
        period = None if k % 50 == 49 else rng.randint(2_000, 2_000_000) * 1_000
        frames.append(CanFrame(f"m{k}", k, False, rng.randint(47, 135) * 2_000, period, rng.choice([0, 100_000])))
    scale = sum(f.c_ns / f.t_ns for f in frames if f.t_ns) / 0.6  # about 60 % load
    frames = [replace(f, t_ns=int(f.t_ns * scale) if f.t_ns else None) for f in frames]
    assert len({(f.t_ns, f.j_ns) for f in frames}) > can_rta.MANY_CLASSES
    vectorised = analyse(frames, 2_000, 100)
    monkeypatch.setattr(can_rta, "MANY_CLASSES", len(frames))
    assert analyse(frames, 2_000, 100) == vectorised
    assert sum(r.wcrt_ns is not None for r in vectorised.values()) > 500  # the sums were taken, not skipped
