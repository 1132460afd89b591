"""How long `netcfg check F.dbc` takes, whole process, on the largest files of the DBC corpus, side by side
with the floor any cantools-based tool pays: a Python process that imports cantools and loads the file.

    python benchmarks/bench_dbc.py [--runs N] [FILE.dbc ...]

Prints, per file, the median [min-max] wall time and the median CPU time (user + system, which a loaded machine
disturbs less) in seconds of both processes, and netcfg's share: its CPU time above the floor's. The files are
the corpus' largest unless given. No assertions.
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
CORPUS = ROOT / "tests" / "data" / "dbc"
FILES = ["gm_global_a_lowspeed_1818125.dbc", "cadillac_ct6_object.dbc", "vw_mqb.dbc", "hyundai_2015_ccan.dbc"]
CANTOOLS_ONLY = "import sys, cantools; cantools.database.load_file(sys.argv[1], strict=False)"


def timed(cmd: list[str], runs: int) -> tuple[list[float], list[float]]:
    """(wall times, CPU times) of `runs` runs of cmd."""
    walls, cpus = [], []
    for _ in range(runs):
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        _, _, usage = os.wait4(proc.pid, 0)
        walls.append(time.perf_counter() - start)
        cpus.append(usage.ru_utime + usage.ru_stime)
    return walls, cpus


def span(times: tuple[list[float], list[float]]) -> str:
    walls, cpus = times
    return f"{statistics.median(walls):.3f} [{min(walls):.3f}-{max(walls):.3f}], CPU {statistics.median(cpus):.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("files", nargs="*", type=Path, help="DBC files (default: the corpus' largest)")
    args = parser.parse_args()
    paths = args.files or [CORPUS / name for name in FILES]
    print(f"python {sys.version.split()[0]}; whole process, {args.runs} runs; seconds, median [min-max], CPU median")
    print(f"{'file':<36} {'messages':>8} {'netcfg check':>34} {'cantools load only':>34} {'netcfg CPU share':>16}")
    for path in paths:
        messages = sum(1 for line in path.read_text(encoding="cp1252").splitlines() if line.startswith("BO_ "))
        check = timed([sys.executable, "-m", "netcfg", "check", str(path), "--bitrate", "500k"], args.runs)
        load = timed([sys.executable, "-c", CANTOOLS_ONLY, str(path)], args.runs)
        share = statistics.median(check[1]) - statistics.median(load[1])
        print(f"{path.name:<36} {messages:>8} {span(check):>34} {span(load):>34} {share:>16.3f}")


if __name__ == "__main__":
    main()
