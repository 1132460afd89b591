"""The simulator's modules form layers: no module of netcfg.sim imports one that imports it back, not even inside a
function or for type checking only; the drivers that live in their protocol's package (netcfg/protocols/<p>/sim*.py)
count as the simulator's. The scenario builds the drivers (FTT-CAN, CANopen, Ethernet) and the whole-run
computations; they see the run through the interfaces of netcfg.sim.run and netcfg.sim.whole_run, never the
scenario itself."""

from __future__ import annotations

import ast
from pathlib import Path

from conftest import ROOT

SIM = ROOT / "netcfg" / "sim"


def _name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imported(module: str, is_package: bool, tree: ast.Module, known: set[str]) -> set[str]:
    """The netcfg.sim modules a module imports anywhere in its text."""
    out: set[str] = set()
    package = module if is_package else module.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package
                for _ in range(node.level - 1):
                    up = up.rpartition(".")[0]
                base = f"{up}.{base}" if base else up
            names = [f"{base}.{a.name}" for a in node.names] + [base]
        else:
            continue
        for name in names:
            while name and name not in known:  # a name imported from a module: that module
                name = name.rpartition(".")[0]
            if name and name != module:
                out.add(name)
    return out


def _graph() -> dict[str, set[str]]:
    # the simulator's drivers that live in their protocol's package (netcfg/protocols/<p>/sim*.py) are its modules too
    drivers = sorted((ROOT / "netcfg" / "protocols").glob("*/sim*.py"))
    paths = {_name(p): p for p in [*SIM.rglob("*.py"), *drivers]}
    known = set(paths)
    return {
        name: _imported(name, path.name == "__init__.py", ast.parse(path.read_text(encoding="utf-8")), known)
        for name, path in paths.items()
    }


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of the graph, as the modules along it, or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(name: str) -> list[str] | None:
        state[name] = 1
        path.append(name)
        for dep in sorted(graph[name]):
            if state.get(dep) == 1:
                return [*path[path.index(dep) :], dep]
            if dep not in state and (found := visit(dep)) is not None:
                return found
        path.pop()
        state[name] = 2
        return None

    for name in sorted(graph):
        if name not in state and (found := visit(name)) is not None:
            return found
    return None


def test_the_simulator_has_no_import_cycle() -> None:
    graph = _graph()
    assert "netcfg.sim.scenario" in graph and graph["netcfg.sim.run"]  # the walk found the package
    cycle = _cycle(graph)
    assert cycle is None, "netcfg.sim imports in a cycle: " + " -> ".join(cycle or [])


def test_the_drivers_do_not_import_the_scenario() -> None:
    graph = _graph()
    below = ["netcfg.sim.run", "netcfg.sim.faults", "netcfg.sim.canopen", "netcfg.sim.pybus"]
    below += ["netcfg.protocols.ftt.sim"]
    below += [name for name in graph if name.startswith("netcfg.sim.ethernet")]
    below += ["netcfg.sim.whole_run", "netcfg.protocols.ftt.sim_whole_run"]
    assert [name for name in below if "netcfg.sim.scenario" in graph[name]] == []
