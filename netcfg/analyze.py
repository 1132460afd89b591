"""Model -> Report: the driver of the analysis. Each bus is analysed by its protocol (netcfg.protocols), each node's
processor and each flow here, iterated to the holistic fixed point of the senders' release jitter.

The report is plain JSON-ready data in the shape DESIGN.md fixes; timing problems are added to the
diagnostics at the source position of the message, bus or flow they concern.
"""

from __future__ import annotations

from typing import Any

from netcfg import model, protocols
from netcfg.bus_analysis import Analysis, us
from netcfg.diagnostics import Collector
from netcfg.spec.units import format_ns
from netcfg.timing import can_offsets, flows

__all__ = ["analysis_jitter", "analyze", "holistic_jitter"]

MAX_HOLISTIC_ROUNDS = 50  # rounds of the sender-jitter iteration between processors and buses


def analyze(m: model.Model, diags: Collector) -> dict[str, Any]:
    """Buses, processors and flows. A message that a task sends as it finishes is released with that task's
    response-time variation as jitter, which in turn may delay tasks started by messages: the two are iterated
    from zero jitter until nothing grows (holistic analysis, Tindell and Clark 1994); the last round reports."""
    acc = Analysis()
    acc.extra_jitter = holistic_jitter(m)
    return _analyze_once(m, diags, acc)


def holistic_jitter(m: model.Model) -> dict[str, int]:
    """Each task-sent message's release jitter beyond the spec's, at the fixed point of the holistic iteration
    (analyze's; --explain and tune read the same figures)."""
    extra: dict[str, int] = {}
    if any(_sent_by_task(m, msg) for msg in m.messages.values()):
        for _ in range(MAX_HOLISTIC_ROUNDS):
            acc = Analysis()
            acc.extra_jitter, acc.jitter_only = extra, True
            _analyze_once(m, Collector(), acc)
            grown = sender_jitter(m, acc)
            if grown == extra:
                break
            extra = grown
    return extra


def analysis_jitter(m: model.Model) -> Analysis:
    """An analysis context that carries only the holistic release jitter, for rta_frames outside analyze."""
    acc = Analysis()
    acc.extra_jitter = holistic_jitter(m)
    return acc


def _sent_by_task(m: model.Model, msg: model.Message) -> bool:
    """Queued by a task as it finishes (not by an FTT-CAN schedule or a CANopen SYNC)."""
    if msg.window == "sync" or msg.implicit or (msg.pdo is not None and 1 <= msg.pdo.transmission <= 240):
        return False
    return bool(flows.sending_tasks(m, msg))


def sender_jitter(m: model.Model, acc: Analysis) -> dict[str, int]:
    """Each task-sent message's extra release jitter: its slowest sender's response minus its BCET."""
    out = {}
    for msg in m.messages.values():
        if not _sent_by_task(m, msg):
            continue
        spread = 0
        for ref in flows.sending_tasks(m, msg):
            r = acc.task_wcrt.get(ref)
            if r is not None:
                spread = max(spread, r - m.task(ref).bcet_ns)
        if spread:
            out[msg.name] = spread
    return out


def _analyze_once(m: model.Model, diags: Collector, acc: Analysis) -> dict[str, Any]:
    buses = [protocols.of(bus).analyze(m, bus, diags, acc) for bus in m.buses.values()]
    for row, bus in zip(buses, m.buses.values()):
        row["assumes"] = protocols.of(bus).assumptions(bus, tuple(q["node"] for q in row.get("tx_queues", ())))
        check_offsets(m, bus, diags)
        warn_if_nothing_analysed(m, bus, diags)
    nodes = [analyze_node(m, node, acc, diags) for node in m.nodes.values() if node.tasks]
    return {"buses": buses, "nodes": nodes, "flows": [analyze_flow(m, f, acc, diags) for f in m.flows.values()]}


def warn_if_nothing_analysed(m: model.Model, bus: model.Bus, diags: Collector) -> None:
    """A bus whose every message is on-demand carries no analysed load: its 0.0 % and the verdict say nothing of
    its timing (a DBC without cycle times imports that way), which a user must not read as a pass."""
    if not bus.messages or any(msg.kind != "on-demand" for msg in bus.messages):
        return
    if any(d.code == "dbc-not-analysed" for d in diags.items):  # check F.dbc: each message has said so already
        return
    diags.add(
        "not-analysed",
        f"bus '{bus.name}': all {len(bus.messages)} of its messages are on-demand, so nothing on it is analysed and "
        "its 0.0 % load says nothing of its timing; give its messages a period (or min_interarrival for sporadic "
        "ones), or for a DBC assume one with --default-period T (check, import dbc, init --from dbc)",
        m.source.at(bus.path),
        "warning",
    )


def check_offsets(m: model.Model, bus: model.Bus, diags: Collector) -> None:
    """A warning for each offset the analysis of this bus cannot use, and for each sender whose offsets unroll
    into more releases than the offset analysis follows (it then takes them at any phase)."""
    for msg in bus.messages:
        if (ignored := protocols.of(bus).offset_ignored(m, bus, msg)) is not None:
            why, fix = ignored
            diags.add(
                "offset-unused",
                f"the analysis does not use the offset {format_ns(msg.offset_ns or 0)} of '{msg.name}': {why}; "
                f"{fix}",
                m.source.at((*msg.path, "offset")),
                "warning",
            )
    offsets = protocols.release_offsets(m, bus)
    # where can_offsets or a FIFO queue (within the same limit) gives the bound: not in FTT-CAN's windows (the
    # master's schedule uses synchronous offsets)
    periods = {msg.name: msg.period_ns for msg in bus.messages if msg.name in offsets and msg.window is None}
    for node, names in can_offsets.too_long({n: (offsets[n][0], t) for n, t in periods.items() if t}).items():
        first = m.messages[names[0]]
        diags.add(
            "offset-unused",
            f"the analysis does not use the offsets of node '{node}' ({', '.join(repr(n) for n in names)}): their "
            f"periods' hyperperiod unrolls into more than {can_offsets.MAX_JOBS} releases, so they are taken at any "
            "phase; choose periods that divide each other (harmonic), or drop the offsets",
            m.source.at((*first.path, "offset")),
            "warning",
        )


def activation(m: model.Model, task: model.Task, acc: Analysis) -> tuple[int | None, int | None]:
    """(shortest interval, jitter) of a task's activations; jitter None when its message has no bound."""
    if task.on_message is not None:
        d = acc.chained.get(task.on_message)
        if d is None or d.worst_ns is None:
            return m.messages[task.on_message].interval_ns, None
        # the message's response jitter from its nominal release: its delivery's spread, and the release jitter its
        # sending task's response adds (Tindell and Clark 1994: an activated task inherits its message's jitter)
        inherited = d.worst_ns - d.best_ns + acc.extra_jitter.get(task.on_message, 0)
        return m.messages[task.on_message].interval_ns, inherited
    if task.trigger is not None:
        return m.triggers[task.trigger].interval_ns, 0
    if task.sync_bus is not None and task.sync_bus in acc.canopen:
        loop = acc.canopen[task.sync_bus].master
        if loop is not None and task.node == loop.node:  # the SYNC producer's loop keeps k T + offset (MasterLoop)
            return task.period_ns, loop.jitter_ns
        sync = acc.canopen[task.sync_bus].sync  # the SYNC frame may be held up by arbitration (or a FIFO queue)
        return task.period_ns, None if sync.worst_ns is None else sync.worst_ns - sync.best_ns
    return task.period_ns, task.cycle_jitter_ns  # a cycle its node keeps starts up to that late (else 0)


def analyze_node(m: model.Model, node: model.Node, acc: Analysis, diags: Collector) -> dict[str, Any]:
    """Response time of each task on the node's processor; a node above 100 % is an error."""
    from netcfg.timing import cpu

    tasks = []
    unbounded_input = set()
    for task in node.tasks.values():
        interval, jitter = activation(m, task, acc)
        if jitter is None:
            unbounded_input.add(task.name)
        tasks.append(cpu.CpuTask(task.name, task.wcet_ns, interval, jitter or 0, task.priority))
    load_ = cpu.utilisation(tasks)
    overloaded = cpu.overloaded(tasks)
    if overloaded:
        diags.add(
            "cpu-overload",
            f"node '{node.name}' needs {load_:.1%} of its processor for its tasks ({load_ - 1:.1%} too much): "
            "shorten their execution times or lengthen their periods",
            m.source.at(node.path),
        )
    response = cpu.analyse(tasks, node.scheduling)
    for t in tasks:
        if response[t.name] is None and not overloaded and t.name not in unbounded_input:
            diags.add(
                "task-unbounded",
                f"task '{node.name}.{t.name}' has no bounded response time: the tasks at its priority and above "
                "fill the processor (exactly 100 % with jitter or blocking); shorten a WCET or lower a rate",
                m.source.at(node.tasks[t.name].path),
            )
    rows = []
    for rank, t in enumerate(cpu.priority_order(tasks)):
        r = None if t.name in unbounded_input else response[t.name]
        # flows time a task from its actual activation, whose lateness they already count: R - J
        acc.task_ns[f"{node.name}.{t.name}"] = None if r is None else r - t.j_ns
        acc.task_wcrt[f"{node.name}.{t.name}"] = r
        rows.append(
            {
                "name": t.name,
                "priority": rank,
                "wcet_us": us(t.c_ns),
                "interval_us": us(t.t_ns),
                "jitter_us": us(t.j_ns),
                "wcrt_us": us(r),
            }
        )
    return {"name": node.name, "scheduling": node.scheduling, "utilization": round(load_, 6), "tasks": rows}


def flow_buses(m: model.Model, flow: model.Flow) -> list[str]:
    """The buses a flow's steps are on, in its order: its messages' and the cycles its tasks run on."""
    out: list[str] = []
    for s in flow.steps:
        for r in s.refs:
            bus = m.messages[r].bus if s.kind == "message" else m.task(r).sync_bus
            if bus is not None and bus not in out:
                out.append(bus)
    return out


def analyze_flow(m: model.Model, flow: model.Flow, acc: Analysis, diags: Collector) -> dict[str, Any]:
    unsync, delivery = flows.unsynchronised(m, flow, acc.plain, acc.task_ns)
    sync = None
    ftt_bus = next(
        (m.messages[r].bus for s in flow.steps if s.kind == "message" for r in s.refs if m.messages[r].bus in acc.ftt),
        None,
    )
    if ftt_bus is not None:
        sync = flows.synchronised(m, flow, acc.ftt[ftt_bus], acc.chained, acc.task_ns)
    else:
        co_bus = next(
            (
                t.sync_bus
                for s in flow.steps
                if s.kind == "task"
                for r in s.refs
                if (t := m.task(r)).sync_bus in acc.canopen
            ),
            None,
        )
        co_bus = co_bus or next(
            (
                m.messages[r].bus
                for s in flow.steps
                if s.kind == "message"
                for r in s.refs
                if m.messages[r].bus in acc.canopen
            ),
            None,
        )
        if co_bus is not None:
            sync = flows.synchronised_canopen(m, flow, co_bus, acc.canopen[co_bus], acc.chained, acc.task_ns)
        else:
            cyc = next((b for b in flow_buses(m, flow) if b in acc.cycle_flows), None)
            if cyc is not None:
                sync = acc.cycle_flows[cyc](m, flow, acc)
            if sync and unsync[1] is not None:
                # a run in step with the cycle is one of the free-running ones, so both bound it: the tighter holds
                # (the walk counts a first task's start jitter at worst, the free-running model from its start)
                (s_lo, s_hi), got = sync
                sync = ((max(s_lo, unsync[0]), min(s_hi, unsync[1])), got)
    lo: int
    hi: int | None
    if sync:
        lo, hi = sync[0]
    elif ftt_bus is not None:  # free-running steps around FTT-CAN windows: the windows' own delivery times
        lo, hi = flows.unsynchronised(m, flow, acc.chained, acc.task_ns, acc.ftt[ftt_bus])[0]
    else:
        lo, hi = unsync
    out: dict[str, Any] = {
        "name": flow.name,
        "mode": "synchronised" if sync else "unsynchronised",
        "latency_min_us": us(lo),
        "latency_max_us": us(hi),
        "latency_ns": [lo, hi],  # exact, for runtime.json
        "jitter_us": None if hi is None else us(hi - lo),
        "deadline_us": us(flow.deadline_ns),
        "meets_deadline": None if flow.deadline_ns is None else hi is not None and hi <= flow.deadline_ns,
        "unsynchronised": {
            "latency_min_us": us(unsync[0]),
            "latency_max_us": us(unsync[1]),
            "latency_ns": list(unsync),
        },
        "steps": [list(s.refs) if len(s.refs) > 1 else s.refs[0] for s in flow.steps],
    }
    if sync:
        out["synchronised"] = {"latency_min_us": us(sync[0][0]), "latency_max_us": us(sync[0][1])}
        if sync[1]:
            out["synchronised"]["delivery_min_us"] = us(sync[1][0])
            out["synchronised"]["delivery_max_us"] = us(sync[1][1])
    if delivery:
        out["unsynchronised"]["delivery_min_us"] = us(delivery[0])
        out["unsynchronised"]["delivery_max_us"] = us(delivery[1])
    if flow.deadline_ns is not None and (hi is None or hi > flow.deadline_ns):
        how = "is unbounded" if hi is None else f"reaches {hi / 1000:g} us, {(hi - flow.deadline_ns) / 1000:g} us late"
        diags.add(
            "flow-deadline",
            f"flow '{flow.name}' {how} for its deadline of {flow.deadline_ns / 1000:g} us",
            m.source.at(flow.path),
        )
    return out
