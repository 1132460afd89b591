"""netcfg tune on random 500 kbit/s CAN buses whose identifiers are in the wrong order (the longest periods on the
smallest identifiers) at about 80 % worst-case load: time of Audsley's search alone (in process, median of 3) and
of the whole `netcfg tune` process (check before, search, offsets, check after), one core.

    .venv/bin/python benchmarks/bench_tune.py            # N = 100, 300, 1000
    .venv/bin/python benchmarks/bench_tune.py 1000 2000
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import random_can

from netcfg.check import analyse_spec, load_model
from netcfg.diagnostics import Collector
from netcfg.timing import load
from netcfg.timing.can_rta import ONE_SHOT
from netcfg.timing.frames import bits_to_ns
from netcfg.tuning import Item, audsley

UTILISATION = 0.8


def wrong_order_spec(n: int, folder: Path) -> Path:
    msgs, extended = random_can.random_messages(n, UTILISATION)
    ids = sorted(m.id for m in msgs)
    ranked = sorted(msgs, key=lambda m: (-m.period_us, m.name))  # longest period gets the smallest identifier
    width = 8 if extended else 3
    lines = [
        f"system: wrong_order_{n}",
        "buses:",
        f"  - {{name: can0, protocol: can, bitrate: 500 kbit/s, id_bits: {29 if extended else 11}}}",
        "nodes:",
        *(f"  - {{name: ecu{i:02d}, buses: [can0]}}" for i in range(1, random_can.NODES + 1)),
        "messages:",
    ]
    for ident, m in zip(ids, ranked):
        lines.append(
            f"  - {{name: {m.name}, id: 0x{ident:0{width}X}, producer: {m.producer}, "
            f"consumers: [{', '.join(m.consumers)}], size: {m.size}, period: {m.period_us} us}}"
        )
    path = folder / f"wrong_order_{n}.yaml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def items_of(path: Path) -> tuple[list[Item], int]:
    m = load_model(path, Collector())
    assert m is not None
    bus = next(iter(m.buses.values()))
    timings, _, _ = load.can_bus_load(bus)
    items = [
        Item(
            x.name,
            timings[x.name].tx_ns,
            x.interval_ns or ONE_SHOT,
            x.jitter_ns,
            x.deadline_ns,
            x.extended,
            x.id,
            x.producer,
            False,
            None,
        )
        for x in bus.messages
    ]
    return items, bits_to_ns(1, bus.bitrate)


def main() -> int:
    sizes = [int(a) for a in sys.argv[1:]] or [100, 300, 1000]
    folder = Path(tempfile.mkdtemp(prefix="netcfg-tune-"))
    print(f"{'N':>6} {'load':>7} {'check before':>13} {'audsley s':>10} {'tune process s':>15} {'check after':>12}")
    for n in sizes:
        spec = wrong_order_spec(n, folder)
        _, before = analyse_spec(spec)
        items, tau = items_of(spec)
        times = []
        for _ in range(3):
            start = time.perf_counter()
            audsley(items, tau)
            times.append(time.perf_counter() - start)
        out = folder / f"tuned_{n}.yaml"
        start = time.perf_counter()
        run = subprocess.run(
            [sys.executable, "-m", "netcfg", "tune", str(spec), "-o", str(out), "--force"],
            capture_output=True,
            text=True,
        )
        whole = time.perf_counter() - start
        if run.returncode:
            print(run.stderr, file=sys.stderr)
            return 1
        _, after = analyse_spec(out)
        print(
            f"{n:>6} {before['buses'][0]['utilization']:>7.1%} {'ok' if before['ok'] else 'refused':>13} "
            f"{statistics.median(times):>10.3f} {whole:>15.2f} {'ok' if after['ok'] else 'refused':>12}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
