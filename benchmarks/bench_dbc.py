"""How long `netcfg check F.dbc` takes, whole process, on the largest files of the DBC corpus, side by side
with the floor any cantools-based tool pays: a Python process that imports cantools and loads the file.

    python benchmarks/bench_dbc.py [--runs N]

Prints the median [min-max] wall time in seconds per file; no assertions.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CORPUS = ROOT / "tests" / "data" / "dbc"
FILES = ["gm_global_a_lowspeed_1818125.dbc", "cadillac_ct6_object.dbc", "vw_mqb.dbc", "hyundai_2015_ccan.dbc"]
CANTOOLS_ONLY = "import sys, cantools; cantools.database.load_file(sys.argv[1], strict=False)"


def timed(cmd: list[str], runs: int) -> list[float]:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        times.append(time.perf_counter() - start)
    return times


def span(times: list[float]) -> str:
    return f"{statistics.median(times):.3f} [{min(times):.3f}-{max(times):.3f}]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}; whole process, {args.runs} runs; seconds, median [min-max]")
    print(f"{'file':<36} {'messages':>8} {'netcfg check':>22} {'cantools load only':>22}")
    for name in FILES:
        path = CORPUS / name
        messages = sum(1 for line in path.read_text(encoding="cp1252").splitlines() if line.startswith("BO_ "))
        check = timed([sys.executable, "-m", "netcfg", "check", str(path), "--bitrate", "500k"], args.runs)
        load = timed([sys.executable, "-c", CANTOOLS_ONLY, str(path)], args.runs)
        print(f"{name:<36} {messages:>8} {span(check):>22} {span(load):>22}")


if __name__ == "__main__":
    main()
