"""Simulator speed, side by side with its peers (benchmarks/sim_peers.py), on this machine.

    python benchmarks/bench_sim.py [--seconds 10] [--runs 8]

1. A 1 Mbit/s bus loaded to 90 % (sim_peers.fully_loaded_set): netcfg's single run against the plain simpy
   model on the same frames (same release instants: no drift, no phase), with their maximum response times
   compared message by message (they must agree exactly), and python-can's virtual bus for scale.
2. A Monte Carlo batch of the same bus over random phasings and drifts on every core: frames per second.
3. The example systems: CAMBADA (FTT-CAN), ALLEX-2 (CANopen master cycle), large_plant (three buses).
4. The seed specs as a user runs them: `netcfg simulate generated/<system>/runtime.json --duration 600s` as a
   whole process (start-up, imports, reading, simulating, the report), in wall time and in the process's CPU time.
Figures are medians of three runs (seven for netcfg's single run, three batches for Monte Carlo); wall times in
1-3 are whole simulations (set-up included), not process start-up; in 4 they are whole processes.

The goals (the editor-support issue's, which replaced "200x real time on every seed spec"), each printed as a
closing `goal:` line with its figure and whether it is met: the free-running 1 Mbit/s bus of 1 (one run, 90 %
load, no synchronisation) >= 200x real time; ALLEX-2 600 s >= 100x and NTUA SAHR 600 s >= 200x as whole processes;
Monte Carlo >= 1 M frames/s. A whole process is judged on its CPU time (user + system): on an idle machine this
single-threaded process's wall time is the same, and on a shared one the CPU time moves far less; the wall-time
ratio is printed beside it. The free-running bus is judged on the wall time of the run inside this process.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from sim_peers import (  # noqa: E402
    PeerFrame,
    fully_loaded_set,
    median_run,
    python_can_virtual,
    response_maxima_match,
    simpy_can,
    utilisation,
)

from netcfg import runtime  # noqa: E402
from netcfg.commands.simulate import load_document  # noqa: E402
from netcfg.sim.montecarlo import run_batch, run_once  # noqa: E402
from netcfg.sim.scenario import SimOptions  # noqa: E402

SECOND = 1_000_000_000


def peer_spec(frames: list[PeerFrame], bitrate: int = 1_000_000) -> str:
    """The peer set as a netcfg spec: one node per message (so each has its own queue, as in the simpy model),
    sizes recovered from the worst-case frame time (55 + 10 s bits for 11-bit ids at this bit rate)."""
    lines = ["system: loaded_bus", "buses:", f"  - {{name: can0, protocol: can, bitrate: {bitrate // 1000} kbit/s}}"]
    lines.append("nodes:")
    lines.append("  - {name: sink, buses: [can0]}")
    lines += [f"  - {{name: n{f.can_id}, buses: [can0]}}" for f in frames]
    lines.append("messages:")
    for f in frames:
        bits = f.duration_ns * bitrate // SECOND
        size = (bits - 55) // 10
        lines.append(
            f"  - {{name: m{f.can_id}, id: {f.can_id:#x}, size: {size}, producer: n{f.can_id}, consumers: [sink],"
            f" period: {f.period_ns // 1000} us, offset: {f.offset_ns // 1000} us}}"
        )
    return "\n".join(lines) + "\n"


def peer_document(frames: list[PeerFrame]) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "loaded_bus.yaml"
        spec.write_text(peer_spec(frames))
        doc = load_document(spec)
    assert doc is not None, "the peer set must compile"
    return doc


def netcfg_single(doc: dict, seconds: int, **opts: object) -> tuple[float, int, dict[str, int]]:
    cfg = runtime.parse(doc)
    t0 = time.perf_counter()
    _sc, res = run_once(cfg, SimOptions(duration_ns=seconds * SECOND, **opts))  # type: ignore[arg-type]
    wall = time.perf_counter() - t0
    maxima = {name: int(r.max()) for name, r in res.response.items() if len(r)}
    return wall, res.frames, maxima


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=int, default=10)
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--whole-process-only", action="store_true", help="only part 4: the seed specs as processes")
    args = ap.parse_args()
    if args.whole_process_only:
        print()
        for line in whole_process():
            print(line)
        return
    frames = fully_loaded_set()
    doc = peer_document(frames)
    secs = args.seconds
    print(f"1 Mbit/s bus, {len(frames)} messages, worst-case load {utilisation(frames):.3f}, {secs} s simulated")
    walls = []
    for _ in range(7):  # cheap enough for more runs than the peers: a steadier median
        wall, n, maxima = netcfg_single(doc, secs, drift_ppm=0.0, random_phase=False)
        walls.append(wall)
    wall = statistics.median(walls)
    peer = median_run(lambda: simpy_can(frames, secs * SECOND))
    ours = {int(name[1:]): v for name, v in maxima.items()}
    differ = response_maxima_match(ours, peer.max_response_ns)
    virt = median_run(lambda: python_can_virtual(200_000))
    rows = [
        ("netcfg simulate, one run", n, wall, secs / wall),
        ("simpy frame-level model", peer.frames, peer.wall_s, secs / peer.wall_s),
        ("python-can virtual bus (send+recv)", virt.frames, virt.wall_s, None),
    ]
    print(f"  {'':<38}{'frames':>10}{'wall s':>9}{'frames/s':>12}{'x real time':>13}")
    for name, fr, w, x in rows:
        print(f"  {name:<38}{fr:>10,}{w:>9.3f}{fr / w:>12,.0f}{'-' if x is None else f'{x:.1f}x':>13}")
    print(f"  netcfg vs simpy: {peer.wall_s / wall:.1f}x faster; maximum response times differ for {len(differ)} "
          f"of {len(frames)} messages {differ[:5] if differ else ''}")
    free_x = secs / wall
    goal_lines = [f"goal: free-running 1 Mbit/s bus ({len(frames)} messages, 90 % load), one run of {secs} s "
                  f">= {GOAL_FREE_X}x real time: {free_x:.0f}x (median of 7, {secs / max(walls):.0f}-"
                  f"{secs / min(walls):.0f}x; the simpy model {secs / peer.wall_s:.1f}x): "
                  f"{verdict(free_x, GOAL_FREE_X)}"]  # fmt: skip
    jobs = os.cpu_count() or 1
    batches = []
    for _ in range(3):  # a batch is under a second: its median, as one batch moves with the machine by a third
        t0 = time.perf_counter()
        res = run_batch(doc, SimOptions(duration_ns=secs * SECOND), args.runs, jobs)
        batches.append(time.perf_counter() - t0)
    batch_wall = statistics.median(batches)
    print(f"  Monte Carlo: {args.runs} runs x {secs} s on {jobs} cores: {res.frames:,} frames in {batch_wall:.2f} s "
          f"(median of 3 batches, {min(batches):.2f}-{max(batches):.2f} s) = {res.frames / batch_wall:,.0f} frames/s, "
          f"{args.runs * secs / batch_wall:.0f}x real time")
    rate = res.frames / batch_wall
    goal_lines.append(f"goal: Monte Carlo on {jobs} cores >= {GOAL_FRAMES_PER_S:,} frames/s: {rate:,.0f}: "
                      f"{verdict(rate, GOAL_FRAMES_PER_S)}")  # fmt: skip
    print()
    print(f"  {'example (10 s simulated)':<38}{'frames':>10}{'wall s':>9}{'frames/s':>12}{'x real time':>13}")
    for system in ("cambada", "allex2", "large_plant"):
        d = json.loads((ROOT / "generated" / system / "runtime.json").read_text())
        ws = []
        for _ in range(3):
            w, n, _m = netcfg_single(d, 10)
            ws.append(w)
        w = sorted(ws)[1]
        print(f"  {system:<38}{n:>10,}{w:>9.3f}{n / w:>12,.0f}{10 / w:>12.0f}x")
    print()
    goal_lines += whole_process()
    print()
    for line in goal_lines:
        print(line)


# (system, simulated seconds, goal in x real time or None): the goals are the editor-support issue's; CAMBADA's
# figure is printed without a goal of its own. NTUA SAHR's two 15 kHz loops make 600 s about 38 M events, over
# simulate's default --max-events, which is raised for it.
WHOLE = (("allex2", 600, 100), ("ntua_sahr", 600, 200), ("cambada", 600, None))
MAX_EVENTS = 50_000_000
GOAL_FREE_X = 200
GOAL_FRAMES_PER_S = 1_000_000  # a Monte Carlo batch, every core


def verdict(figure: float, goal: float) -> str:
    return "met" if figure >= goal else f"not met ({goal / figure:.1f}x short)"


def whole_process(runs: int = 3) -> list[str]:
    """`netcfg simulate` as a user runs it, median of `runs` processes; returns the goal lines. Wall time moves with
    whatever else the machine runs; the CPU time (user + system) of the process does much less, so the real-time
    ratio is given both ways (simulated seconds per wall second and per CPU second) and the goal is judged on CPU."""
    print(f"  {'netcfg simulate, whole process':<34}{'simulated':>10}{'wall s':>8}{'CPU s':>7}{'CPU min-max':>13}"
          f"{'x wall':>8}{'x CPU':>7}  goal (on CPU)")
    goals = []
    for system, seconds, goal in WHOLE:
        walls, cpus = [], []
        for _ in range(runs):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            subprocess.run(
                [sys.executable, "-m", "netcfg", "simulate", str(ROOT / "generated" / system / "runtime.json"),
                 "--duration", f"{seconds}s", "--max-events", str(MAX_EVENTS), "--format", "json"],
                check=True, stdout=subprocess.DEVNULL, cwd=ROOT,
            )
            walls.append(time.perf_counter() - t0)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
        w, c = statistics.median(walls), statistics.median(cpus)
        x = seconds / c
        print(f"  {system:<34}{seconds:>9}s{w:>8.2f}{c:>7.2f}{f'{min(cpus):.2f}-{max(cpus):.2f}':>13}"
              f"{seconds / w:>7.0f}x{x:>6.0f}x  {'-' if goal is None else f'>= {goal}x'}")
        if goal is not None:
            goals.append(f"goal: simulate {system} {seconds} s, whole process, >= {goal}x real time: {x:.0f}x on CPU "
                         f"({c:.2f} s, median of {runs}), {seconds / w:.0f}x on wall time: {verdict(x, goal)}")
    return goals


if __name__ == "__main__":
    main()
