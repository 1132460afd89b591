"""Soundness: random specs of every protocol, analysed, then simulated; no simulated figure may leave its bound.

Each spec is drawn by a hypothesis strategy (random periods, period ranges, offsets, sizes, jitters, priorities,
identifiers, tasks and flows) over plain CAN, FTT-CAN, switched Ethernet and CANopen (SYNC, synchronous TPDOs
every n-th SYNC, RxPDOs; flows through the CANopen master are not drawn). Specs that `check` refuses are
skipped (they promise nothing). Every accepted spec is simulated twice: once with random clock phases and drift,
once at the critical instant (every clock at 0, no drift), and every message and flow must stay inside its
analysed range. The tightness of a bound is the worst simulated figure over the bound.

CAN, FTT-CAN and CANopen buses get a bit-error model one time in three (a burst of 0-2 errors, then one per 1-50
ms); their runs are then hit about as hard as the model allows: the burst, a few tens of microseconds apart, at a
random instant, then one error per interval (plus a microsecond, so that the errors meet the frames at every phase).
A run whose errors left the model would be a fault of this pattern, and counts as a violation.

    .venv/bin/python benchmarks/soundness.py --specs 2500           # 10,000 specs; the tightness and run time
    .venv/bin/python benchmarks/soundness.py --specs 200 --protocol ftt-can

tests/test_soundness.py runs the same check on a bounded number of specs in CI.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from itertools import pairwise
from pathlib import Path
from typing import Any

import yaml
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st

from netcfg import runtime
from netcfg.check import analyse_spec
from netcfg.emit.runtime_json import runtime_document
from netcfg.sim.faults import Fault
from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import summary
from netcfg.sim.scenario import SimOptions
from netcfg.timing.can_errors import first_breach

PROTOCOLS = ("can", "ftt-can", "ethernet-udp", "canopen")
US = 1_000
# transmit queues of CAN nodes: mostly by priority; FIFO ones at SocketCAN's default depth, or shallow ones whose
# writer blocks (check refuses those that can fill up, so only the ones that cannot are simulated)
TX_QUEUES = st.sampled_from(["priority", "priority", "fifo", {"policy": "fifo", "depth": 2}])


def _names(prefix: str, n: int) -> list[str]:
    return [f"{prefix}{i}" for i in range(n)]


@st.composite
def can_spec(draw: st.DrawFn) -> dict[str, Any]:
    """Plain CAN: 2-4 nodes, up to 10 messages (periodic with offsets and jitter, sporadic), a task chain per
    flow."""
    bitrate = draw(st.sampled_from(["125 kbit/s", "250 kbit/s", "500 kbit/s", "1 Mbit/s"]))
    nodes = _names("n", draw(st.integers(2, 4)))
    count = draw(st.integers(1, 10))
    ids = draw(st.lists(st.integers(1, 0x7FF), min_size=count, max_size=count, unique=True))
    messages = []
    for i, ident in enumerate(ids):
        producer = draw(st.sampled_from(nodes))
        consumer = draw(st.sampled_from([n for n in nodes if n != producer]))
        msg: dict[str, Any] = {
            "name": f"m{i}",
            "id": ident,
            "extended": draw(st.booleans()),
            "producer": producer,
            "consumers": [consumer],
            "size": draw(st.integers(0, 8)),
        }
        if draw(st.integers(0, 4)) == 0:
            msg["min_interarrival"] = f"{draw(st.integers(1_000, 100_000))} us"
        else:
            period = draw(st.integers(500, 100_000))
            msg["period"] = f"{period} us"
            if draw(st.booleans()):  # released at an offset of its node's clock: analysed as a transaction
                msg["offset"] = f"{draw(st.integers(0, period - 1))} us"
            jitter = draw(st.integers(0, period // 4))
            if jitter:
                msg["jitter"] = f"{jitter} us"
        messages.append(msg)
    spec = {
        "system": "random_can",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": bitrate}],
        "nodes": [{"name": n, "buses": ["can0"], "tx_queue": draw(TX_QUEUES)} for n in nodes],
        "messages": messages,
    }
    _add_flows(draw, spec)
    _add_errors(draw, spec)
    return spec


def _add_errors(draw: st.DrawFn, spec: dict[str, Any]) -> None:
    """One time in three, the bus gets a bit-error model."""
    if draw(st.integers(0, 2)) == 0:
        spec["buses"][0]["errors"] = {"burst": draw(st.integers(0, 2)), "interval": f"{draw(st.integers(1, 50))} ms"}


def error_pattern(spec: dict[str, Any], duration_ns: int, seed_value: int) -> tuple[Fault, ...]:
    """Errors about as dense as the bus's model allows (none without one): its burst plus one, 37 us apart, at a
    seeded instant in the first interval, then one per interval + 1 us."""
    model = spec["buses"][0].get("errors")
    if model is None:
        return ()
    interval = int(model["interval"].split()[0]) * 1_000_000
    start = (seed_value * 7_919_113) % interval
    times = [start + i * 37_000 for i in range(model["burst"] + 1)]
    while times[-1] + interval + 1_000 < duration_ns:
        times.append(times[-1] + interval + 1_000)
    assert first_breach(times, model["burst"], interval) is None
    return tuple(Fault("bit-error", None, t) for t in times)


@st.composite
def ftt_spec(draw: st.DrawFn) -> dict[str, Any]:
    """FTT-CAN: synchronous messages with periods, ranges and offsets in ECs, asynchronous ones, triggers."""
    ec_ms = draw(st.integers(2, 10))
    nodes = ["master", *_names("n", draw(st.integers(2, 4)))]
    count = draw(st.integers(1, 8))
    messages = []
    ftt_id = 1
    for i in range(count):
        producer = draw(st.sampled_from(nodes[1:]))
        consumer = draw(st.sampled_from([n for n in nodes[1:] if n != producer]))
        msg: dict[str, Any] = {
            "name": f"m{i}",
            "producer": producer,
            "consumers": [consumer],
            "size": draw(st.integers(0, 8)),
        }
        if draw(st.booleans()):
            period = draw(st.integers(1, 6))
            msg |= {"ftt_id": ftt_id, "period": f"{period} EC", "offset": f"{draw(st.integers(0, period - 1))} EC"}
            ftt_id += 1
            if draw(st.integers(0, 3)) == 0:
                msg["period_range"] = [f"{draw(st.integers(1, period))} EC", f"{period + draw(st.integers(0, 2))} EC"]
        else:
            msg |= {"id": 0x200 + i, "window": "async"}
            if draw(st.booleans()):
                msg["min_interarrival"] = f"{draw(st.integers(2, 200))} ms"
            else:
                msg["period"] = f"{draw(st.integers(2, 200))} ms"
        messages.append(msg)
    spec: dict[str, Any] = {
        "system": "random_ftt",
        "buses": [
            {
                "name": "bus",
                "protocol": "ftt-can",
                "bitrate": draw(st.sampled_from(["250 kbit/s", "500 kbit/s", "1 Mbit/s"])),
                "ftt": {
                    "ec": f"{ec_ms} ms",
                    "tm_size": draw(st.integers(1, 8)),
                    "windows": draw(st.sampled_from(["async-first", "sync-first"])),
                },
            }
        ],
        "nodes": [{"name": "master", "role": "master", "buses": ["bus"]}]
        + [{"name": n, "buses": ["bus"]} for n in nodes[1:]],
        "messages": messages,
    }
    _add_flows(draw, spec, ftt_ids=ftt_id, ec_us=ec_ms * 1000)
    _add_errors(draw, spec)
    return spec


@st.composite
def ethernet_spec(draw: st.DrawFn) -> dict[str, Any]:
    """Switched Ethernet: a chain of 1-3 switches, 3-6 hosts, periodic datagrams with jitter."""
    hosts = _names("h", draw(st.integers(3, 6)))
    switches = _names("sw", draw(st.integers(1, 3)))
    ports: dict[str, list[dict[str, Any]]] = {s: [] for s in switches}
    for a, b in pairwise(switches):
        ports[a].append({"port": len(ports[a]) + 1, "to": b})
    for i, h in enumerate(hosts):  # every switch gets a host first, the rest at random
        s = switches[i] if i < len(switches) else draw(st.sampled_from(switches))
        ports[s].append({"port": len(ports[s]) + 1, "to": h})
    messages = []
    for i in range(draw(st.integers(1, 8))):
        producer = draw(st.sampled_from(hosts))
        consumer = draw(st.sampled_from([h for h in hosts if h != producer]))
        period = draw(st.integers(100, 20_000))
        msg = {
            "name": f"m{i}",
            "id": i + 1,
            "producer": producer,
            "consumers": [consumer],
            "size": draw(st.integers(1, 1400)),
            "period": f"{period} us",
            "udp": {"src_port": 5000 + i, "dst_port": 6000 + i},
        }
        jitter = draw(st.integers(0, period // 4))
        if jitter:
            msg["jitter"] = f"{jitter} us"
        messages.append(msg)
    spec = {
        "system": "random_eth",
        "buses": [
            {
                "name": "lan",
                "protocol": "ethernet-udp",
                "bitrate": "100 Mbit/s",
                "ethernet": {"switches": [{"name": s, "ports": ports[s]} for s in switches]},
            }
        ],
        "nodes": [{"name": h, "ip": f"10.0.0.{i + 1}", "buses": ["lan"]} for i, h in enumerate(hosts)],
        "messages": messages,
    }
    _add_flows(draw, spec)
    return spec


@st.composite
def canopen_spec(draw: st.DrawFn) -> dict[str, Any]:
    """CANopen: a master and 1-6 EPOS4 drives; SYNC period, synchronous TPDOs (every n-th SYNC), periodic RxPDOs
    with jitter, an optional sporadic message from the master."""
    period_ms = draw(st.integers(2, 40))
    drives = _names("d", draw(st.integers(1, 6)))
    messages: list[dict[str, Any]] = []
    for d in drives:
        messages.append(
            {
                "name": f"{d}_cmd",
                "producer": "master",
                "consumers": [d],
                "period": f"{period_ms * draw(st.integers(1, 3))} ms",
                "pdo": {"rpdo": 1, "transmission": 255, "map": [0x60FF]},
            }
        )
        for k in range(1, draw(st.integers(1, 2)) + 1):
            messages.append(
                {
                    "name": f"{d}_tx{k}",
                    "producer": d,
                    "consumers": ["master"],
                    "pdo": {"tpdo": k, "transmission": draw(st.integers(1, 3)), "map": [[0x6064, 0x606C][k - 1]]},
                }
            )
    spec: dict[str, Any] = {
        "system": "random_canopen",
        "buses": [
            {
                "name": "can0",
                "protocol": "canopen",
                "bitrate": draw(st.sampled_from(["250 kbit/s", "500 kbit/s", "1 Mbit/s"])),
                "canopen": {"sync_period": f"{period_ms} ms"},
            }
        ],
        "nodes": [{"name": "master", "role": "master", "node_id": 127, "buses": ["can0"], "tx_queue": draw(TX_QUEUES)}]
        + [{"name": d, "node_id": i + 1, "device": "epos4", "buses": ["can0"]} for i, d in enumerate(drives)],
        "messages": messages,
    }
    _add_errors(draw, spec)
    return spec


def _us(text: str, ec_us: int) -> int:
    value, unit = text.split()
    return int(value) * {"us": 1, "ms": 1000, "EC": ec_us}[unit]


def _add_flows(draw: st.DrawFn, spec: dict[str, Any], ftt_ids: int | None = None, ec_us: int = 0) -> None:
    """Tasks around some messages, and a flow producer task -> message -> consumer task for each.
    FTT-CAN synchronous messages get triggered tasks (a trigger per task pair), others periodic or
    message-driven ones; every task has a random WCET and priority."""
    nodes = {n["name"]: n for n in spec["nodes"]}
    triggers: list[dict[str, Any]] = []
    flows: list[dict[str, Any]] = []
    for msg in spec["messages"]:
        if "period" not in msg or draw(st.booleans()):
            continue
        i = len(flows)
        producer, consumer = nodes[msg["producer"]], nodes[msg["consumers"][0]]
        most = max(2, _us(msg["period"], ec_us) // 4)  # WCETs up to a quarter of the message's period
        wcet = draw(st.integers(1, most))
        send: dict[str, Any] = {"name": f"send{i}", "wcet": f"{wcet} us", "bcet": f"{max(1, wcet // 2)} us"}
        use: dict[str, Any] = {"name": f"use{i}", "wcet": f"{draw(st.integers(1, most))} us"}
        if draw(st.booleans()):
            send["priority"] = draw(st.integers(0, 5))
        if ftt_ids is not None and "ftt_id" in msg:
            # the producer's task is triggered every period of the message, in the EC of its offset
            triggers.append(
                {
                    "name": f"t_send{i}",
                    "ftt_id": ftt_ids + 2 * i,
                    "bus": "bus",
                    "period": msg["period"],
                    "offset": msg["offset"],
                    "tasks": [f"{producer['name']}.send{i}"],
                }
            )
            triggers.append(
                {
                    "name": f"t_use{i}",
                    "ftt_id": ftt_ids + 2 * i + 1,
                    "bus": "bus",
                    "period": f"{draw(st.integers(1, 8))} EC",
                    "tasks": [f"{consumer['name']}.use{i}"],
                }
            )
        else:
            send["period"] = msg["period"]
            if draw(st.booleans()):
                use["on_message"] = msg["name"]
            else:
                use["period"] = f"{draw(st.integers(1, 50))} ms"
        producer.setdefault("tasks", []).append(send)
        consumer.setdefault("tasks", []).append(use)
        flows.append(
            {"name": f"f{i}", "chain": [f"{producer['name']}.send{i}", msg["name"], f"{consumer['name']}.use{i}"]}
        )
    if triggers:
        spec["triggers"] = triggers
    if flows:
        spec["flows"] = flows
    if draw(st.booleans()):
        for node in spec["nodes"]:
            node["scheduling"] = "non-preemptive"


STRATEGIES = {"can": can_spec(), "ftt-can": ftt_spec(), "ethernet-udp": ethernet_spec(), "canopen": canopen_spec()}


@dataclass
class Outcome:
    accepted: bool  # check had no errors: the analysis promises something
    violations: list[str] = field(default_factory=list)
    tightness: dict[str, float] = field(default_factory=dict)  # message or flow -> worst simulated / bound


# libyaml's emitter when PyYAML has it (the same YAML, several times faster than the pure-Python one)
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def _dump(spec: dict[str, Any]) -> str:
    return yaml.dump(spec, Dumper=_DUMPER, sort_keys=False)


_SCRATCH: list[tempfile.TemporaryDirectory[str]] = []  # one folder per process for every spec it checks


def _spec_path() -> Path:
    """Where a random spec is written for check to read: one folder for the whole sweep (creating and removing a
    folder per spec cost more than checking small specs on a loaded disk)."""
    if not _SCRATCH:
        _SCRATCH.append(tempfile.TemporaryDirectory(prefix="soundness-"))
    return Path(_SCRATCH[0].name) / "spec.yaml"


def runtime_config(spec: dict[str, Any]) -> runtime.RuntimeConfig | None:
    """The spec's runtime configuration as `netcfg build` writes it; None when check refuses the spec."""
    path = _spec_path()
    path.write_text(_dump(spec), encoding="utf-8")
    model, report = analyse_spec(path)
    if model is None or report["errors"]:
        return None
    return runtime.parse(json.loads(json.dumps(runtime_document(model, report))), "random")


def check_spec(spec: dict[str, Any], seed: int, duration_ns: int) -> Outcome:
    """Analyse the spec; when accepted, simulate it with random phases and at the critical instant."""
    cfg = runtime_config(spec)
    if cfg is None:
        return Outcome(False)
    out = Outcome(True)
    faults = error_pattern(spec, duration_ns, seed)
    runs = {
        "random phases": SimOptions(duration_ns=duration_ns, seed=seed, faults=faults),
        "critical instant": SimOptions(
            duration_ns=duration_ns, seed=seed, random_phase=False, drift_ppm=0.0, faults=faults
        ),
    }
    if any(b.get("protocol") == "ftt-can" for b in spec["buses"]):  # the same bus as free-running CAN
        runs["unsynchronised"] = SimOptions(duration_ns=duration_ns, seed=seed, mode="unsync", faults=faults)
    for label, opts in runs.items():
        _, res = run_once(cfg, opts)
        result = summary(res)
        out.violations += [f"{label}: {v}" for v in result["violations"]]
        if result["outside_error_assumption"]:
            out.violations.append(f"{label}: the injected errors left the bus's error model: {result['note']}")
        if result["deadline_misses"]:
            out.violations.append(f"{result['deadline_misses']} deadline misses in a schedulable spec")
        for m in result["messages"]:
            if m["wcrt_us"] and m["response_us"]:
                ratio = m["response_us"]["max"] / m["wcrt_us"]
                out.tightness[m["name"]] = max(out.tightness.get(m["name"], 0.0), ratio)
        for f in result["flows"]:
            if f["analysis_us"] and f["latency_us"] and f["analysis_us"]["max"]:
                ratio = f["latency_us"]["max"] / f["analysis_us"]["max"]
                out.tightness["flow " + f["name"]] = max(out.tightness.get("flow " + f["name"], 0.0), ratio)
    return out


def sweep(protocol: str, specs: int, duration_ms: int, seed_value: int) -> tuple[int, str]:
    """Check `specs` random specs of one protocol. -> (specs with a violation, the tally and tightness line)."""
    tally = {"specs": 0, "accepted": 0, "failures": 0}
    ratios: list[float] = []
    with_errors: list[float] = []  # the same, for the specs with a bit-error model
    error_specs = [0]

    @seed(seed_value)
    @settings(
        max_examples=specs,
        database=None,
        deadline=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(strategy(protocol))
    def run(spec: dict[str, Any]) -> None:
        out = check_spec(spec, tally["specs"], duration_ms * 1_000_000)
        tally["specs"] += 1
        tally["accepted"] += out.accepted
        ratios.extend(out.tightness.values())
        if out.accepted and spec["buses"][0].get("errors"):
            error_specs[0] += 1
            with_errors.extend(out.tightness.values())
        if out.violations:
            tally["failures"] += 1
            print(f"{protocol} spec {tally['specs']}: " + "; ".join(out.violations), file=sys.stderr)
            print(_dump(spec), file=sys.stderr)

    started = time.perf_counter()
    run()
    ratios.sort()
    mid = ratios[len(ratios) // 2] if ratios else 0.0
    line = (
        f"{protocol}: {tally['specs']} specs, {tally['accepted']} accepted by check, {tally['failures']} with a "
        f"simulated figure outside its bound; tightness (worst simulated / bound) over {len(ratios)} messages "
        f"and flows: median {mid:.3f}, max {max(ratios, default=0.0):.3f}; {time.perf_counter() - started:.0f} s"
    )
    with_errors.sort()
    mid_errors = with_errors[len(with_errors) // 2] if with_errors else 0.0
    if error_specs[0]:  # Ethernet specs have no error model
        line += (
            f"\n  of them {error_specs[0]} accepted specs with an error model, hit as hard as it allows: tightness "
            f"over {len(with_errors)} messages and flows: median {mid_errors:.3f}, max {max(with_errors):.3f}"
        )
    return tally["failures"], line


@st.composite
def ftt_wide_spec(draw: st.DrawFn) -> dict[str, Any]:
    """FTT-CAN, wider than ftt_spec and not in the default sweep (`--protocol ftt-can-wide`): nodes with rx and tx
    delays, synchronous messages sent by triggered or periodic tasks, two of them joined into one task, and flows
    through asynchronous messages whose sender is periodic, triggered or started by a synchronous frame. What it
    found is mended (the README, "A wider FTT-CAN generator"); tests/test_soundness.py runs a sample of it in CI."""
    r = draw(st.randoms(use_true_random=False))
    ec = r.randint(2, 8)
    names = [f"n{i}" for i in range(r.randint(2, 4))]
    nodes: dict[str, dict[str, Any]] = {n: {"name": n, "buses": ["bus"], "tasks": []} for n in names}
    for node in nodes.values():
        if r.random() < 0.6:
            node["rx_delay"] = f"{r.choice([0, 1, 7, 13, 37, 111, 503]) * 1000 + r.choice([0, 1, 333])} ns"
        if r.random() < 0.3:
            node["tx_delay"] = f"{r.randint(0, 200)} us"
    triggers: list[dict[str, Any]] = []
    flows: list[dict[str, Any]] = []
    ids = iter(range(1, 64))
    sync = []
    for i in range(r.randint(1, 5)):
        p, c = r.sample(names, 2)
        period = r.randint(1, 4)
        sync.append({"name": f"m{i}", "ftt_id": next(ids), "producer": p, "consumers": [c], "size": r.randint(0, 8),
                     "period": f"{period} EC", "offset": f"{r.randint(0, period - 1)} EC"})
    asynchronous = []
    for i in range(r.randint(0, 3)):
        p, c = r.sample(names, 2)
        m = {"name": f"a{i}", "id": r.choice([0x80, 0x200, 0x300]) + i, "window": "async", "producer": p,
             "consumers": [c], "size": r.randint(0, 8), "extended": r.random() < 0.3}
        m["period" if r.random() < 0.5 else "min_interarrival"] = f"{r.randint(1, 30)} ms"
        asynchronous.append(m)
    messages: list[dict[str, Any]] = sync + asynchronous

    def trigger(task: str, period: str, offset: str | None = None) -> None:
        triggers.append({"name": f"t_{task.replace('.', '_')}", "ftt_id": next(ids), "bus": "bus", "period": period,
                         **({"offset": offset} if offset else {}), "tasks": [task]})

    def user(name: str, c: str, message: str) -> dict[str, Any]:
        task: dict[str, Any] = {"name": name, "wcet": f"{r.randint(5, 300)} us", "bcet": f"{r.randint(1, 5)} us"}
        kind = r.choice(["trig", "per", "msg"])
        if kind == "trig":
            trigger(f"{c}.{name}", f"{r.randint(1, 4)} EC")
        elif kind == "per":
            task["period"] = f"{r.randint(1, 20)} ms"
        else:
            task["on_message"] = message
        return task

    for i, m in enumerate(sync):
        if r.random() < 0.2:
            continue
        p, c = m["producer"], m["consumers"][0]
        w = r.randint(5, 300)
        send: dict[str, Any] = {"name": f"s{i}", "wcet": f"{w} us", "bcet": f"{max(1, w // 2)} us"}
        if r.random() < 2 / 3:
            trigger(f"{p}.s{i}", m["period"], m["offset"])
        else:
            send["period"] = f"{r.randint(1, 4) * ec} ms"
        nodes[p]["tasks"].append(send)
        nodes[c]["tasks"].append(user(f"u{i}", c, m["name"]))
        flows.append({"name": f"f{i}", "chain": [f"{p}.s{i}", m["name"], f"{c}.u{i}"]})
    by_producer: dict[str, list[dict[str, Any]]] = {}
    for m in sync:
        by_producer.setdefault(m["producer"], []).append(m)
    joined = next((ms[:2] for ms in by_producer.values() if len(ms) >= 2), None)
    if joined and r.random() < 0.7:  # two synchronous messages from one producer, joined into one task
        c = r.choice([n for n in names if n != joined[0]["producer"]])
        for m in joined:
            if c not in m["consumers"]:
                m["consumers"].append(c)
        nodes[c]["tasks"].append(user("join", c, r.choice(joined)["name"]))
        flows.append({"name": "fj", "chain": [[m["name"] for m in joined], f"{c}.join"]})
    for i, m in enumerate(asynchronous):
        if r.random() < 0.25:
            continue
        p, c = m["producer"], m["consumers"][0]
        w = r.randint(5, 300)
        send = {"name": f"as{i}", "wcet": f"{w} us", "bcet": f"{max(1, w // 2)} us"}
        started_by = [x["name"] for x in sync if p in x["consumers"]]
        kind = r.choice(["per", "trig", "msg"])
        if kind == "msg" and started_by:
            send["on_message"] = r.choice(started_by)
        elif kind == "trig":
            trigger(f"{p}.as{i}", f"{r.randint(1, 4)} EC")
        else:
            send["period"] = f"{r.randint(1, 25)} ms"
        nodes[p]["tasks"].append(send)
        nodes[c]["tasks"].append(user(f"au{i}", c, m["name"]))
        flows.append({"name": f"af{i}", "chain": [f"{p}.as{i}", m["name"], f"{c}.au{i}"]})
    bus: dict[str, Any] = {
        "name": "bus", "protocol": "ftt-can", "bitrate": r.choice(["250 kbit/s", "500 kbit/s", "1 Mbit/s"]),
        "ftt": {"ec": f"{ec} ms", "tm_size": r.randint(3, 8), "windows": r.choice(["async-first", "sync-first"])},
    }
    if r.random() < 0.4:
        bus["errors"] = {"burst": r.randint(0, 2), "interval": f"{r.randint(1, 50)} ms"}
    for node in nodes.values():
        if not node["tasks"]:
            del node["tasks"]
    spec: dict[str, Any] = {
        "system": "random_ftt_wide", "buses": [bus],
        "nodes": [{"name": "master", "role": "master", "buses": ["bus"]}, *nodes.values()], "messages": messages,
    }
    if triggers:
        spec["triggers"] = triggers
    if flows:
        spec["flows"] = flows
    return spec


OPT_IN = {"ftt-can-wide": ftt_wide_spec}  # not in the default sweep; built only when asked for


def strategy(protocol: str) -> st.SearchStrategy[dict[str, Any]]:
    """A protocol's random specs: the default sweep's, or an opt-in one (built on first use)."""
    if protocol not in STRATEGIES:
        STRATEGIES[protocol] = OPT_IN[protocol]()
    return STRATEGIES[protocol]


GOAL_SPECS = 10_000
GOAL_S = 600


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--specs", type=int, default=1000, help="random specs per protocol")
    parser.add_argument("--protocol", choices=[*STRATEGIES, *OPT_IN], action="append",
                        help="default: all but ftt-can-wide")
    parser.add_argument("--duration-ms", type=int, default=500, help="simulated time per run")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                        help="protocols swept at once, one process each (default: every core)")
    args = parser.parse_args()
    protocols = args.protocol or list(PROTOCOLS)
    started = time.perf_counter()
    jobs = max(1, min(args.jobs, len(protocols)))
    sweeps = [(p, args.specs, args.duration_ms, args.seed) for p in protocols]
    bad = 0
    if jobs == 1:
        for a in sweeps:
            failures, line = sweep(*a)
            bad += failures
            print(line, flush=True)
    else:  # each sweep is its own seeded hypothesis run: the same specs and lines whatever the process
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for future in [pool.submit(sweep, *a) for a in sweeps]:  # printed in protocol order
                failures, line = future.result()
                bad += failures
                print(line, flush=True)
    took = time.perf_counter() - started
    print(f"{len(protocols) * args.specs:,} random specs in {took:.0f} s on {jobs} "
          f"process{'es' if jobs > 1 else ''}", flush=True)
    if len(protocols) * args.specs >= GOAL_SPECS:
        print(f"goal: {GOAL_SPECS:,} random specs in under {GOAL_S // 60} minutes: "
              f"{'met' if took < GOAL_S else 'not met'}", flush=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
