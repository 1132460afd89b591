"""`# netcfg-spec:` lines of a bus.yml netcfg wrote (netcfg.emit.bus_yml_spec): the spec keys a bus.yml cannot say,
one item a line as JSON, put back into the imported spec. dcfgen and ros2_canopen never see them (comments); a hand-
edited line that is not JSON, or names nothing of this bus, is a warning and is left out."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from netcfg.diagnostics import Collector, Position

SPEC_NOTE = "netcfg-spec:"
KINDS = ("system", "bus", "node", "message", "flow", "joint")
SpecPath = tuple[str | int, ...]


def read_spec_notes(lines: list[str], file: str, diags: Collector) -> list[tuple[int, dict[str, Any]]]:
    """(line, item) of every `# netcfg-spec:` comment before the first YAML line."""
    out = []
    for n, line in enumerate(lines, 1):
        text = line.strip()
        if text and not text.startswith("#"):
            break
        body = text.lstrip("#").strip()
        if not body.startswith(SPEC_NOTE):
            continue
        where = Position(file, n, line.index(SPEC_NOTE) + len(SPEC_NOTE) + 2)
        try:
            item = json.loads(body[len(SPEC_NOTE) :])
        except json.JSONDecodeError as exc:
            diags.add("bus-yml-note", f"'# {SPEC_NOTE}' is not JSON ({exc.msg}); left out", where, "warning")
            continue
        kinds = [k for k in KINDS if isinstance(item, dict) and k in item]
        if len(kinds) != 1:
            diags.add(
                "bus-yml-note",
                f"'# {SPEC_NOTE}' holds one of {', '.join(KINDS)} per line; left out",
                where,
                "warning",
            )
            continue
        out.append((n, item))
    return out


def apply_spec_notes(
    spec: dict[str, Any],
    notes: list[tuple[int, dict[str, Any]]],
    link: Callable[[SpecPath, int], None],
    warn: Callable[[str, int], None],
) -> None:
    """Merge the notes into spec; link(spec path, line) places later errors at the note's line."""
    for line, item in notes:
        if "system" in item:
            _merge(spec, item["system"], (), line, link)
        elif "bus" in item:
            _merge(spec["buses"][0], item["bus"], ("buses", 0), line, link)
        elif "flow" in item or "joint" in item:
            kind = "flow" if "flow" in item else "joint"
            section = spec.setdefault(f"{kind}s", [])
            section.append(item[kind])
            link((f"{kind}s", len(section) - 1), line)
        else:
            kind = "node" if "node" in item else "message"
            section = "nodes" if kind == "node" else "messages"
            name = item[kind]
            index = next((i for i, x in enumerate(spec[section]) if x.get("name") == name), None)
            if index is None:
                warn(f"'# {SPEC_NOTE}' names {kind} '{name}', which this bus.yml does not have; left out", line)
                continue
            keys = {k: v for k, v in item.items() if k != kind}
            _merge(spec[section][index], keys, (section, index), line, link)


def _merge(into: dict[str, Any], keys: dict[str, Any], path: SpecPath, line: int, link: Callable) -> None:
    for key, value in keys.items():
        if isinstance(value, dict) and isinstance(into.get(key), dict):
            into[key] = {**into[key], **value}
        else:
            into[key] = value
        link((*path, key), line)
