"""The structure the code keeps: layers and their contracts, no import cycle, no protocol decided by its name or by
its flags (an FTT-CAN section's presence, `is_fd`) outside its layer, no module past 600 lines.

The layer contracts themselves are import-linter's (`[tool.importlinter]` in pyproject.toml), run by `make test` and
here; the rest reads the sources with `ast` and import-linter's own import graph (grimp).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import get_args

import grimp
import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "netcfg"
MAX_LINES = 600  # the structure issue's limit

# Where a protocol's name may be compared: its own layer, and runtime.json's format check (each protocol's section,
# and the link of a bus in a file written before buses stated it: the runtime imports without the compiler, so it
# cannot ask the layers). The runtime itself decides by the link runtime.json states.
NAMES_ALLOWED = ("netcfg/links/", "netcfg/protocols/", "netcfg/runtime/schema.py")


def _sources() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def test_the_layer_contracts_hold() -> None:
    done = subprocess.run(
        [str(Path(sys.executable).with_name("lint-imports")), "--no-cache"], cwd=ROOT, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]


def import_cycles(edges: Iterable[tuple[str, str]]) -> list[list[str]]:
    """The import graph's strongly connected components of more than one module: each a set of modules that reach
    one another through their imports, sorted."""
    g = nx.DiGraph(edges)
    return sorted(sorted(c) for c in nx.strongly_connected_components(g) if len(c) > 1)


def test_no_import_cycle_even_by_annotations() -> None:
    """No module reaches itself through imports, counting those under `if TYPE_CHECKING:` too. Where a lower layer
    names what it needs of a higher one, it defines that as a typing Protocol of its own (rules.Resolution: what the
    layers' resolution hooks ask of the resolver; links.arbitration.ArbitrationHooks: what the arbitration analysis
    asks of a protocol), so not even an annotation points up."""
    graph = grimp.build_graph("netcfg", exclude_type_checking_imports=False, cache_dir=None)
    edges = ((m, d) for m in graph.modules for d in graph.find_modules_directly_imported_by(m))
    assert import_cycles(edges) == []


def test_the_python_can_frames_are_a_leaf() -> None:
    """The runtime (and the model, through the runtime's shapes) imports netcfg.links.pycan_frames, import-linter
    allowing that one edge: it must import no module of netcfg, not even under TYPE_CHECKING."""
    graph = grimp.build_graph("netcfg", exclude_type_checking_imports=False, cache_dir=None)
    assert graph.find_modules_directly_imported_by("netcfg.links.pycan_frames") == set()
    assert "netcfg.links.pycan_frames" in graph.find_modules_directly_imported_by("netcfg.runtime.config")


def test_the_cycle_measure_finds_a_cycle() -> None:
    """a -> b -> c -> a is one component of three (d, imported by c, is in none); a lone a -> b is none."""
    assert import_cycles([("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")]) == [["a", "b", "c"]]
    assert import_cycles([("a", "b")]) == []


def _is_name(node: ast.expr) -> bool:
    from netcfg.spec import schema

    return isinstance(node, ast.Constant) and node.value in get_args(schema.Bus.model_fields["protocol"].annotation)


def _compares_a_protocol_name(node: ast.Compare) -> bool:
    """`bus.protocol == x`, `x == "canopen"`, `p in ("can", "canopen")`, `"canopen" in protocols`."""
    operands = [node.left, *node.comparators]
    if all(isinstance(op, (ast.Is, ast.IsNot)) for op in node.ops):
        return False
    named = any(
        (isinstance(p, ast.Attribute) and p.attr == "protocol") or (isinstance(p, ast.Name) and p.id == "protocol")
        for p in operands
    )
    literal = any(_is_name(p) for p in operands) and any(isinstance(op, (ast.Eq, ast.NotEq)) for op in node.ops)
    listed = any(isinstance(p, (ast.Tuple, ast.List, ast.Set)) and any(_is_name(e) for e in p.elts) for p in operands)
    member = _is_name(node.left) and any(isinstance(p, ast.Name) and "protocol" in p.id for p in node.comparators)
    return named or literal or listed or member


def test_no_command_decides_by_a_protocol_name() -> None:
    """`bus.protocol == "canopen"` outside the layers is a question the bus's link or protocol should answer."""

    found = []
    for path in _sources():
        rel = path.relative_to(ROOT).as_posix()
        if rel.startswith(NAMES_ALLOWED):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Compare) and _compares_a_protocol_name(node):
                found.append(f"{rel}:{node.lineno}: {ast.unparse(node)}")
    assert found == []


LAYERS = ("netcfg/links/", "netcfg/protocols/")
# A foreign library's frame format: python-can's Message and cantools' DBC Message say `is_fd` (python-can also
# `bitrate_switch`). Only the link layer's adapters speak it (links/pycan_frames.py, links/dbc_frames.py); frames of
# netcfg's own say `fd` and `brs`, and a bus's CAN FD data phase is its link's (Link.data_phase).
FOREIGN_FLAGS = ("is_fd", "bitrate_switch")


def _decides_by_a_flag(node: ast.AST) -> bool:
    """`bus.ftt is None`, `b.ftt is not None` (a bus's FTT-CAN section: its protocol's question), and a foreign
    frame's format flag read (`msg.is_fd`) or handed over (`can.Message(is_fd=...)`) outside the layers."""
    if isinstance(node, ast.Compare) and all(isinstance(op, (ast.Is, ast.IsNot)) for op in node.ops):
        return any(isinstance(p, ast.Attribute) and p.attr == "ftt" for p in (node.left, *node.comparators))
    if isinstance(node, ast.Attribute) and node.attr in FOREIGN_FLAGS:
        return True
    return isinstance(node, ast.Call) and any(k.arg in FOREIGN_FLAGS for k in node.keywords)


def test_no_command_decides_by_a_protocol_flag() -> None:
    """What an FTT-CAN section or a CAN FD flag would decide outside the layers is a question for the bus's protocol
    (Protocol.own_frames, scheduled, runtime_section, sim_driver, log_frames, ...) or its link (Link.data_phase); a
    frame goes to python-can or cantools, or comes from them, through the link layer's adapters."""
    found = []
    for path in _sources():
        rel = path.relative_to(ROOT).as_posix()
        if rel.startswith(LAYERS):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if _decides_by_a_flag(node):
                found.append(f"{rel}:{getattr(node, 'lineno', 0)}: {ast.unparse(node)}")
    assert found == []


@pytest.mark.parametrize(
    ("code", "decides"),
    [
        ("bus.ftt is not None", True),
        ("b.ftt is None", True),
        ("bus.ftt == other", False),  # not a presence test (and no such code exists)
        ("link.is_fd", True),
        ("msg.is_fd", True),  # python-can's frame flag: pycan_frames.frame_format reads it
        ("msg.bitrate_switch and x", True),
        ("can.Message(arbitration_id=1, is_fd=True)", True),  # handed to python-can: pycan_frames.message does it
        ("cdb.Message(is_fd=msg.fd)", True),  # handed to cantools: dbc_frames.message does it
        ("pycan_frames.message(1, False, data, fd=True, brs=msg.brs)", False),  # netcfg's own flags
    ],
)
def test_the_flag_check_tells_a_decision_from_a_frame_of_our_own(code: str, decides: bool) -> None:
    tree = ast.parse(code)
    assert any(_decides_by_a_flag(n) for n in ast.walk(tree)) is decides


@pytest.mark.parametrize("path", _sources(), ids=lambda p: p.relative_to(PACKAGE).as_posix())
def test_no_module_past_600_lines(path: Path) -> None:
    lines = len(path.read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_LINES, f"{path.relative_to(ROOT)}: {lines} lines; split it where its parts own different rules"
