"""`netcfg check`: load, resolve and analyse one spec; returns the JSON-ready report."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import ValidationError

from netcfg.analyze import analyze
from netcfg.diagnostics import Collector, sort_diagnostics
from netcfg.importers import ImportOptions
from netcfg.model import Model
from netcfg.resolve import resolve
from netcfg.spec.load import read_spec, report_validation_errors
from netcfg.spec.schema import Spec
from netcfg.spec.source import SourceMap


def load_model(path: Path, diags: Collector, options: ImportOptions | None = None) -> Model | None:
    """Read and resolve a spec (or a DBC file, analysed as the spec netcfg would import from it); None (with
    errors in diags) when it is not usable. OSError propagates."""
    if path.suffix.lower() == ".dbc":
        return load_dbc(path, diags, options or ImportOptions())
    spec, smap = read_spec(path, diags)
    if spec is None:
        return None
    return resolve(spec, smap, diags, path.parent)


def load_dbc(path: Path, diags: Collector, options: ImportOptions) -> Model | None:
    from netcfg.importers.dbc import import_dbc_located

    imported, positions = import_dbc_located(path, options, diags)
    if imported is None or diags.errors:
        return None
    smap = SourceMap.from_positions(str(path), positions)  # errors found later point into the DBC
    try:
        spec = Spec.model_validate(imported[0])
    except ValidationError as exc:
        report_validation_errors(exc, smap, diags, imported[0])
        return None
    return resolve(spec, smap, diags, path.parent)


def analyse_spec(path: Path, options: ImportOptions | None = None) -> tuple[Model | None, dict[str, Any]]:
    """Load, resolve and analyse; -> (model or None, JSON-ready report). OSError propagates."""
    diags = Collector()
    model = load_model(path, diags, options)
    report: dict[str, Any] = {"system": None, "file": str(path), "ok": False, "buses": [], "flows": []}
    if model is not None:
        report.update(analyze(model, diags))
        report["system"] = model.system
    items = sort_diagnostics(diags.items)
    report["errors"] = [d.as_json() for d in items if d.severity == "error"]
    report["warnings"] = [d.as_json() for d in items if d.severity == "warning"]
    report["ok"] = model is not None and not report["errors"]
    return model, report


def check(path: Path, options: ImportOptions | None = None) -> dict[str, Any]:
    return analyse_spec(path, options)[1]


def promote_warnings(report: dict[str, Any], codes: frozenset[str]) -> dict[str, Any]:
    """`--werror CODE`: warnings with one of these codes count as errors (e.g. dbc-no-receiver in CI)."""
    promoted = [w for w in report["warnings"] if w["code"] in codes]
    if not promoted:
        return report
    report["warnings"] = [w for w in report["warnings"] if w["code"] not in codes]
    report["errors"] = report["errors"] + promoted
    report["ok"] = False
    return report


SPEC_SUFFIXES = (".yaml", ".yml")


def spec_files(paths: list[Path]) -> list[Path]:
    """The specs to check: files as given, folders as every *.yaml/*.yml directly inside them, sorted by name.

    Raises FileNotFoundError for a folder without specs, so that `check empty/` is not silently fine.
    """
    out: list[Path] = []
    for path in paths:
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.suffix in SPEC_SUFFIXES and p.is_file())
            if not found:
                raise FileNotFoundError(f"no specs (*.yaml, *.yml) in folder {path}")
            out += found
        else:
            out.append(path)
    return out
