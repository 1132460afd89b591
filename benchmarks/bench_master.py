"""How late the live master's SYNC comes on this host, idle and under CPU load, against the `master_jitter` the
analysis assumes.

    python benchmarks/bench_master.py [--cycles 500] [--spec specs/allex2.yaml]

It builds the spec, runs `netcfg run --interface virtual --simulated-drives` for --cycles SYNC periods with a log,
once on the machine as it is and once while a load generator keeps every core busy (one process per core spinning
in pure Python, started here and stopped with the run). From the log (python-can's ASC reader) it takes each SYNC's
time and how much longer than the period each interval between two SYNCs was (the master's wake-up latency), and
from the run's JSON the cycles longer than the period plus master_jitter and the read windows that closed
before the due TPDOs were in.

The drives are simulated in the same process as the master, so their answers share the host with it: the read
times measure the host, not a wire. No test asserts these figures; they say what a Python master on a general-purpose
kernel does, beside what the spec assumes.
"""

from __future__ import annotations

import argparse
import itertools
import json
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import can

ROOT = Path(__file__).resolve().parent.parent
NETCFG = str(Path(sys.executable).with_name("netcfg"))


def _spin(stop_at: float) -> None:
    """A core's worth of pure-Python work until stop_at (bounded in time: a stray generator ends by itself)."""
    x = 0
    while time.time() < stop_at:
        x = (x * 31 + 7) % 1_000_003


def _quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def sync_lateness_us(log: Path, sync_id: int, period_s: float) -> list[float]:
    """How much longer than the period each SYNC interval of the log was, in us: the live master waits from each
    iteration's start (netcfg.runtime.canopen_master, dynamic waiting), so a SYNC's lateness is its interval's excess
    over the period, and one late wake-up moves the SYNCs after it without shortening the next interval."""
    times = [msg.timestamp for msg in can.ASCReader(str(log)) if msg.arbitration_id == sync_id and msg.dlc <= 1]
    return [(b - a - period_s) * 1e6 for a, b in itertools.pairwise(times)]


def run_once(runtime: Path, cycles: int, log: Path, load: bool) -> dict:
    """One run of the live master (its JSON result), with every core loaded when `load`."""
    spinners: list[multiprocessing.Process] = []
    if load:
        stop_at = time.time() + 600  # longer than any run here; stopped below in any case
        spinners = [multiprocessing.Process(target=_spin, args=(stop_at,)) for _ in range(os.cpu_count() or 1)]
        for p in spinners:
            p.start()
    try:
        out = subprocess.run(
            [NETCFG, "run", str(runtime), "--interface", "virtual", "--simulated-drives", "--cycles", str(cycles),
             "--format", "json", "--log", str(log)],
            capture_output=True, text=True, check=False, timeout=1800,
        )
    finally:
        for p in spinners:
            p.terminate()
            p.join()
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=500)
    parser.add_argument("--spec", type=Path, default=ROOT / "specs" / "allex2.yaml")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "build"
        subprocess.run([NETCFG, "build", str(args.spec), "-o", str(out)], capture_output=True, check=True)
        config = json.loads((out / "runtime.json").read_text(encoding="utf-8"))
        co = next(b["canopen"] for b in config["buses"] if b.get("canopen"))
        period_s, jitter_us = co["sync_period_ns"] / 1e9, co["master_jitter_ns"] / 1e3
        print(f"live master, {args.spec.name}: {args.cycles} SYNC periods of {period_s * 1e3:g} ms on the virtual bus, "
              f"{os.cpu_count()} cores; the spec assumes master_jitter {jitter_us:g} us")
        print(f"{'host':<22}{'load avg':>9}{'late p50':>10}{'p99':>9}{'max':>10}{'> T+jitter':>12}"
              f"{'read missed':>13}{'beyond bound':>14}")
        for label, load in (("as it is", False), ("every core busy", True)):
            log = Path(tmp) / f"run-{load}.asc"
            before = os.getloadavg()[0]
            doc = run_once(out / "runtime.json", args.cycles, log, load)
            late = sync_lateness_us(log, co["sync_id"], period_s)
            cyc, read = doc["cycle"], doc["read"]
            print(f"{label:<22}{before:>9.2f}{statistics.median(late):>8.0f}us{_quantile(late, 0.99):>7.0f}us"
                  f"{max(late):>8.0f}us{cyc['overruns']:>12}{read['overruns']:>13}{read['beyond_analysis']:>14}")
        print("late: a SYNC interval's excess over the period; > T+jitter: cycles longer than the period plus "
              "master_jitter; read missed: read windows closed before a due TPDO; beyond bound: complete reads later "
              "than the analysed SYNC-cycle completion")


if __name__ == "__main__":
    main()
