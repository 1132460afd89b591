"""What a spec says about a CANopen bus that a bus.yml cannot: written into the bus.yml as `# netcfg-spec:` comments.

dcfgen and ros2_canopen read none of it; `netcfg import bus-yml` puts it back into the spec, so that a build, an
import of its bus.yml and a second build give the same system (the timing of the master's cycle, its transmit queue,
the tasks and their flows, supervision). Each line is one item in spec keys, as JSON (one line, no YAML to indent):

    # netcfg-spec: {"system": {"description": "ALLEX-2 exoskeleton"}}
    # netcfg-spec: {"bus": {"canopen": {"master_jitter": "13 us"}}}
    # netcfg-spec: {"node": "master", "tx_queue": {"policy": "fifo", "depth": 16, "on_full": "block"}, "tasks": [...]}
    # netcfg-spec: {"message": "hip_l_cmd", "deadline": "5 ms"}
    # netcfg-spec: {"flow": {"name": "joint_feedback", "chain": ["hip_l_state", "master.control"]}}
    # netcfg-spec: {"joint": {"name": "left_hip_joint", "node": "hip_l", "gear_ratio": 100.0, ...}}

Only what differs from the spec language's defaults is written. A flow is written when every step of it is on this
bus (its messages on the bus, its tasks on the bus's nodes); one that crosses buses is named in the header instead.
A joint is written whole in the bus.yml of the bus its drive is driven over: the scaling keys dcfgen and ros2_canopen
read are derived from it, and a drive's gear and encoder cannot be told apart from their product alone.
"""

from __future__ import annotations

import json
from dataclasses import MISSING, fields
from typing import Any

from netcfg.emit.joint_scaling import joint_bus
from netcfg.importers.bus_yml_notes import SPEC_NOTE
from netcfg.model import Bus, Flow, Joint, Model, Node, Task, TxQueue
from netcfg.spec.units import format_ns  # exact to the nanosecond, in the spec's grammar

__all__ = ["SPEC_NOTE", "spec_notes"]
# what a node and a bus are when the spec says nothing: the model's defaults, which resolve fills in; what differs
# from them is written
NODE_DEFAULTS = {f.name: f.default for f in fields(Node) if f.default is not MISSING}
BUS_DEFAULTS = {f.name: f.default for f in fields(Bus) if f.default is not MISSING}


def spec_notes(model: Model, bus: Bus) -> tuple[list[str], list[str]]:
    """(the JSON lines, what stays in the spec alone: tasks started and flows that run beyond the bus)."""
    items: list[dict[str, Any]] = []
    if model.description:
        items.append({"system": {"description": model.description}})
    bus_keys = _bus_keys(bus)
    if bus_keys:
        items.append({"bus": bus_keys})
    left: list[str] = []
    on_bus = {m.name for m in bus.messages}
    for name in bus.nodes:
        node = model.nodes[name]
        keys = _node_keys(node)
        # a task started from another bus (a message there, an FTT-CAN trigger) cannot be written without it
        tasks = [t for t in node.tasks.values() if t.trigger is None and (t.on_message or "") in on_bus | {""}]
        left.extend(f"task {t.ref} is started from another bus" for t in node.tasks.values() if t not in tasks)
        if tasks:
            keys["tasks"] = [_task_keys(t) for t in tasks]
        if keys:
            items.append({"node": name, **keys})
    for m in bus.messages:
        if m.implicit is not None:
            continue
        keys = {}
        if m.deadline_ns is not None and m.deadline_ns != m.interval_ns:
            keys["deadline"] = format_ns(m.deadline_ns)
        if m.jitter_ns:
            keys["jitter"] = format_ns(m.jitter_ns)
        if m.offset_auto:
            keys["offset"] = "auto"
        elif m.offset_ns:
            keys["offset"] = format_ns(m.offset_ns)
        if m.description:
            keys["description"] = m.description
        if keys:
            items.append({"message": m.name, **keys})
    for flow in model.flows.values():
        if _on_bus(model, bus, flow):
            items.append({"flow": _flow_keys(flow)})
        else:
            left.append(f"flow {flow.name} crosses buses")
    items.extend({"joint": _joint_keys(j)} for j in model.joints.values() if joint_bus(model, j) is bus)
    return [json.dumps(item, ensure_ascii=False, separators=(", ", ": ")) for item in items], left


def _bus_keys(bus: Bus) -> dict[str, Any]:
    co = bus.canopen
    assert co is not None
    out: dict[str, Any] = {}
    if co.master_jitter_ns:
        out["canopen"] = {"master_jitter": format_ns(co.master_jitter_ns)}
    if bus.clock_tolerance_ppm != BUS_DEFAULTS["clock_tolerance_ppm"]:
        out["clock_tolerance"] = bus.clock_tolerance_ppm
    if bus.errors is not None:
        out["errors"] = {
            "burst": bus.errors.burst,
            "interval": format_ns(bus.errors.interval_ns),
            "ber": bus.errors.ber,
        }
    if bus.description:
        out["description"] = bus.description
    return out


def _node_keys(node: Node) -> dict[str, Any]:
    out: dict[str, Any] = {}
    if node.tx_queue != TxQueue():
        q = node.tx_queue
        out["tx_queue"] = {"policy": q.policy, "depth": q.depth, "on_full": q.on_full}
    if node.tx_delay_ns:
        out["tx_delay"] = format_ns(node.tx_delay_ns)
    if node.rx_delay_ns:
        out["rx_delay"] = format_ns(node.rx_delay_ns)
    for key in ("on_loss", "on_emcy", "on_reboot", "safe_stop", "scheduling", "sdo_retries"):
        if getattr(node, key) != NODE_DEFAULTS[key]:
            out[key] = getattr(node, key)
    if node.sdo_timeout_ns != NODE_DEFAULTS["sdo_timeout_ns"]:
        out["sdo_timeout"] = format_ns(node.sdo_timeout_ns)
    if node.description:
        out["description"] = node.description
    return out


def _task_keys(t: Task) -> dict[str, Any]:
    out: dict[str, Any] = {"name": t.name}
    if t.sync_bus is not None:
        out["sync"] = True
    elif t.on_message is not None:
        out["on_message"] = t.on_message
    elif t.period_ns is not None:
        out["period"] = format_ns(t.period_ns)
    if t.offset_ns:
        out["offset"] = format_ns(t.offset_ns)
    out["wcet"] = format_ns(t.wcet_ns)
    if t.bcet_ns != t.wcet_ns:
        out["bcet"] = format_ns(t.bcet_ns)
    if t.priority is not None:
        out["priority"] = t.priority
    if t.description:
        out["description"] = t.description
    return out


def _on_bus(model: Model, bus: Bus, flow: Flow) -> bool:
    names = {m.name for m in bus.messages}
    for step in flow.steps:
        for ref in step.refs:
            if step.kind == "message" and ref not in names:
                return False
            if step.kind == "task" and ref.split(".", 1)[0] not in bus.nodes:
                return False
    return True


def _flow_keys(flow: Flow) -> dict[str, Any]:
    chain: list[str | list[str]] = [s.refs[0] if len(s.refs) == 1 else list(s.refs) for s in flow.steps]
    out: dict[str, Any] = {"name": flow.name, "chain": chain}
    if flow.deadline_ns is not None:
        out["deadline"] = format_ns(flow.deadline_ns)
    if flow.description:
        out["description"] = flow.description
    return out


def _joint_keys(j: Joint) -> dict[str, Any]:
    out: dict[str, Any] = {"name": j.name, "node": j.node}
    if j.axis != 1:
        out["axis"] = j.axis
    out["gear_ratio"] = j.gear_ratio
    if j.encoder_counts is not None:
        out["encoder_counts"] = j.encoder_counts
    if j.velocity_unit != "rpm":
        out["velocity_unit"] = j.velocity_unit
    if j.rated_torque is not None:
        out["rated_torque"] = j.rated_torque
    if j.zero:
        out["zero"] = j.zero
    for side_name, side in (("command", j.command), ("state", j.state)):
        if side:
            out[side_name] = {i: f"{c.message}.{c.signal}" for i, c in side.items()}
    if j.limits:
        out["limits"] = {i: list(lim) if i == "position" else lim[1] for i, lim in j.limits.items()}
    if j.description:
        out["description"] = j.description
    return out
