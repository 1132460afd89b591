"""How long `netcfg lsp` takes to check a spec again after an edit, warm (inside the running server process:
imports done, EDS and device profiles cached), against the goals of the editor-support issue.

    python benchmarks/bench_lsp.py [--runs 20]

It times netcfg.lsp.server.analyse_quietly, the function the server's worker runs on every edit (check's pipeline on the
editor's text, then the diagnostics converted to LSP's), on ALLEX-2 (specs/allex2.yaml) and on the random 1,000-
message CAN set of benchmarks/random_can.py, after one warm-up check of each: the median and the best of --runs, in
wall time and in this process's CPU time. Beside each, the yardstick a user has without the server: the same spec
checked by a cold `netcfg check` process (median of 3, wall and CPU). The closing `goal:` lines judge the median
wall time; where only the median CPU time meets the goal (on a shared machine the wall time also counts what
other users take), they say so.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

GOALS_MS = {"ALLEX-2": 30.0, "random CAN, 1,000 messages": 100.0}


def warm_recheck_ms(path: Path, runs: int) -> tuple[list[float], list[float]]:
    """(wall times, CPU times) of runs warm re-checks of the spec's text, in ms."""
    from netcfg.lsp.server import analyse_quietly, collect_idle

    text = path.read_text(encoding="utf-8")
    analyse_quietly(path, text)  # warm-up: imports, caches
    collect_idle()
    walls, cpus = [], []
    for n in range(runs):
        edited = text + f"\n# edit {n}\n"  # a new text each time, as an edit makes
        start, cpu = time.perf_counter(), time.process_time()
        analyse_quietly(path, edited)
        walls.append((time.perf_counter() - start) * 1000)
        cpus.append((time.process_time() - cpu) * 1000)
        collect_idle()  # as the server does once it is idle, outside the time an edit waits for
    return walls, cpus


def cold_check_s(path: Path, runs: int = 3) -> tuple[float, float]:
    """(median wall, median CPU) seconds of a whole `netcfg check` process on the spec."""
    walls, cpus = [], []
    for _ in range(runs):
        start = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "netcfg", "check", str(path)], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, cwd=ROOT)  # fmt: skip
        _, _, usage = os.wait4(proc.pid, 0)
        walls.append(time.perf_counter() - start)
        cpus.append(usage.ru_utime + usage.ru_stime)
    return statistics.median(walls), statistics.median(cpus)


def judged(wall_ms: float, cpu_ms: float, goal: float) -> str:
    """Met or not, on wall time; where only the CPU time meets it, said so (the rest is other users' load)."""
    if wall_ms <= goal:
        return "met"
    if cpu_ms <= goal:
        return "met on CPU time (wall time not: the machine is loaded)"
    return f"not met ({cpu_ms / goal:.2f}x over on CPU time)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args()
    from random_can import write_random_can

    specs = {"ALLEX-2": ROOT / "specs" / "allex2.yaml", "random CAN, 1,000 messages": write_random_can(1000)}
    goals = []
    for name, path in specs.items():
        walls, cpus = warm_recheck_ms(path, args.runs)
        wall, cpu = statistics.median(walls), statistics.median(cpus)
        cold_wall, cold_cpu = cold_check_s(path)
        print(f"warm re-check, {name}: median {wall:.1f} ms [{min(walls):.1f}-{max(walls):.1f}], CPU {cpu:.1f} ms; "
              f"a cold `netcfg check` process: {cold_wall:.3f} s, CPU {cold_cpu:.3f} s")  # fmt: skip
        goal = GOALS_MS[name]
        goals.append(f"goal: warm re-check of {name} <= {goal:g} ms: {wall:.1f} ms wall, {cpu:.1f} ms CPU (median "
                     f"of {args.runs}; the cold process {cold_cpu * 1000 / cpu:.0f}x that CPU): "
                     f"{judged(wall, cpu, goal)}")  # fmt: skip
    print()
    for line in goals:
        print(line)


if __name__ == "__main__":
    main()
