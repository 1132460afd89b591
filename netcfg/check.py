"""`netcfg check`: load, resolve and analyse one spec; returns the JSON-ready report."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from netcfg.analyze import analyze
from netcfg.diagnostics import Collector, sort_diagnostics
from netcfg.model import Model
from netcfg.resolve import resolve
from netcfg.spec.load import read_spec


def load_model(path: Path, diags: Collector) -> Model | None:
    """Read and resolve a spec; None (with errors in diags) when it is not usable. OSError propagates."""
    spec, smap = read_spec(path, diags)
    if spec is None:
        return None
    return resolve(spec, smap, diags, path.parent)


def analyse_spec(path: Path) -> tuple[Model | None, dict[str, Any]]:
    """Load, resolve and analyse; -> (model or None, JSON-ready report). OSError propagates."""
    diags = Collector()
    model = load_model(path, diags)
    report: dict[str, Any] = {"system": None, "file": str(path), "ok": False, "buses": [], "flows": []}
    if model is not None:
        report.update(analyze(model, diags))
        report["system"] = model.system
    items = sort_diagnostics(diags.items)
    report["errors"] = [d.as_json() for d in items if d.severity == "error"]
    report["warnings"] = [d.as_json() for d in items if d.severity == "warning"]
    report["ok"] = model is not None and not report["errors"]
    return model, report


def check(path: Path) -> dict[str, Any]:
    return analyse_spec(path)[1]
