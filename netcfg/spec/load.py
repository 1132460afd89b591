"""Read a spec file: YAML with positions, then the pydantic models, with every error placed in the file."""

from __future__ import annotations

import re
from pathlib import Path
from types import UnionType
from typing import Annotated, Any, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from netcfg.diagnostics import Collector, Position
from netcfg.inputs import MAX_BYTES, InputError, decode_text, read_input_bytes
from netcfg.spec.schema import Spec
from netcfg.spec.source import SourceMap, load_yaml

MAX_SPEC_BYTES = MAX_BYTES["spec"]


def read_spec(path: Path, diags: Collector, display_name: str | None = None) -> tuple[Spec | None, SourceMap]:
    """Load and type-check a spec. Problems go to diags; returns (None, map) when the spec is unusable.

    Raises OSError when the file cannot be read (the CLI turns that into exit code 2).
    """
    spec, smap, _ = read_spec_data(path, diags, display_name)
    return spec, smap


def read_spec_data(
    path: Path, diags: Collector, display_name: str | None = None
) -> tuple[Spec | None, SourceMap, Any]:
    """read_spec, with the YAML's data as written (see parse_spec)."""
    name = display_name or str(path)
    raw = read_input_bytes(path, "spec")  # refuses devices, FIFOs and files over MAX_SPEC_BYTES at once
    try:
        text = decode_text(raw, path, "spec")
    except InputError as exc:
        what = "is not UTF-8 text; save it as UTF-8" if "UTF-8" in exc.message else "contains a NUL byte"
        diags.add("encoding", f"the spec {what}", Position(name, exc.line or 1, 1))
        return None, SourceMap(name), None
    return parse_spec(text, path, diags, name)


def parse_spec(
    text: str, path: Path, diags: Collector, display_name: str | None = None
) -> tuple[Spec | None, SourceMap, Any]:
    """read_spec on text already in memory (an editor's unsaved buffer); path names the file and its folder, against
    which the files the spec names (EDS, DBC) are found. -> (spec or None, map, the YAML's data as written, before
    any DBC is merged in: None when it is not a mapping)."""
    name = display_name or str(path)
    if "\0" in text:
        line = text[: text.index("\0")].count("\n") + 1
        diags.add("encoding", "the spec contains a NUL byte", Position(name, line, 1))
        return None, SourceMap(name), None
    data, smap = load_yaml(text.removeprefix("\ufeff"), name, diags)
    if diags.errors:
        return None, smap, data if isinstance(data, dict) else None
    if not isinstance(data, dict):
        diags.add("not-a-mapping", "a spec is a mapping with keys system, buses, nodes, messages...", smap.at(()))
        return None, smap, None
    written = data
    if isinstance(data.get("buses"), list) and any(isinstance(b, dict) and "import" in b for b in data["buses"]):
        from netcfg.importers.dbc import merge_bus_imports

        data = merge_bus_imports(data, smap, path.parent, diags)
        if diags.errors:
            return None, smap, written
    try:
        return Spec.model_validate(data), smap, written
    except ValidationError as exc:
        report_validation_errors(exc, smap, diags, data)
        return None, smap, written


# The spec's lists of named items, and what one item is called in a message.
ITEM_NAMES = {
    "buses": "bus", "nodes": "node", "messages": "message", "tasks": "task", "flows": "flow", "triggers": "trigger",
    "signals": "signal", "switches": "switch",
}


def _fmt_path(loc: tuple[Any, ...], data: Any = None) -> str:
    """A location as a person names it: "pdo.map[2] of message 'odometry'", not "messages[3].pdo.map[2]"."""
    words: list[str] = []  # named items stand alone; keys and indexes after them join with dots
    named_last = False
    node = data
    for i, part in enumerate(loc):
        child = _child(node, part)
        key = loc[i - 1] if i else None
        name = child.get("name") if isinstance(child, dict) else None
        if isinstance(part, int) and key in ITEM_NAMES and isinstance(name, str) and words:
            words[-1] = words[-1].removesuffix(str(key)).removesuffix(".")
            words[-1:] = [w for w in (words[-1],) if w] + [f"{ITEM_NAMES[key]} '{name}'"]
            named_last = True
        elif isinstance(part, int):
            words[-1:] = [f"{words[-1] if words else ''}[{part}]"]
        elif named_last or not words:
            words.append(str(part))
            named_last = False
        else:
            words[-1] += f".{part}"
        node = child
    if len(words) > 1 and not named_last:  # "size of message 'odometry'", "canopen of bus 'can0'"
        return f"{words[-1]} of {' '.join(words[:-1])}"
    return " ".join(words)


def _child(node: Any, part: Any) -> Any:
    if isinstance(node, dict):
        return node.get(part)
    if isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
        return node[part]
    return None


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


def _model_at(raw_loc: tuple[Any, ...]) -> type[BaseModel] | None:
    """The spec model found at a pydantic error location (which names union branches by class)."""
    tp: Any = Spec
    for part in raw_loc:
        tp = _unwrap(tp)
        members = [_unwrap(m) for m in get_args(tp)] if get_origin(tp) in (Union, UnionType) else [tp]
        models = [m for m in members if isinstance(m, type) and issubclass(m, BaseModel)]
        if isinstance(part, int):
            lists = [m for m in members if get_origin(m) in (list, tuple)]
            tp = get_args(lists[0])[0] if lists and get_args(lists[0]) else None
        elif any(m.__name__ == part for m in models):
            tp = next(m for m in models if m.__name__ == part)
        elif any(part in m.model_fields for m in models):
            tp = next(m for m in models if part in m.model_fields).model_fields[part].annotation
        # anything else is a tag pydantic adds for a validator or a literal branch: stay where we are
    tp = _unwrap(tp)
    members = [_unwrap(m) for m in get_args(tp)] if get_origin(tp) in (Union, UnionType) else [tp]
    return next((m for m in members if isinstance(m, type) and issubclass(m, BaseModel)), None)


def _unwrap(tp: Any) -> Any:
    """X from Annotated[X, ...] and from X | None."""
    while get_origin(tp) is Annotated:
        tp = get_args(tp)[0]
    if get_origin(tp) in (Union, UnionType):
        args = [a for a in get_args(tp) if a is not type(None)]
        if len(args) == 1:
            return _unwrap(args[0])
    return tp


def report_validation_errors(
    exc: ValidationError, smap: SourceMap, diags: Collector, data: Any = None
) -> None:
    from netcfg.spec.suggest import closest, did_you_mean, suggestion

    errors = exc.errors(include_url=False)
    missing = {_data_path(tuple(e["loc"])) for e in errors if e["type"] == "missing"}
    models: dict[tuple[Any, ...], type[BaseModel] | None] = {}  # by location with list indexes as 0
    meant_by_error: dict[int, str | None] = {}  # an unknown key's error -> the model's closest key
    explained: set[tuple[Any, ...]] = set()  # required keys that are there, misspelt: one error says both
    for n, e in enumerate(errors):
        if e["type"] == "extra_forbidden":
            loc = _data_path(tuple(e["loc"]))
            shape = tuple(0 if isinstance(part, int) else part for part in tuple(e["loc"])[:-1])
            if shape not in models:
                models[shape] = _model_at(shape)
            model = models[shape]
            meant = closest(str(loc[-1]), model.model_fields) if model is not None else None
            meant_by_error[n] = meant
            if meant is not None and (*loc[:-1], meant) in missing:
                explained.add((*loc[:-1], meant))
    seen: set[tuple[Any, ...]] = set()
    for n, err in enumerate(errors):
        loc = _data_path(tuple(err["loc"]))
        kind = err["type"]
        if kind == "extra_forbidden":
            key = loc[-1]
            parent = loc[:-1]
            where = _fmt_path(parent, data) or "the spec"
            meant = meant_by_error[n]
            hint = suggestion(meant)
            if meant is not None and (*parent, meant) in explained:
                hint = f" (did you mean '{meant}'? it is required)"
            message = f"unknown key '{key}' in {where}{hint or '; check its spelling (netcfg schema)'}"
            pos = smap.key_at(loc)
        elif kind == "missing" and loc in explained:
            continue
        elif kind == "missing":
            message = f"missing required key '{loc[-1]}' in {_fmt_path(loc[:-1], data) or 'the spec'}"
            pos = smap.at(loc[:-1])
        else:
            text = str(err["msg"]).removeprefix("Value error, ")
            if kind == "literal_error" and isinstance(err.get("input"), str):
                allowed = re.findall(r"'([^']*)'", str(err.get("ctx", {}).get("expected", "")))
                text += did_you_mean(err["input"], allowed)
            if kind == "list_type" and isinstance(err.get("input"), (str, int, float)):
                text += f"; write it as a list, e.g. [{err['input']}]"  # `consumers: b` for `consumers: [b]`
            message = f"{_fmt_path(loc, data)}: {text}"
            pos = smap.at(loc)
        if loc in seen:  # a union reports one error per branch; keep the first
            continue
        seen.add(loc)
        diags.add(kind.replace("_", "-"), message, pos)
