"""End-to-end flows: chains of tasks and messages, each step handing its data to the next."""

from __future__ import annotations

from netcfg import model
from netcfg.resolve.core import Resolver, quoted_names
from netcfg.resolve.suggest import did_you_mean
from netcfg.spec.source import Path


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
                        hint = did_you_mean(ref, all_tasks(r))
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
                        f"{did_you_mean(ref, [*(m.name for m in r.spec.messages), *all_tasks(r)])}",
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


def check_flow_links(r: Resolver, flow: str, steps: list[model.FlowStep], path: Path) -> bool:
    """Each step must hand its data to the next: a producer to its message, a message to a consumer,
    a task to a task on the same node."""
    ok = True
    for j in range(1, len(steps)):
        before, after = steps[j - 1], steps[j]
        where = (*path, "chain", j)
        if before.kind == "message" and after.kind == "message":
            r.err(
                "flow-chain",
                f"flow '{flow}': two message steps in a row; put the task that relays the data between them",
                where,
            )
            ok = False
        elif before.kind == "task" and after.kind == "message":
            nodes = {r.split(".")[0] for r in before.refs}
            for ref in after.refs:
                msg = r.model.messages[ref]
                if msg.producer not in nodes:
                    r.err(
                        "flow-chain",
                        f"flow '{flow}': '{ref}' is produced by '{msg.producer}', not by {quoted_names(nodes)}",
                        where,
                    )
                    ok = False
        elif before.kind == "message" and after.kind == "task":
            for ref in after.refs:
                node = ref.split(".")[0]
                if not any(node in r.model.messages[m].consumers for m in before.refs):
                    r.err("flow-chain", f"flow '{flow}': '{node}' consumes none of {quoted_names(before.refs)}", where)
                    ok = False
        else:
            nodes = {r.split(".")[0] for r in before.refs}
            for ref in after.refs:
                if ref.split(".")[0] not in nodes:
                    r.err(
                        "flow-chain",
                        f"flow '{flow}': '{ref}' follows tasks of {quoted_names(nodes)} without a "
                        "message in between; data crosses nodes only in messages",
                        where,
                    )
                    ok = False
    return ok


def all_tasks(r: Resolver) -> list[str]:
    """Every task as a flow step names it: node.task."""
    return [f"{n.name}.{t}" for n in r.model.nodes.values() for t in n.tasks]
