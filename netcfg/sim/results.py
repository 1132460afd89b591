"""What a simulation measured, pooled over Monte Carlo runs, compared with the analysis, and printed.

A run's raw records become a RunResult (numpy arrays per message and per flow, plain counters), small enough to
send back from a worker process; several merge into one; `summary()` gives the JSON contract of DESIGN.md
(`netcfg simulate --format json`) with more keys beside it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from netcfg.runtime import ErrorAssumption, Message, RuntimeConfig
from netcfg.sim.scenario import Scenario
from netcfg.sim.stats import stats_us
from netcfg.timing.can_errors import describe, first_breach

HIST_BINS = 40


@dataclass
class RunResult:
    system: str
    duration_ns: int
    runs: int = 1
    frames: int = 0
    response: dict[str, np.ndarray] = field(default_factory=dict)  # message -> response times, ns
    deadline: dict[str, int | None] = field(default_factory=dict)
    wcrt: dict[str, int | None] = field(default_factory=dict)
    sent: dict[str, int] = field(default_factory=dict)
    lost: dict[str, int] = field(default_factory=dict)
    retransmissions: dict[str, int] = field(default_factory=dict)
    error_frames: int = 0
    unsent_at_end: int = 0  # queued when the run ended: neither sent nor lost
    flow_latency: dict[str, np.ndarray] = field(default_factory=dict)
    flow_delivery: dict[str, np.ndarray] = field(default_factory=dict)
    flow_bounds: dict[str, tuple[int | None, int | None]] = field(default_factory=dict)
    protocols: dict[str, list[dict[str, Any]]] = field(default_factory=dict)  # bus -> one report per run
    error_model: bool = False  # bit errors were injected
    error_checks: list[dict[str, Any]] = field(default_factory=list)  # per CAN bus and run: errors vs. the model
    # FIFO transmit queues: (bus, node) -> the largest backlog seen and the frames that found the queue full
    tx_queues: dict[tuple[str, str], dict[str, Any]] = field(default_factory=dict)
    wall_s: float = 0.0

    def merge(self, other: RunResult) -> RunResult:
        out = RunResult(self.system, self.duration_ns + other.duration_ns, self.runs + other.runs)
        out.frames = self.frames + other.frames
        for name in sorted(set(self.response) | set(other.response)):
            out.response[name] = np.concatenate([self.response.get(name, _EMPTY), other.response.get(name, _EMPTY)])
        for table in ("sent", "lost", "retransmissions"):
            a, b = getattr(self, table), getattr(other, table)
            getattr(out, table).update({k: a.get(k, 0) + b.get(k, 0) for k in sorted(set(a) | set(b))})
        out.deadline = {**self.deadline, **other.deadline}
        out.wcrt = {**self.wcrt, **other.wcrt}
        out.error_frames = self.error_frames + other.error_frames
        out.unsent_at_end = self.unsent_at_end + other.unsent_at_end
        for attr in ("flow_latency", "flow_delivery"):
            a, b = getattr(self, attr), getattr(other, attr)
            getattr(out, attr).update({k: np.concatenate([a.get(k, _EMPTY), b.get(k, _EMPTY)]) for k in {**a, **b}})
        out.flow_bounds = {**self.flow_bounds, **other.flow_bounds}
        buses = {**self.protocols, **other.protocols}
        out.protocols = {k: self.protocols.get(k, []) + other.protocols.get(k, []) for k in buses}
        out.error_model = self.error_model or other.error_model
        out.error_checks = self.error_checks + other.error_checks
        for key in sorted(set(self.tx_queues) | set(other.tx_queues)):
            a, b = self.tx_queues.get(key), other.tx_queues.get(key)
            if a is None or b is None:
                out.tx_queues[key] = dict(a or b or {})
                continue
            out.tx_queues[key] = {
                **a,
                "max_backlog": max(a["max_backlog"], b["max_backlog"]),
                "overflows": a["overflows"] + b["overflows"],
            }
        out.wall_s = self.wall_s + other.wall_s
        return out


_EMPTY = np.empty(0, dtype=np.int64)


def collect(sc: Scenario, wall_s: float = 0.0) -> RunResult:
    cfg: RuntimeConfig = sc.cfg
    res = RunResult(cfg.system, sc.opts.duration_ns, wall_s=wall_s)
    res.error_model = any(f.kind in ("ber", "bit-error") for f in sc.opts.faults)
    known = {m.name: m for m in cfg.messages}
    for can in sc.can.values():
        rec = can.record
        msg = np.array(rec.msg, dtype=np.int64)
        resp = np.array(rec.response, dtype=np.int64)
        res.frames += len(msg)
        order = np.argsort(msg, kind="stable")
        bounds = np.searchsorted(msg[order], np.arange(len(can.sources) + 1))
        pending = can.pending_count()
        for src in can.sources:
            r = resp[order[bounds[src.index] : bounds[src.index + 1]]]
            res.response[src.name] = r
            res.sent[src.name] = len(r)
            res.lost[src.name] = can.dropped.get(src.index, 0)
            res.retransmissions[src.name] = can.retries.get(src.index, 0)
            res.unsent_at_end += pending.get(src.index, 0)
            _bounds(res, src.name, known.get(src.name), sc.opts.mode == "unsync")
        res.error_frames += can.error_frames
        if res.error_model:
            res.error_checks.append(error_check(can.name, can.error_log, cfg.bus(can.name).errors))
        node_queues = [n for n in cfg.nodes if n.tx_queue.fifo and can.name in n.buses]
        for node, q in zip(node_queues, can.fifos):
            res.tx_queues[(can.name, node.name)] = {
                "bus": can.name,
                "node": node.name,
                "depth": q.depth,
                "on_full": "drop" if q.drop else "block",
                "max_backlog": q.max_size,
                "overflows": q.overflows,
            }
    for name, n in sc.lost.items():  # losses no bus saw (a crashed task's Ethernet sends)
        res.lost[name] = res.lost.get(name, 0) + n
    for bus, driver in sc.protocols.items():
        records = getattr(driver, "records", None)
        if records is not None:
            for name, release, end in records():
                res.response[name] = np.asarray(end, dtype=np.int64) - np.asarray(release, dtype=np.int64)
                res.sent[name] = len(res.response[name])
                _bounds(res, name, known.get(name), sc.opts.mode == "unsync")
                res.frames += len(res.response[name])
            for name, n in getattr(driver, "lost_by_message", dict)().items():
                res.lost[name] = res.lost.get(name, 0) + n
        report = getattr(driver, "report", None)
        if report is not None:
            res.protocols[bus] = [report()]
            res.frames += int(res.protocols[bus][0].get("frames_on_wire", 0))  # a segment's cyclic frames
    for tr in sc.flows:
        res.flow_latency[tr.name] = np.asarray(tr.latency.samples, dtype=np.int64)
        if tr.delivery is not None:
            res.flow_delivery[tr.name] = np.asarray(tr.delivery.samples, dtype=np.int64)
        if sc.opts.mode == "unsync":  # free-running: the analysis' unsynchronised bounds apply
            res.flow_bounds[tr.name] = (tr.flow.unsync_latency_min_ns, tr.flow.unsync_latency_max_ns)
        else:
            res.flow_bounds[tr.name] = (tr.flow.latency_min_ns, tr.flow.latency_max_ns)
    return res


def error_check(bus: str, hits: list[int], model: ErrorAssumption | None) -> dict[str, Any]:
    """The errors that hit frames on one bus held against the error model its analysis allowed for (none: an
    error-free bus): where they first came faster than n + ceil(t / T_err) per window t, if they did."""
    breach = first_breach(hits, None if model is None else model.burst, model.interval_ns if model else 1)
    out: dict[str, Any] = {
        "bus": bus,
        "errors": len(hits),
        "assumption": "error-free bus" if model is None else describe(model.burst, f"{model.interval_ns / 1000:g} us"),
        "within_assumption": breach is None,
    }
    if breach is not None:
        window = breach.last_ns - breach.first_ns
        allowed = 0 if model is None else model.burst + window // model.interval_ns + 1
        out["exceeded"] = {
            "from_us": breach.first_ns / 1000,
            "to_us": breach.last_ns / 1000,
            "errors": breach.count,
            "allowed": allowed,
        }
    return out


def outside_error_assumption(res: RunResult) -> bool:
    """Whether some bus's errors left the model its analysis assumed: then the analysis does not claim to bound
    the run, and a figure above it is not a violation of it."""
    return any(not c["within_assumption"] for c in res.error_checks)


def _bounds(res: RunResult, name: str, m: Message | None, unsync: bool = False) -> None:
    """A message's deadline and analysed worst case (free-running CAN's when the run is unsynchronised); None for
    frames the configuration does not list (the TM, a babbler's frames)."""
    res.deadline[name] = m.deadline_ns if m else None
    res.wcrt[name] = (m.wcrt_unsync_ns if unsync and m.wcrt_unsync_ns is not None else m.wcrt_ns) if m else None


def summary(res: RunResult) -> dict[str, Any]:
    """The JSON document of `netcfg simulate --format json`. Its `violations` are one line per message or flow
    whose measured range left the analysed one (`exceeds_analysis` names them); the trace judged frame by frame
    is `log_check` (log_check below, added with --log), in verify's shape."""
    messages = []
    misses = 0
    exceeded = []  # messages and flows whose measured range leaves the analysed one
    violations = []  # one line each
    for name in res.response:
        r = res.response[name]
        d = res.deadline.get(name)
        w = res.wcrt.get(name)
        late = int((r > d).sum()) if d is not None and len(r) else 0
        misses += late
        over = bool(len(r) and w is not None and int(r.max()) > w)
        if over and w is not None:
            exceeded.append(name)
            violations.append(f"message {name}: took up to {int(r.max()) / 1000:g} us, analysed {w / 1000:g} us")
        messages.append(
            {
                "name": name,
                "count": len(r),
                "response_us": stats_us(r),
                "wcrt_us": None if w is None else w / 1000,
                "within_analysis": None if w is None or not len(r) else not over,
                "deadline_us": None if d is None else d / 1000,
                "deadline_misses": late,
                "lost": res.lost.get(name, 0),
                "retransmissions": res.retransmissions.get(name, 0),
            }
        )
    flows = []
    for name, lat in res.flow_latency.items():
        lo, hi = res.flow_bounds.get(name, (None, None))
        within = None
        if len(lat) and lo is not None and hi is not None:
            within = bool(lo <= int(lat.min()) and int(lat.max()) <= hi)
            if not within:
                exceeded.append(name)
                violations.append(
                    f"flow {name}: measured {int(lat.min()) / 1000:g}-{int(lat.max()) / 1000:g} us, "
                    f"analysed {lo / 1000:g}-{hi / 1000:g} us"
                )
        flows.append(
            {
                "name": name,
                "latency_us": stats_us(lat),
                "samples": len(lat),
                "delivery_us": stats_us(res.flow_delivery[name]) if name in res.flow_delivery else None,
                "analysis_us": None if lo is None or hi is None else {"min": lo / 1000, "max": hi / 1000},
                "within_analysis": within,
            }
        )
    for bus, reps in res.protocols.items():  # a protocol's own cycles held against its analysis (CANopen's SYNC)
        texts = [text for i, rep in enumerate(reps) for text in _run_texts(rep.get("violations", []), i, res.runs)]
        if texts:
            exceeded.append(f"{bus}.{reps[0].get('cycle_name', 'sync_cycle')}")
            violations += [f"bus {bus}: {text}" for text in texts]
    duration = res.duration_ns / 1e9
    out: dict[str, Any] = {
        "system": res.system,
        "duration_us": res.duration_ns / 1000,
        "runs": res.runs,
        "frames": res.frames,
        "messages": messages,
        "flows": flows,
        "lost": sum(res.lost.values()),
        "deadline_misses": misses,
        "retransmissions": sum(res.retransmissions.values()),
        "error_frames": res.error_frames,
        "unsent_at_end": res.unsent_at_end,
        "exceeds_analysis": exceeded,
        "violations": violations,
        "analysis_has_error_model": any(c["assumption"] != "error-free bus" for c in res.error_checks),
        "error_checks": res.error_checks,
        "outside_error_assumption": outside_error_assumption(res),
        "protocols": res.protocols if res.runs == 1 else {k: v[:1] for k, v in res.protocols.items()},
    }
    if res.tx_queues:
        out["tx_queues"] = [res.tx_queues[key] for key in sorted(res.tx_queues)]
    if res.wall_s > 0:
        out["speed"] = {
            "wall_s": round(res.wall_s, 3),
            "frames_per_s": round(res.frames / res.wall_s),
            "x_real_time": round(duration / res.wall_s, 1),
        }
    findings = [
        f"bus {bus}{f', run {i + 1}' if res.runs > 1 else ''}: {text}"
        for bus, reps in res.protocols.items()
        for i, rep in enumerate(reps)
        for text in rep.get("findings", [])
    ]
    if findings:
        out["findings"] = findings
    broken = [c for c in res.error_checks if not c["within_assumption"]]
    if broken:
        out["note"] = (
            "the run exceeded the error assumption ("
            + "; ".join(_breach_text(c) for c in broken)
            + ("): the analysis does not bound such a run, so figures above it are not violations of it")
        )
    elif res.error_model:
        out["note"] = "bit errors were injected within every bus's error assumption: the analysis bounds this run"
    return out


def _run_texts(texts: list[str], run: int, runs: int) -> list[str]:
    """A protocol report's lines, each naming its run when there are several."""
    return [f"{f'run {run + 1} ' if runs > 1 else ''}{text}" for text in texts]


def _breach_text(check: dict[str, Any]) -> str:
    e = check.get("exceeded")
    if e is None:
        return f"bus {check['bus']}"
    if e["allowed"] == 0:
        return f"bus {check['bus']} assumes no bit errors and one hit a frame at {e['from_us'] / 1000:.3f} ms"
    return (
        f"bus {check['bus']}: {e['errors']} errors within {(e['to_us'] - e['from_us']) / 1000:.3f} ms from "
        f"{e['from_us'] / 1000:.3f} ms, its model allows {e['allowed']}"
    )


def log_check(cfg: RuntimeConfig, frames: list[Any]) -> dict[str, Any]:
    """The trace held against the analysis by `netcfg verify`'s checker, so that both call the same things a
    violation: its verdict and the first violations."""
    from netcfg.verify import check_frames

    report = check_frames(cfg, frames)
    keys = ("ok", "violation_count", "violations_by_kind", "warning_count")
    out = {**{k: report[k] for k in keys}, "violations": report["violations"][:20]}
    if report.get("fault_phases"):  # the drills' faults, as verify reads them (netcfg.verify.fault_phases)
        out["fault_phases"] = report["fault_phases"]
        out["phase_sequence"] = report["phase_sequence"]
    return out


def text(doc: dict[str, Any]) -> str:
    lines = [
        f"system {doc['system']}: {doc['runs']} run(s), {doc['duration_us'] / 1e6:.3f} s simulated, "
        f"{doc['frames']} frames, {doc['lost']} lost, {doc['deadline_misses']} deadline misses, "
        f"{doc['retransmissions']} retransmissions"
    ]
    if "speed" in doc:
        s = doc["speed"]
        lines.append(f"  {s['wall_s']} s wall, {s['frames_per_s']} frames/s, {s['x_real_time']}x real time")
    lines.append("")
    head = f"{'count':>8}{'min us':>10}{'mean us':>10}{'p99 us':>10}{'max us':>10}"
    lines.append(f"  {'message':<28}{head}{'wcrt us':>10}")
    for m in doc["messages"]:
        r = m["response_us"] or {}
        flag = "" if m["within_analysis"] in (None, True) else "  EXCEEDS ANALYSIS"
        extra = f"  lost {m['lost']}" if m["lost"] else ""
        lines.append(
            f"  {m['name']:<28}{m['count']:>8}{_f(r.get('min')):>10}{_f(r.get('mean')):>10}{_f(r.get('p99')):>10}"
            f"{_f(r.get('max')):>10}{_f(m['wcrt_us']):>10}{flag}{extra}"
        )
    if doc["flows"]:
        lines.append("")
        lines.append(f"  {'flow':<28}{'samples':>8}{'min us':>10}{'mean us':>10}{'p99 us':>10}{'max us':>10}  analysis")
        for f in doc["flows"]:
            r = f["latency_us"] or {}
            a = f["analysis_us"]
            span = f"{a['min']:.0f}-{a['max']:.0f}" if a else "-"
            if f["within_analysis"] is False:
                span += "  OUTSIDE THE ANALYSED RANGE"
            lines.append(
                f"  {f['name']:<28}{f['samples']:>8}{_f(r.get('min')):>10}{_f(r.get('mean')):>10}"
                f"{_f(r.get('p99')):>10}{_f(r.get('max')):>10}  {span}"
            )
    for bus, reports in doc.get("protocols", {}).items():
        lines += ["", *_protocol_text(bus, reports[0])]
    for q in doc.get("tx_queues", ()):
        how = "dropped" if q["on_full"] == "drop" else "blocked their writer"
        lines += [
            "",
            f"  bus {q['bus']}: {q['node']}'s FIFO transmit queue held up to {q['max_backlog']} of {q['depth']} frames"
            + (f"; {q['overflows']} frames found it full and {how}" if q["overflows"] else ""),
        ]
    for finding in doc.get("findings", []):
        lines += ["", f"  finding: {finding}"]
    if doc.get("error_checks"):
        lines.append("")
        by_bus: dict[str, list[dict[str, Any]]] = {}
        for c in doc["error_checks"]:  # one per bus and run
            by_bus.setdefault(c["bus"], []).append(c)
        for name, checks in by_bus.items():
            broken = [c for c in checks if not c["within_assumption"]]
            runs = f" in {len(checks)} runs" if len(checks) > 1 else ""
            verdict = "within it" if not broken else "EXCEEDED: " + _breach_text(broken[0])
            if broken and len(checks) > 1:
                verdict += f" (in {len(broken)} of the runs)"
            lines.append(
                f"  bit errors on bus {name}: {sum(c['errors'] for c in checks)} hit frames{runs}; assumed "
                f"{checks[0]['assumption']}: {verdict}"
            )
    if doc.get("violations"):
        lines += ["", "  outside the analysis:", *(f"    {v}" for v in doc["violations"])]
    check = doc.get("log_check")
    if check is not None:
        faults = len(check.get("fault_phases", ()))
        lines += [
            "",
            f"  trace held against the analysis (as netcfg verify): {check['violation_count']} violations"
            + (f", {faults} fault phase{'s' if faults > 1 else ''} (their gaps are the faults', not violations)"
               if faults else ""),
        ]
        for ph in check.get("phase_sequence", ()) if faults else ():
            detail = f": {ph['detail']}" if ph.get("detail") else ""
            lines.append(f"    {ph['from_us'] / 1e6:9.6f} .. {ph['to_us'] / 1e6:9.6f} s  {ph['phase']}{detail}")
        for v in check["violations"]:
            lines.append(f"    {v['time_us'] / 1e6:.6f} s: {v['kind']}: {v['message'] or ''} {v['detail']}")
    if doc.get("note"):
        lines.append("")
        lines.append("  " + doc["note"])
    return "\n".join(lines)


def _protocol_text(bus: str, rep: dict[str, Any]) -> list[str]:
    """A few lines per bus on what its protocol did: the CANopen master's samples, FTT-CAN's ECs, Ethernet links."""
    if "drives" in rep:
        out = [f"  bus {bus}: CANopen master, {rep['mode'].upper()} mode, period {rep['period_us']:.0f} us"]
        if "cycles" in rep:
            out.append(f"    {rep['cycles']} cycles, {rep['incomplete_cycles']} incomplete")
        done = rep.get("sync_completion_us")
        if done and done["max"] is not None:
            bound = "no bound" if done["analysed"] is None else f"{done['analysed']:g} us"
            out.append(f"    SYNC -> last TPDO up to {done['max']:g} us, analysed {bound}")
        # the drills played (--fault KIND:ARG) and the live master's supervision, in time order, as netcfg run says
        lines = [(d["time_s"], 0, f"drill: {d['text']}") for d in rep.get("drills", ())]
        lines += [(e["time_s"], 1, f"{e['text']} -> {e['action']}") for e in rep.get("supervision", ())]
        out += [f"    {t:9.3f} s  {text}" for t, _, text in sorted(lines, key=lambda line: line[:2])]
        if rep.get("ended_by"):
            out.append(f"    cycle ended by {rep['ended_by']}")
        for drive, d in rep["drives"].items():
            p = d["period_us"] or {}
            out.append(
                f"    {drive:<16} {d['samples']:>6} samples, {d['missing_frames']} missing frames, period "
                f"{_f(p.get('mean'))} us mean, {_f(p.get('std'))} us std"
            )
        return out
    if "ecs" in rep:
        out = [f"  bus {bus}: FTT-CAN, {rep['ecs']} elementary cycles, {rep['ecs_without_tm']} without trigger message"]
        if rep.get("takeover_at_us") is not None:
            out.append(f"    backup master {rep['backup']} took over at {rep['takeover_at_us']:.0f} us")
        return out
    if "links" in rep:
        out = [f"  bus {bus}: switched Ethernet"]
        for link in rep["links"]:
            out.append(
                f"    {link['from'] + ' -> ' + link['to']:<24} {link['frames']:>8} frames, utilisation "
                f"{link['utilization']:.4f}, longest queue {link['max_queue']}, lost {link['lost']}"
            )
        return out
    if "expected_wkc" in rep:
        return _ethercat_text(bus, rep)
    return [f"  bus {bus}: {json.dumps(rep)[:200]}"]


def _ethercat_text(bus: str, rep: dict[str, Any]) -> list[str]:
    """An EtherCAT segment's cycles: the frames' return against the analysis, each slave's passing and SYNC0."""
    out = [
        f"  bus {bus}: EtherCAT, {rep['cycles']} cycles of {rep['cycle_us']:g} us, {rep['lost_frames']} frames "
        f"lost, {rep['wkc_mismatches']} working-counter mismatches (expected {rep['expected_wkc']})"
    ]
    lat = rep.get("latency_us")
    if lat:
        bound = "-" if lat["analysed"] is None else f"{lat['analysed']:g}"
        out.append(
            f"    frames back at the master {lat['min']:g}-{lat['max']:g} us after the cycle starts (analysed "
            f"{bound}), {rep['mailbox_room_us']:g} us left for mailbox traffic"
        )
    for node, s in rep["slaves"].items():
        p = s.get("frame_passed_us")
        if p is None:
            continue
        analysed = "-" if p["analysed"] is None else f"{p['analysed']:g}"
        line = f"    {node:<16} frame passed up to {p['max']:g} us (analysed {analysed})"
        if "sync0_margin_us" in s:
            e = s["sync0_error_ns"]
            line += f", SYNC0 {s['sync0_margin_us']:g} us after it at least (DC error {e['min']:g}..{e['max']:g} ns)"
        out.append(line)
    for m in rep.get("mismatches", ()):
        out.append(f"    {m['time_us'] / 1000:10.3f} ms  working counter {m['wkc']}: {m['why']}")
    return out


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.1f}"


def histograms(res: RunResult, folder: str) -> list[str]:
    """One PNG per flow and per message with a deadline or an analysed bound: the response distribution."""
    import matplotlib

    matplotlib.use("Agg")
    from pathlib import Path

    import matplotlib.pyplot as plt

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    series = [(f"flow_{k}", v, res.flow_bounds.get(k, (None, None))[1]) for k, v in res.flow_latency.items()]
    series += [(f"msg_{k}", v, res.wcrt.get(k)) for k, v in res.response.items() if res.wcrt.get(k) is not None]
    for name, values, bound in series:
        if not len(values):
            continue
        fig, ax = plt.subplots(figsize=(6, 3.2))
        ax.hist(values / 1000, bins=HIST_BINS, color="#4878a8")
        if bound is not None:
            ax.axvline(bound / 1000, color="#c03030", linestyle="--", label="analysis bound")
            ax.legend()
        ax.set_xlabel("us")
        ax.set_ylabel("count")
        ax.set_title(name)
        fig.tight_layout()
        path = out / f"{name}.png"
        fig.savefig(path, metadata={"Software": None})
        plt.close(fig)
        written.append(str(path))
    return written
