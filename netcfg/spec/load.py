"""Read a spec file: YAML with positions, then the pydantic models, with every error placed in the file."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import ValidationError

from netcfg.diagnostics import Collector, Position
from netcfg.inputs import MAX_BYTES, InputError, decode_text, read_input_bytes
from netcfg.spec.schema import Spec
from netcfg.spec.source import SourceMap, load_yaml

MAX_SPEC_BYTES = MAX_BYTES["spec"]


def read_spec(path: Path, diags: Collector, display_name: str | None = None) -> tuple[Spec | None, SourceMap]:
    """Load and type-check a spec. Problems go to diags; returns (None, map) when the spec is unusable.

    Raises OSError when the file cannot be read (the CLI turns that into exit code 2).
    """
    name = display_name or str(path)
    raw = read_input_bytes(path, "spec")  # refuses devices, FIFOs and files over MAX_SPEC_BYTES at once
    try:
        text = decode_text(raw, path, "spec")
    except InputError as exc:
        what = "is not UTF-8 text; save it as UTF-8" if "UTF-8" in exc.message else "contains a NUL byte"
        diags.add("encoding", f"the spec {what}", Position(name, exc.line or 1, 1))
        return None, SourceMap(name)
    data, smap = load_yaml(text, name, diags)
    if diags.errors:
        return None, smap
    if not isinstance(data, dict):
        diags.add("not-a-mapping", "a spec is a mapping with keys system, buses, nodes, messages...", smap.at(()))
        return None, smap
    if isinstance(data.get("buses"), list) and any(isinstance(b, dict) and "import" in b for b in data["buses"]):
        from netcfg.importers.dbc import merge_bus_imports

        data = merge_bus_imports(data, smap, path.parent, diags)
        if diags.errors:
            return None, smap
    try:
        return Spec.model_validate(data), smap
    except ValidationError as exc:
        report_validation_errors(exc, smap, diags)
        return None, smap


def _fmt_path(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _data_path(loc: tuple[Any, ...]) -> tuple[Any, ...]:
    """Drop the entries pydantic adds for union branches (e.g. 'int', 'EdsDevice') from a location."""
    out = []
    for part in loc:
        if isinstance(part, str) and (part[:1].isupper() or part in {"int", "str", "function-plain[parse_offset()]"}):
            continue
        if isinstance(part, str) and part.startswith(("function-", "literal[", "tuple[", "list[")):
            continue
        out.append(part)
    return tuple(out)


def report_validation_errors(exc: ValidationError, smap: SourceMap, diags: Collector) -> None:
    seen: set[tuple[Any, ...]] = set()
    for err in exc.errors(include_url=False):
        loc = _data_path(tuple(err["loc"]))
        kind = err["type"]
        if kind == "extra_forbidden":
            key = loc[-1]
            parent = loc[:-1]
            message = f"unknown key '{key}' in {_fmt_path(parent) or 'the spec'}; check its spelling (netcfg schema)"
            pos = smap.key_at(loc)
        elif kind == "missing":
            message = f"missing required key '{loc[-1]}' in {_fmt_path(loc[:-1]) or 'the spec'}"
            pos = smap.at(loc[:-1])
        else:
            text = str(err["msg"]).removeprefix("Value error, ")
            message = f"{_fmt_path(loc)}: {text}"
            pos = smap.at(loc)
        if loc in seen:  # a union reports one error per branch; keep the first
            continue
        seen.add(loc)
        diags.add(kind.replace("_", "-"), message, pos)
