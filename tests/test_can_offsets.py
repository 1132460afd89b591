"""Offset-aware response times on plain CAN (netcfg.timing.can_offsets): the hand-worked figures, equality with
the offset-free analysis where offsets cannot help, and no simulated response above the bound."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import yaml
from conftest import ROOT, check, runtime_config
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from netcfg.check import analyse_spec
from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import summary
from netcfg.sim.scenario import SimOptions
from netcfg.timing import can_offsets, can_rta

DATA = ROOT / "tests" / "data" / "offsets"


def _wcrt(report: dict[str, Any], key: str = "wcrt_us") -> dict[str, float]:
    return {m["name"]: m[key] for b in report["buses"] for m in b["messages"]}


def test_repro_13_offsets_of_one_node_are_never_queued_together() -> None:
    """Repro 13: s1, s2, s3 leave node a at 0, 5 and 10 ms of a 15 ms period, so none waits for another. An 8-byte
    standard frame is 55 + 80 = 135 bit times with worst-case stuffing (Davis et al. 2007, eq. 1), 540 us at
    250 kbit/s; s3 waits at most for the lower-priority blk already on the bus: R = B + C = 540 + 540 = 1080 us
    (offsets ignored it was 2160 us = B + s1 + s2 + C)."""
    got = _wcrt(check(DATA / "13-plain-rta-offsets.yaml"), "wcrt_plain_can_us")
    assert got["s3"] == 1080.0
    # blk (lowest) meets at most one of s1..s3 in any window shorter than 5 ms: 540 + 540
    assert got["blk"] == 1080.0


def test_two_nodes_hand_worked() -> None:
    """tests/data/offsets/two_nodes.yaml at 500 kbit/s: every frame is 8 bytes, 135 bits, C = 270 us.
    Node a sends a1 (0x10, 10 ms, offset 0), a2 (0x20, 10 ms, 5 ms), a3 (0x30, 20 ms, 2.5 ms); node b sends
    b1 (0x18, 5 ms) and b2 (0x40, 50 ms), without offsets.
    - a3: blocking B = C(b2) = 270. With a3 at the critical instant, a1 is 7.5 ms away and a2 2.5 ms away, both
      beyond the busy period B + C(b1) + C(a3) = 810 us; started by a1 or a2, the busy period (810 us) ends before
      a3 is due. So w = B + C(b1) = 540 and R = 540 + 270 = 810 us (offsets ignored: B + a1 + a2 + b1 + C = 1350).
    - a2: B = 270, a1 is 5 ms away: w = 270 + C(b1) = 540, R = 810 (ignored: 1080).
    - b2: no blocking; node a releases at most one frame in any window under 2.5 ms: w = 270 + C(b1) = 540,
      R = 810 (ignored: 4 * 270 + 270 = 1350).
    - a1 (highest): R = B + C = 540; b1: R = B + C(a1) + C = 810 (no offsets involved, as before)."""
    got = _wcrt(check(DATA / "two_nodes.yaml"))
    assert got == {"a1": 540.0, "a2": 810.0, "a3": 810.0, "b1": 810.0, "b2": 810.0}


frame_sets = st.lists(
    st.tuples(st.integers(1, 0x7FF), st.integers(200, 2_000), st.integers(1, 40), st.integers(0, 3), st.integers(0, 3)),
    min_size=1,
    max_size=12,
    unique_by=lambda x: x[0],
)


@settings(max_examples=60, deadline=None)
@given(frame_sets, st.booleans())
def test_equal_to_the_offset_free_analysis_where_offsets_cannot_help(raw: list[tuple[int, ...]], same: bool) -> None:
    """Without offsets, or with one offset message per node, the bound is can_rta.analyse's exactly (the
    pyCPA-equal analysis of Davis et al. 2007)."""
    frames = [
        can_rta.CanFrame(f"m{i}", ident, False, c * 1000, t * 100_000, j * 10_000)
        for i, (ident, c, t, j, _) in enumerate(raw)
    ]
    plain = can_rta.analyse(frames, 2_000)
    assert can_offsets.analyse(frames, 2_000, {}) == plain
    one_each = {f.name: (f"node{i}", k * 1000) for i, (f, (*_, k)) in enumerate(zip(frames, raw))}
    assert can_offsets.analyse(frames, 2_000, one_each) == plain
    if same:  # offsets of one node: never above the offset-free bound
        together = {f.name: ("a", k * 50_000) for f, (*_, k) in zip(frames, raw)}
        for name, r in can_offsets.analyse(frames, 2_000, together).items():
            if plain[name].wcrt_ns is not None:
                assert r.wcrt_ns is not None and r.wcrt_ns <= plain[name].wcrt_ns


def _simulate(spec_path: Path, seed: int, duration_ns: int) -> list[str]:
    """Simulated responses above their bound, at the critical instant (clocks at 0, no drift: offsets as written)
    and with random phases and drift between the nodes."""
    cfg = runtime_config(spec_path)
    out = []
    for opts in (
        SimOptions(duration_ns=duration_ns, seed=seed, random_phase=False, drift_ppm=0.0),
        SimOptions(duration_ns=duration_ns, seed=seed),
    ):
        result = summary(run_once(cfg, opts)[1])
        out += [
            f"{m['name']}: {m['response_us']['max']} > {m['wcrt_us']}"
            for m in result["messages"]
            if m["within_analysis"] is False
        ]
    return out


def test_two_nodes_simulated_inside_the_bound() -> None:
    assert _simulate(DATA / "two_nodes.yaml", 0, 400_000_000) == []


@st.composite
def offset_specs(draw: st.DrawFn) -> dict[str, Any]:
    """Plain CAN, 2-3 nodes, each sending 1-4 periodic messages from harmonic periods with offsets (some jitter)."""
    nodes = [f"n{i}" for i in range(draw(st.integers(2, 3)))]
    ids = iter(draw(st.lists(st.integers(1, 0x7FF), min_size=12, max_size=12, unique=True)))
    messages = []
    for node in nodes:
        for _ in range(draw(st.integers(1, 4))):
            period = draw(st.sampled_from([1_000, 2_000, 4_000, 5_000, 10_000]))
            msg: dict[str, Any] = {
                "name": f"m{len(messages)}",
                "id": next(ids),
                "producer": node,
                "consumers": [n for n in nodes if n != node][:1],
                "size": draw(st.integers(0, 8)),
                "period": f"{period} us",
                "offset": f"{draw(st.integers(0, period - 1)) // 100 * 100} us",
            }
            if draw(st.integers(0, 3)) == 0:
                msg["jitter"] = f"{draw(st.integers(1, period // 10))} us"
            messages.append(msg)
    return {
        "system": "random_offsets",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": draw(st.sampled_from(["125 kbit/s", "500 kbit/s"]))}],
        "nodes": [{"name": n, "buses": ["can0"]} for n in nodes],
        "messages": messages,
    }


def test_random_offset_specs_simulated_inside_the_bound() -> None:
    """The soundness relation with offsets: simulated with the given offsets, no response exceeds its bound."""
    runs = []

    @settings(max_examples=12, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
    @given(offset_specs())
    def run(spec: dict[str, Any]) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "spec.yaml"
            path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
            _, report = analyse_spec(path)
            if report["errors"]:
                return
            runs.append(spec)
            assert _simulate(path, len(runs), 100_000_000) == []

    run()
    assert runs, "no random spec passed check: the strategy tests nothing"
