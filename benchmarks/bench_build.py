"""How long `netcfg build` takes, whole process, on the example specs (the large synthetic one included).

    python benchmarks/bench_build.py [--runs N]

Prints the median [min-max] wall time in seconds and the number and size of the files written; no assertions.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SPECS = ["large_plant", "allex2", "cambada", "ntua_sahr"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}; netcfg build, whole process, {args.runs} runs; seconds, median [min-max]")
    print(f"{'spec':<12} {'time':>22} {'files':>6} {'bytes':>10}")
    with tempfile.TemporaryDirectory(prefix="netcfg-bench-") as tmp:
        for name in SPECS:
            out = Path(tmp) / name
            times = []
            for _ in range(args.runs):
                start = time.perf_counter()
                cmd = [sys.executable, "-m", "netcfg", "build", str(ROOT / "specs" / f"{name}.yaml"), "-o", str(out)]
                subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
                times.append(time.perf_counter() - start)
            files = [p for p in out.rglob("*") if p.is_file()]
            med = statistics.median(times)
            span = f"{med:.3f} [{min(times):.3f}-{max(times):.3f}]"
            print(f"{name:<12} {span:>22} {len(files):>6} {sum(p.stat().st_size for p in files):>10,}")


if __name__ == "__main__":
    main()
