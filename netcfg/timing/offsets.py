"""Automatic offsets for FTT-CAN (`offset: auto` on synchronous messages and triggers).

Each offset is derived from the flows an item belongs to, the way the CAMBADA designers did by hand (seed 002,
section 5.2): a transmission goes out as soon as its data is ready, i.e. in the EC its producer was
activated in plus the producer's worst-case execution time rounded up to whole ECs; a consumer is triggered
in the EC right after the transmission; a task that takes data from a task on the same node is triggered as
soon as that task's data is ready. The first step of a flow starts at EC 0. An item reached by several flows
must get the same offset from all of them. Derived offsets are init times (the first EC in which the item is
due), so they may exceed the period, as Table 2's trigger 13 (period 6, init 6) does.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from netcfg import model

Report = Callable[[str, str, tuple[str | int, ...]], None]


def ceil_div(a: int, b: int) -> int:
    return -(-a // b)


def derive_offsets(m: model.Model, error: Report) -> None:
    derived: dict[str, tuple[int, str]] = {}  # item -> (offset in ECs, flow that set it)

    def settle(name: str, is_auto: bool, current_ns: int | None, want: int, ec: int, flow: model.Flow) -> int:
        if not is_auto:
            return (current_ns or 0) // ec
        if name in derived and derived[name][0] != want:
            other_ec, other_flow = derived[name]
            error(
                "offset-conflict",
                f"flows '{other_flow}' and '{flow.name}' need different offsets for '{name}' "
                f"(EC {other_ec} and EC {want}); give it an explicit offset",
                flow.path,
            )
            return other_ec
        derived[name] = (want, flow.name)
        return want

    for flow in m.flows.values():
        ec = _flow_ec(m, flow)
        if ec is None:
            continue
        ready = 0  # EC in which the previous step's data can be used
        for i, step in enumerate(flow.steps):
            if step.kind == "message":
                sent = []
                for ref in step.refs:
                    msg = m.messages[ref]
                    if msg.window != "sync":
                        continue
                    sent.append(settle(ref, msg.offset_auto, msg.offset_ns, ready if i else 0, ec, flow))
                ready = (max(sent) if sent else ready) + 1  # consumers are triggered right after
            else:
                done = []
                for ref in step.refs:
                    task = m.task(ref)
                    start = ready if i else 0
                    if task.trigger is not None:
                        trig = m.triggers[task.trigger]
                        start = settle(trig.name, trig.offset_auto, trig.offset_ns, start, ec, flow)
                    elif task.period_ns is not None:
                        start = task.offset_ns // ec  # free-running: its own offset
                    done.append(start + ceil_div(task.wcet_ns, ec))
                ready = max(done)
    # write the derived offsets into the model
    for name, (offset_ec, _) in derived.items():
        if name in m.messages:
            msg = m.messages[name]
            ec = m.buses[msg.bus].ftt.ec_ns  # type: ignore[union-attr]
            msg.offset_ns = offset_ec * ec
        else:
            trig = m.triggers[name]
            ec = m.buses[trig.bus].ftt.ec_ns  # type: ignore[union-attr]
            m.triggers[name] = replace(trig, offset_ns=offset_ec * ec)
            for ref in trig.tasks:
                node_name, task_name = ref.split(".", 1)
                tasks = m.nodes[node_name].tasks
                tasks[task_name] = replace(tasks[task_name], offset_ns=offset_ec * ec)
    for msg in m.messages.values():
        if msg.offset_auto and msg.name not in derived:
            error(
                "offset-auto",
                f"'{msg.name}' has 'offset: auto' but no flow passes through it; add it to a flow or give a duration",
                (*msg.path, "offset"),
            )
    for trig in m.triggers.values():
        if trig.offset_auto and trig.name not in derived:
            error(
                "offset-auto",
                f"trigger '{trig.name}' has 'offset: auto' but no flow passes through its tasks; "
                "add one to a flow or give a duration",
                (*trig.path, "offset"),
            )


def _flow_ec(m: model.Model, flow: model.Flow) -> int | None:
    for step in flow.steps:
        for ref in step.refs:
            bus_name = m.messages[ref].bus if step.kind == "message" else None
            if bus_name and (ftt := m.buses[bus_name].ftt):
                return ftt.ec_ns
    return None
