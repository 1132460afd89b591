"""End-to-end flows: chains of tasks and messages, each step handing its data to the next."""

from __future__ import annotations

from netcfg import model
from netcfg.resolve.core import Resolver, quoted_names
from netcfg.spec.source import Path
from netcfg.spec.suggest import did_you_mean
from netcfg.timing.flows import same_rate


def resolve_flows(r: Resolver) -> None:
    for i, f in enumerate(r.spec.flows):
        path: Path = ("flows", i)
        steps: list[model.FlowStep] = []
        ok = True
        for j, item in enumerate(f.chain):
            spath = (*path, "chain", j)
            refs = [item] if isinstance(item, str) else item
            if not refs:
                r.err("flow-chain", "an empty list is not a step", spath)
                ok = False
                continue
            kinds = set()
            for k, ref in enumerate(refs):
                rpath = spath if isinstance(item, str) else (*spath, k)
                if "." in ref:
                    node_name, _, task_name = ref.partition(".")
                    node = r.model.nodes.get(node_name)
                    if node is None or task_name not in node.tasks:
                        hint = did_you_mean(ref, r.task_refs())
                        if node is None:
                            why = f"there is no node '{node_name}'"
                        elif node.tasks:
                            why = f"node '{node_name}' has the tasks {', '.join(node.tasks)}"
                        else:
                            why = f"node '{node_name}' has no tasks: declare '{task_name}' under its tasks:"
                        r.err(
                            "unknown-task",
                            f"flow '{f.name}': '{ref}' is not a task (node.task){hint}; {why}",
                            rpath,
                        )
                        ok = False
                    kinds.add("task")
                elif ref in r.model.messages:
                    kinds.add("message")
                elif any(m.name == ref for m in r.spec.messages):
                    ok = False  # in the spec, but with errors of its own, reported where they are
                else:
                    r.err(
                        "unknown-message",
                        f"flow '{f.name}': '{ref}' is neither a message nor a task (tasks are written node.task)"
                        f"{did_you_mean(ref, [*(m.name for m in r.spec.messages), *r.task_refs()])}",
                        rpath,
                    )
                    ok = False
            if len(kinds) > 1:
                r.err("flow-chain", "a parallel step holds either tasks or messages, not both", spath)
                ok = False
            elif kinds:
                steps.append(model.FlowStep(kinds.pop(), tuple(refs)))  # type: ignore[arg-type]
        if ok:
            ok = check_flow_links(r, f.name, steps, path)
        if ok and steps[-1].kind != "task":
            r.err(
                "flow-chain",
                f"flow '{f.name}' must end with the task that uses the data (node.task)",
                (*path, "chain", len(steps) - 1),
            )
        r.model.flows[f.name] = model.Flow(
            description=f.description,
            name=f.name,
            steps=tuple(steps),
            deadline_ns=r.ns(f.deadline, (*path, "deadline"), None),
            path=path,
        )
    if not r.d.errors:  # (a flow with errors may name tasks and messages that do not exist)
        r.model.sent_by = message_senders(r.model)


def message_senders(m: model.Model) -> dict[str, tuple[str, ...]]:
    """Message -> the tasks (node.task) that send it as they finish: in some flow, a task on its producer in the
    step before it, at its rate (a task a message starts runs at that message's: a reply goes out with every
    run); for a sporadic message any such task, whose run raises the event (at most once per minimum
    inter-arrival time, the load the analysis assumes). Other messages run at their own rate, and so do those
    whose bus's own cycle carries them (Protocol.sent_as_tasks_end)."""
    from netcfg import protocols

    out: dict[str, set[str]] = {}
    for flow in m.flows.values():
        for prev, step in zip(flow.steps, flow.steps[1:]):
            if step.kind != "message" or prev.kind != "task":
                continue
            for name in step.refs:
                msg = m.messages[name]
                if not protocols.of(m.buses[msg.bus]).sent_as_tasks_end(m.buses[msg.bus]):
                    continue  # its bus's cycle takes the data the task left (an EtherCAT PDO)
                for ref in prev.refs:
                    task = m.task(ref)
                    if task.node == msg.producer and (msg.kind == "sporadic" or same_rate(m, task, msg)):
                        out.setdefault(name, set()).add(ref)
    return {name: tuple(sorted(refs)) for name, refs in sorted(out.items())}


def check_flow_links(r: Resolver, flow: str, steps: list[model.FlowStep], path: Path) -> bool:
    """Each step must hand its data to the next: a producer to its message, a message to a consumer,
    a task to a task on the same node."""
    ok = True
    for j in range(1, len(steps)):
        for problem in _link_problems(r, steps[j - 1], steps[j]):
            r.err("flow-chain", f"flow '{flow}': {problem}", (*path, "chain", j))
            ok = False
    return ok


def _link_problems(r: Resolver, before: model.FlowStep, after: model.FlowStep) -> list[str]:
    """What keeps step `before` from handing its data to step `after`, one line each."""
    if before.kind == "message" and after.kind == "message":
        return ["two message steps in a row; put the task that relays the data between them"]
    if before.kind == "message":  # to a task
        return [
            f"'{node}' consumes none of {quoted_names(before.refs)}"
            for node in (ref.split(".")[0] for ref in after.refs)
            if not any(node in r.model.messages[m].consumers for m in before.refs)
        ]
    nodes = {ref.split(".")[0] for ref in before.refs}
    if after.kind == "message":  # from a task
        return [
            f"'{ref}' is produced by '{producer}', not by {quoted_names(nodes)}"
            for ref in after.refs
            if (producer := r.model.messages[ref].producer) not in nodes
        ]
    return [  # a task to a task
        f"'{ref}' follows tasks of {quoted_names(nodes)} without a message in between; data crosses nodes only in "
        "messages"
        for ref in after.refs
        if ref.split(".")[0] not in nodes
    ]
