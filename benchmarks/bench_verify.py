"""`netcfg verify` speed and memory, on a generated log, side by side with python-can's own readers.

    python benchmarks/bench_verify.py [--frames 5000000] [--reference-frames 200000] [--repeat 3]

The log is the simulated ALLEX-2 network (seed 000's 8 s gait cycle, about 7,600 frames) repeated back to back, its
times shifted by 8 s each time, as a candump -L file. Figures:
1. netcfg's vectorised candump reader and checker together (what `netcfg verify` does after start-up): frames per
   CPU second, median of --repeat runs (one core: everything runs in one thread).
2. python-can's readers (candump, ASC, BLF) on the first --reference-frames frames, each followed by the same
   checker: frames per CPU second, median of three.
3. Peak memory (maximum resident set) of a fresh process checking logs of 1/5 and all of --frames frames: bounded
   memory shows as the same figure for both.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import can

from netcfg import runtime
from netcfg.emit.runtime_json import runtime_document
from netcfg.sim.can_trace import trace_frames
from netcfg.sim.montecarlo import run_once
from netcfg.sim.scenario import SimOptions
from netcfg.verify import verify_log

ROOT = Path(__file__).resolve().parent.parent
GAIT_NS = 8_000_000_000


def allex2_config() -> runtime.RuntimeConfig:
    from netcfg.check import analyse_spec

    model, report = analyse_spec(ROOT / "specs" / "allex2.yaml")
    assert model is not None
    return runtime.parse(json.loads(json.dumps(runtime_document(model, report))))


def write_log(cfg: runtime.RuntimeConfig, path: Path, frames: int) -> int:
    """The simulated gait cycle, repeated until the log has `frames` frames; -> the frames written."""
    sc, _ = run_once(cfg, SimOptions(duration_ns=GAIT_NS, seed=0, trace=True))
    cycle = [(f.t_ns, f.channel, f"{f.can_id:03X}#{f.data.hex().upper()}") for f in trace_frames(sc) if not f.error]
    written = 0
    with path.open("w", encoding="ascii") as out:
        rep = 0
        while written < frames:
            base = rep * GAIT_NS
            chunk = cycle[: frames - written]
            out.write("".join(f"({(base + t) // 1000 // 1_000_000}.{(base + t) // 1000 % 1_000_000:06d}) {ch} {body}\n"
                              for t, ch, body in chunk))
            written += len(chunk)
            rep += 1
    return written


def timed(fn: object, repeat: int = 3) -> float:
    """Median CPU seconds of this process (one core; the machine's other load does not count)."""
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()  # type: ignore[operator]
        times.append(time.process_time() - t0)
    return statistics.median(times)


def peak_rss_mb(log: Path) -> float:
    code = (
        "import resource, sys; from pathlib import Path; from netcfg import runtime; from netcfg.verify import "
        "verify_log; cfg = runtime.load(sys.argv[1]); verify_log(cfg, Path(sys.argv[2])); "
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)"
    )
    out = subprocess.run([sys.executable, "-c", code, str(ROOT / "generated" / "allex2" / "runtime.json"), str(log)],
                         capture_output=True, text=True, check=True)
    return int(out.stdout.strip()) / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=5_000_000)
    ap.add_argument("--reference-frames", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure (the median is printed)")
    args = ap.parse_args()
    cfg = allex2_config()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        big = folder / "big.log"
        small = folder / "small.log"
        n = write_log(cfg, big, args.frames)
        n_small = write_log(cfg, small, args.frames // 5)
        size_mb = big.stat().st_size / 1e6
        print(f"log: {n:,} frames, {size_mb:.0f} MB candump -L (ALLEX-2 gait cycle repeated)")
        fast = timed(lambda: verify_log(cfg, big), args.repeat)
        print(f"netcfg verify, vectorised candump reader + checker: {fast:.2f} s CPU, {n / fast:,.0f} frames/s")

        ref_log = folder / "ref.log"
        n_ref = write_log(cfg, ref_log, args.reference_frames)
        with can.LogReader(str(ref_log)) as reader:
            msgs = list(reader)
        for suffix in (".asc", ".blf"):
            with can.Logger(str(folder / f"ref{suffix}")) as writer:
                for m in msgs:
                    writer.on_message_received(m)
        same = verify_log(cfg, ref_log) == verify_log(cfg, ref_log, fast=False)
        print(f"python-can's readers + the same checker, {n_ref:,} frames (vectorised and python-can candump "
              f"reports identical: {same}):")
        own = timed(lambda: verify_log(cfg, ref_log))
        print(f"  {'candump, vectorised':<22} {n_ref / own:>12,.0f} frames/s")
        for name, path, fast_path in (("candump, python-can", ref_log, False), ("ASC, python-can", folder / "ref.asc",
                                      False), ("BLF, python-can", folder / "ref.blf", False)):
            t = timed(lambda p=path, f=fast_path: verify_log(cfg, p, fast=f))  # type: ignore[misc]
            print(f"  {name:<22} {n_ref / t:>12,.0f} frames/s   ({own / t:.2f}x the vectorised reader's rate)")
        print("peak memory of a fresh process (maximum resident set):")
        print(f"  {n_small:>12,} frames: {peak_rss_mb(small):6.0f} MB")
        print(f"  {n:>12,} frames: {peak_rss_mb(big):6.0f} MB")


if __name__ == "__main__":
    main()
