"""The check pipeline: load, resolve and analyse one spec (or a DBC); returns the JSON-ready report.

`netcfg check` (netcfg.commands.check), build, simulate, run, verify, diff, tune and the language server all read a
spec through it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from netcfg.analyze import analyze
from netcfg.diagnostics import Collector, sort_diagnostics
from netcfg.importers import ImportOptions
from netcfg.inputs import SPEC_SUFFIXES
from netcfg.model import Model
from netcfg.resolve import resolve
from netcfg.spec.load import parse_spec, read_spec_data, report_validation_errors
from netcfg.spec.schema import Spec
from netcfg.spec.source import SourceMap


def load_model(
    path: Path, diags: Collector, options: ImportOptions | None = None, text: str | None = None
) -> Model | None:
    """Read and resolve a spec (or a DBC file, analysed as the spec netcfg would import from it); None (with
    errors in diags) when it is not usable. text: the spec's text as an editor holds it, instead of the file's
    (a DBC is always read from its file). OSError propagates."""
    return _load(path, diags, options, text).model


@dataclass
class Loaded:
    """What one check read: the model (None when unusable), where each value was written, and the spec's YAML
    data as written (None for a DBC input or text that is not a mapping). The editor support and --watch read
    the spec's names and the files it names from here instead of parsing it a second time."""

    model: Model | None
    smap: SourceMap | None
    data: Any


def _load(path: Path, diags: Collector, options: ImportOptions | None, text: str | None) -> Loaded:
    if path.suffix.lower() == ".dbc":
        return Loaded(load_dbc(path, diags, options or ImportOptions()), None, None)
    if text is None:
        spec, smap, data = read_spec_data(path, diags)
    else:
        spec, smap, data = parse_spec(text, path, diags)
    if spec is None:
        return Loaded(None, smap, data)
    return Loaded(resolve(spec, smap, diags, path.parent), smap, data)


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


def analyse_spec(
    path: Path, options: ImportOptions | None = None, text: str | None = None
) -> tuple[Model | None, dict[str, Any]]:
    """Load, resolve and analyse; -> (model or None, JSON-ready report). text: see load_model. OSError propagates."""
    loaded, report = analyse_loaded(path, options, text)
    return loaded.model, report


def analyse_loaded(
    path: Path, options: ImportOptions | None = None, text: str | None = None
) -> tuple[Loaded, dict[str, Any]]:
    """analyse_spec, keeping what was read (Loaded)."""
    diags = Collector()
    loaded = _load(path, diags, options, text)
    model = loaded.model
    report: dict[str, Any] = {"system": None, "file": str(path), "ok": False, "buses": [], "flows": []}
    if model is not None:
        report.update(analyze(model, diags))
        report["system"] = model.system
    items = sort_diagnostics(diags.items)
    report["errors"] = [d.as_json() for d in items if d.severity == "error"]
    report["warnings"] = [d.as_json() for d in items if d.severity == "warning"]
    report["ok"] = model is not None and not report["errors"]
    return loaded, report


def named_files(path: Path, data: Any) -> list[Path]:
    """The files a spec names and reads: its devices' EDS files and the DBC files its buses import (as paths
    against the spec's folder, whether they exist or not)."""
    out: list[Path] = []
    if not isinstance(data, dict):
        return out
    for key, inner in (("nodes", "device"), ("buses", None)):
        items = data.get(key)
        for item in items if isinstance(items, list) else ():
            if not isinstance(item, dict):
                continue
            holder = item.get(inner) if inner else item
            value = holder.get("eds" if inner else "import") if isinstance(holder, dict) else None
            if isinstance(value, str) and value and "\0" not in value:
                out.append(path.parent / value)
    return list(dict.fromkeys(out))


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
