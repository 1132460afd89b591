"""Runs: one, or a Monte Carlo batch over random phasings and drifts (run i uses seed + i), on every core.

Workers get the runtime configuration as its JSON document and return RunResults, so nothing but plain data
crosses process boundaries; results merge in seed order, so a batch is reproducible whatever the core count.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from netcfg import runtime
from netcfg.sim.results import RunResult, collect
from netcfg.sim.scenario import Scenario, SimOptions


def run_once(cfg: runtime.RuntimeConfig, opts: SimOptions) -> tuple[Scenario, RunResult]:
    t0 = time.perf_counter()
    sc = Scenario(cfg, opts)
    sc.run()
    res = collect(sc, time.perf_counter() - t0)
    return sc, res


def _worker(doc: dict[str, Any], opts: SimOptions) -> RunResult:
    cfg = _cached(doc)
    return run_once(cfg, opts)[1]


_CFG: dict[str, runtime.RuntimeConfig] = {}  # a worker parses each configuration once


def _cached(doc: dict[str, Any]) -> runtime.RuntimeConfig:
    key = str(doc.get("spec_sha256"))
    if key not in _CFG:
        _CFG.clear()
        _CFG[key] = runtime.parse(doc)
    return _CFG[key]


def run_batch(
    doc: dict[str, Any],
    opts: SimOptions,
    runs: int,
    jobs: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> RunResult:
    """`runs` simulations with seeds opts.seed .. opts.seed + runs - 1, merged in seed order."""
    jobs = max(1, min(jobs or os.cpu_count() or 1, runs))
    t0 = time.perf_counter()
    seeds = [replace(opts, seed=opts.seed + i, trace=False) for i in range(runs)]
    results: list[RunResult | None] = [None] * runs
    if jobs == 1:
        cfg = runtime.parse(doc)
        for i, o in enumerate(seeds):
            results[i] = run_once(cfg, o)[1]
            if progress:
                progress(i + 1, runs)
    else:
        from concurrent.futures import ProcessPoolExecutor  # multiprocessing's imports, only for parallel runs

        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = [pool.submit(_worker, doc, o) for o in seeds]
            for done, fut in enumerate(futures, 1):
                results[done - 1] = fut.result()
                if progress:
                    progress(done, runs)
    merged = results[0]
    assert merged is not None
    for r in results[1:]:
        assert r is not None
        merged = merged.merge(r)
    merged.wall_s = time.perf_counter() - t0  # the batch's elapsed time, not the sum of the workers'
    return merged


def progress_bar(done: int, total: int) -> None:
    """A one-line bar on stderr, only when stderr is a terminal (logs stay clean)."""
    if not sys.stderr.isatty():
        return
    width = 30
    fill = width * done // total
    sys.stderr.write(f"\r  [{'#' * fill}{'.' * (width - fill)}] {done}/{total} runs")
    if done == total:
        sys.stderr.write("\n")
    sys.stderr.flush()
