"""How long `netcfg build` takes, whole process, on the example specs (the large synthetic one included), and
how `netcfg import bus-yml` + `netcfg build` of a 126-drive CANopen bus compare with Lely's dcfgen on the same
bus.yml.

    python benchmarks/bench_build.py [--runs N] [--peer-runs N] [--eds FILE]

1. every example spec: median [min-max] wall and CPU time in seconds, the number and size of the files written;
2. 126 maxon EPOS4 drives (node ids 1-126, master 127, 1 Mbit/s, SYNC every 100 ms; per drive RPDO1 and two
   TPDOs of two objects each, synchronous, and a 100 ms heartbeat), written as a bus.yml in dcfgen's own layout
   next to the vendor's EDS: `netcfg import bus-yml` then `netcfg build` (two processes, their times added per
   run) beside `dcfgen -r` (Lely's dcf-tools, the `dcf-tools` dev dependency: installed beside this Python or
   on PATH), with each side's CPU time (user + system, from the process's own accounting: less moved by other
   jobs on a shared machine than the wall time), peak resident memory and the ratios of the medians. The EDS
   is the vendor's file (--eds, default ../shared/devices/maxon_epos4_50-5.eds beside the project); without it
   that part is skipped, and without dcfgen netcfg's figures are printed alone.

No assertions; the machine may be shared, so compare the ratios of one run.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SPECS = ["large_plant", "allex2", "cambada", "ntua_sahr"]
VENDOR_EDS = ROOT.parent / "shared" / "devices" / "maxon_epos4_50-5.eds"
DRIVES = 126


def run(cmd: list[str], cwd: Path) -> tuple[float, float, float]:
    """(wall time in s, CPU time in s (user + system), peak resident memory in MB) of one process; it must
    succeed."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    assert proc.stderr is not None
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)  # this child's own rusage: ru_maxrss in KiB on Linux
    elapsed = time.perf_counter() - start
    proc.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {err.decode(errors='replace').strip().splitlines()[-1:]}")
    return elapsed, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def span(times: list[float]) -> str:
    med = statistics.median(times)
    return f"{med:.3f} [{min(times):.3f}-{max(times):.3f}]"


def drives_bus_yml(drives: int = DRIVES) -> str:
    """dcfgen's layout (slaves at the top level), every key written out: dcfgen reads no `defaults` section."""
    lines = ["master:", "  node_id: 127", "  baudrate: 1000", "  sync_period: 100000", "  sync_window: 80000", ""]
    pdo = "      enabled: true\n      cob_id: auto\n      transmission: 1\n      mapping:\n"
    for node_id in range(1, drives + 1):
        lines += [
            f"drive_{node_id}:",
            '  dcf: "epos4.eds"',
            f"  node_id: {node_id}",
            "  heartbeat_producer: 100",
            "  rpdo:",
            "    1:",
            pdo + "        - {index: 0x6040, sub_index: 0}\n        - {index: 0x60FF, sub_index: 0}",
            "  tpdo:",
            "    1:",
            pdo + "        - {index: 0x6041, sub_index: 0}\n        - {index: 0x6064, sub_index: 0}",
            "    2:",
            pdo + "        - {index: 0x606C, sub_index: 0}\n        - {index: 0x6077, sub_index: 0}",
            "",
        ]
    return "\n".join(lines)


def find_dcfgen() -> str | None:
    beside = Path(sys.executable).parent / "dcfgen"
    return str(beside) if beside.is_file() else shutil.which("dcfgen")


def bench_specs(runs: int, tmp: Path) -> None:
    print(f"{'spec':<12} {'time':>22} {'CPU':>22} {'files':>6} {'bytes':>10}")
    for name in SPECS:
        out = tmp / name
        cmd = [sys.executable, "-m", "netcfg", "build", str(ROOT / "specs" / f"{name}.yaml"), "-o", str(out)]
        measured = [run(cmd, ROOT) for _ in range(runs)]
        times, cpu = [m[0] for m in measured], [m[1] for m in measured]
        files = [p for p in out.rglob("*") if p.is_file()]
        size = sum(p.stat().st_size for p in files)
        print(f"{name:<12} {span(times):>22} {span(cpu):>22} {len(files):>6} {size:>10,}")


def bench_drives(runs: int, peer_runs: int, eds: Path, tmp: Path) -> None:
    work = tmp / "drives"
    work.mkdir()
    shutil.copy(eds, work / "epos4.eds")
    (work / "bus.yml").write_text(drives_bus_yml(), encoding="utf-8")
    netcfg = [sys.executable, "-m", "netcfg"]
    ours, ours_cpu, ours_mb = [], [], 0.0
    for i in range(runs):
        spec, out = work / f"spec{i}.yaml", work / f"out{i}"
        t_import, cpu_import, mb_import = run([*netcfg, "import", "bus-yml", "bus.yml", "-o", str(spec)], work)
        t_build, cpu_build, mb_build = run([*netcfg, "build", str(spec), "-o", str(out)], work)
        ours.append(t_import + t_build)
        ours_cpu.append(cpu_import + cpu_build)
        ours_mb = max(ours_mb, mb_import, mb_build)
    written = sum(1 for p in (work / "out0").rglob("*") if p.is_file())
    print(f"\n{DRIVES} EPOS4 drives from one bus.yml ({eds.name}); seconds, median [min-max]; CPU; peak RSS")
    print(f"  netcfg import bus-yml + build: {span(ours)}, CPU {span(ours_cpu)}, {ours_mb:.0f} MB, {written} files")
    dcfgen = find_dcfgen()
    if dcfgen is None:
        print("  peer Lely dcfgen not found (pip install dcf-tools); netcfg's figure alone")
        return
    theirs, theirs_cpu, theirs_mb = [], [], 0.0
    for i in range(peer_runs):
        (work / f"lely{i}").mkdir()
        elapsed, cpu, mb = run([dcfgen, "-r", "-d", f"lely{i}", "bus.yml"], work)
        theirs.append(elapsed)
        theirs_cpu.append(cpu)
        theirs_mb = max(theirs_mb, mb)
    print(f"  Lely dcfgen -r:                {span(theirs)}, CPU {span(theirs_cpu)}, {theirs_mb:.0f} MB")
    wall = statistics.median(theirs) / statistics.median(ours)
    cpu_ratio = statistics.median(theirs_cpu) / statistics.median(ours_cpu)
    print(f"  dcfgen / netcfg: {wall:.1f}x (wall), {cpu_ratio:.1f}x (CPU)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--peer-runs", type=int, default=3, help="dcfgen runs (about 20-40 s each)")
    parser.add_argument("--eds", type=Path, default=VENDOR_EDS, help="the EPOS4 EDS the drives use")
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}; netcfg build, whole process, {args.runs} runs; seconds, median [min-max]")
    with tempfile.TemporaryDirectory(prefix="netcfg-bench-") as tmp:
        bench_specs(args.runs, Path(tmp))
        if args.eds.is_file():
            bench_drives(args.runs, args.peer_runs, args.eds, Path(tmp))
        else:
            print(f"\n{DRIVES}-drive bus.yml skipped: no EDS at {args.eds} (give one with --eds)")


if __name__ == "__main__":
    main()
