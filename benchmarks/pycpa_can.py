"""The pyCPA side of bench_check.py: time pyCPA's analysis of one CAN bus, in a process of its own.

pyCPA (github.com/IDA-TUBS/pycpa) has no CAN-specific module; a CAN bus is a resource with its
static-priority non-preemptive scheduler (SPNPScheduler), as in its examples, here with cycle_time = one bit
time (Davis' tau). analyze_system() calls gc.collect() once per task it analyses, so its time grows with
everything else the process holds: this script imports nothing but pyCPA and the standard library.

Reads {"tau": ns, "frames": [[name, C ns, T ns, J ns], ...]} (highest priority first) on stdin; prints
{"times": [s, ...], "cpu": [s, ...], "wcrt": {name: ns}} on stdout (wall and CPU seconds of each run).
Usage: PYTHONPATH=<pycpa checkout> python pycpa_can.py RUNS
"""

from __future__ import annotations

import json
import sys
import time

TIMEOUT_S = 120.0
SLOW_S = 10.0  # a run slower than this is not repeated


def main() -> None:
    from pycpa import analysis, model, options, schedulers

    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    options.set_opt("timeout", TIMEOUT_S)
    job = json.load(sys.stdin)
    times: list[float] = []
    cpu: list[float] = []
    wcrt: dict[str, int] = {}
    while len(times) < runs and (not times or times[0] < SLOW_S):
        system = model.System()
        bus = system.bind_resource(model.Resource("CAN", schedulers.SPNPScheduler(cycle_time=job["tau"])))
        tasks = []
        for rank, (name, c, t, j) in enumerate(job["frames"]):
            task = bus.bind_task(model.Task(name, wcet=c, bcet=c, scheduling_parameter=rank))
            task.in_event_model = model.PJdEventModel(P=t, J=j)
            tasks.append(task)
        start, start_cpu = time.perf_counter(), time.process_time()
        results = analysis.analyze_system(system)
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
        wcrt = {t.name: results[t].wcrt for t in tasks}
    json.dump({"times": times, "cpu": cpu, "wcrt": wcrt}, sys.stdout)


if __name__ == "__main__":
    main()
