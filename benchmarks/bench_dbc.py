"""How long `netcfg check F.dbc` takes, whole process, against cantools' own `load_file` of the same file, also a
whole process: a Python process that imports cantools and loads the file, the floor any cantools-based tool pays.

    python benchmarks/bench_dbc.py [--runs N] [FILE.dbc ...]

The two processes run in turn (netcfg, cantools, netcfg, ...), so each pair shares the machine's state of the
moment, and the ratio netcfg / cantools is the median of the pairs' ratios. Prints, per file, the median
[min-max] wall time and the median CPU time (user + system, which a loaded machine disturbs less) in seconds of
both, and the ratios. Whole processes are compared because that is what a user waits for: `netcfg check F.dbc`
must import cantools and load the file too, so cantools' own process is the fair floor; netcfg's own work on top
(its imports, the check, the report) is what the ratio measures.

The goal (the editor-support issue's): at most 1.3x cantools' load, on the random 1,000-message set of
benchmarks/random_can.py written as a DBC by netcfg's emitter and on the largest opendbc file of the tests
(cadillac_ct6_object.dbc, 232 kB, 294 messages); a closing `goal:` line each, judged on the CPU-time ratio (the
wall-time ratio beside it). The corpus' other large files are timed without a goal. No assertions.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
CORPUS = ROOT / "tests" / "data" / "dbc"
LARGEST = "cadillac_ct6_object.dbc"  # the largest file of the corpus (bytes)
FILES = [LARGEST, "gm_global_a_lowspeed_1818125.dbc", "vw_mqb.dbc", "hyundai_2015_ccan.dbc"]
CANTOOLS_ONLY = "import sys, cantools; cantools.database.load_file(sys.argv[1], strict=False)"
GOAL_RATIO = 1.3


def run(cmd: list[str]) -> tuple[float, float]:
    """(wall, CPU) seconds of one process."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    _, _, usage = os.wait4(proc.pid, 0)
    return time.perf_counter() - start, usage.ru_utime + usage.ru_stime


def paired(path: Path, runs: int) -> dict[str, list[float]]:
    """runs pairs of (netcfg check, cantools load), in turn, after one warm-up of each."""
    check = [sys.executable, "-m", "netcfg", "check", str(path), "--bitrate", "500k"]
    load = [sys.executable, "-c", CANTOOLS_ONLY, str(path)]
    run(check)  # warm-up: the file cache and byte-code
    run(load)
    out: dict[str, list[float]] = {"check wall": [], "check cpu": [], "load wall": [], "load cpu": []}
    for _ in range(runs):
        for name, cmd in (("check", check), ("load", load)):
            wall, cpu = run(cmd)
            out[f"{name} wall"].append(wall)
            out[f"{name} cpu"].append(cpu)
    return out


def span(walls: list[float], cpus: list[float]) -> str:
    return f"{statistics.median(walls):.3f} [{min(walls):.3f}-{max(walls):.3f}], CPU {statistics.median(cpus):.3f}"


def pair_ratio(t: dict[str, list[float]], kind: str) -> float:
    return statistics.median(a / b for a, b in zip(t[f"check {kind}"], t[f"load {kind}"]))


def random_set_dbc(folder: Path) -> Path:
    """The random 1,000-message set as a DBC, written by netcfg's own DBC emitter (as bench_check.py does)."""
    from random_can import write_random_can

    from netcfg.check import load_model
    from netcfg.diagnostics import Collector
    from netcfg.emit import dbc

    model = load_model(write_random_can(1000, folder), Collector())
    assert model is not None, "the random set must resolve"
    path = folder / "random_can_1000.dbc"
    path.write_bytes(next(iter(dbc.emit(model, {}).values())))
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("files", nargs="*", type=Path, help="DBC files (default: the random set and the corpus')")
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}; whole processes in turn, {args.runs} pairs; seconds, median [min-max], "
          "CPU median; ratios: median of the pairs'")  # fmt: skip
    print(f"{'file':<34} {'messages':>8} {'netcfg check':>32} {'cantools load_file':>32} {'ratio wall':>10} "
          f"{'ratio CPU':>9}")  # fmt: skip
    goals = []
    with tempfile.TemporaryDirectory(prefix="netcfg-bench-") as tmp:
        paths = args.files or [random_set_dbc(Path(tmp)), *(CORPUS / name for name in FILES)]
        for path in paths:
            text = path.read_text(encoding="cp1252")
            messages = sum(1 for line in text.splitlines() if line.startswith("BO_ "))
            t = paired(path, args.runs)
            wall_x, cpu_x = pair_ratio(t, "wall"), pair_ratio(t, "cpu")
            print(f"{path.name:<34} {messages:>8} {span(t['check wall'], t['check cpu']):>32} "
                  f"{span(t['load wall'], t['load cpu']):>32} {wall_x:>9.2f}x {cpu_x:>8.2f}x")  # fmt: skip
            if path.name in ("random_can_1000.dbc", LARGEST):
                verdict = "met" if cpu_x <= GOAL_RATIO else f"not met ({cpu_x / GOAL_RATIO:.2f}x over)"
                goals.append(f"goal: check {path.name} ({messages} messages) <= {GOAL_RATIO}x cantools' load_file, "
                             f"whole processes: {cpu_x:.2f}x on CPU, {wall_x:.2f}x on wall time (CPU: netcfg "
                             f"{statistics.median(t['check cpu']):.3f} s, cantools "
                             f"{statistics.median(t['load cpu']):.3f} s): {verdict}")  # fmt: skip
    print()
    for line in goals:
        print(line)


if __name__ == "__main__":
    main()
