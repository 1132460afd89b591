"""Importers: other tools' network descriptions (DBC, ros2_canopen/Lely bus.yml) -> netcfg specs.

An importer builds the spec as plain data plus a comment per item saying where it came from; write_spec()
turns that into YAML a person can read and edit. Importers are strict: what they cannot map is an error
(with --lenient a warning), never silently dropped.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path as PathLike
from typing import Any

Path = tuple[str | int, ...]


@dataclass(frozen=True)
class ImportOptions:
    bitrate: int | None = None  # from the command line: wins over what the file says
    lenient: bool = False  # what cannot be mapped becomes a warning per item instead of an error
    output: PathLike | None = None  # where the spec will be written: file paths in it are made relative to it
    default_period_ns: int | None = None  # DBC: the period assumed for a message that gives no cycle time
    data_bitrate: int | None = None  # CAN FD data phase, from the command line: wins over the file's


# spec data + comments per path (where each item came from)
Imported = tuple[dict[str, Any], dict[Path, str]]
HEX_KEYS = frozenset({"id", "sync_id", "tm_id", "object", "index", "map"})
_PLAIN = re.compile(r"^[A-Za-z_][A-Za-z0-9_ .:/+-]*$")
_RESERVED = frozenset({"true", "false", "yes", "no", "on", "off", "null", "y", "n", "~", ""})


def scalar(value: Any, key: str | int | None = None) -> str:
    """One YAML scalar: hex for identifiers and object indices, quotes only where YAML would misread it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, int):
        return f"0x{value:X}" if key in HEX_KEYS else str(value)
    if isinstance(value, float):
        return repr(value)
    text = str(value)
    if _PLAIN.match(text) and text.lower() not in _RESERVED and not text[0].isdigit() and ": " not in text:
        return text
    return json.dumps(text, ensure_ascii=False)  # a JSON string is a valid YAML double-quoted scalar


def _inline(value: Any, key: str | int | None = None) -> str | None:
    """Short lists of scalars and small flat mappings stay on one line."""
    if isinstance(value, list) and all(not isinstance(v, (dict, list)) for v in value):
        text = "[" + ", ".join(scalar(v, key) for v in value) + "]"
    elif isinstance(value, dict) and all(not isinstance(v, (dict, list)) for v in value.values()) and value:
        text = "{" + ", ".join(f"{k}: {scalar(v, k)}" for k, v in value.items()) + "}"
    else:
        return None
    return text if len(text) <= 90 else None


def write_spec(data: Mapping[str, Any], comments: Mapping[Path, str] | None = None, header: str = "") -> str:
    """YAML text of a spec; comments[path] is written on the line(s) before the item at path."""
    comments = comments or {}
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    # the paths with a comment somewhere below them: written as blocks, never inline (a set, as 126 nodes carry
    # thousands of comments)
    commented_inside = {p[:i] for p in comments for i in range(len(p))}

    def note(path: Path, indent: str) -> None:
        for line in comments.get(path, "").splitlines():
            lines.append(f"{indent}# {line}".rstrip())

    def block(value: Any, path: Path, indent: str) -> None:
        if isinstance(value, dict):
            for k, v in value.items():
                child = (*path, k)
                note(child, indent)
                inline = None if isinstance(v, (dict, list)) and not v else _inline(v, k)
                if not isinstance(v, (dict, list)):
                    lines.append(f"{indent}{k}: {scalar(v, k)}")
                elif not v:
                    lines.append(f"{indent}{k}: {'{}' if isinstance(v, dict) else '[]'}")
                elif inline is not None and child not in commented_inside:
                    lines.append(f"{indent}{k}: {inline}")
                else:
                    lines.append(f"{indent}{k}:")
                    block(v, child, indent + "  ")
        else:
            key = path[-1] if path else None
            for i, v in enumerate(value):
                child = (*path, i)
                note(child, indent)
                inline = _inline(v, key)
                if not isinstance(v, (dict, list)):
                    lines.append(f"{indent}- {scalar(v, key)}")
                elif inline is not None and child not in commented_inside:
                    lines.append(f"{indent}- {inline}")
                elif isinstance(v, dict):
                    sub: list[str] = []
                    saved = len(lines)
                    block(v, child, indent + "  ")
                    sub = lines[saved:]
                    del lines[saved:]
                    first = next(i for i, line in enumerate(sub) if not line.lstrip().startswith("#"))
                    sub[first] = indent + "- " + sub[first][len(indent) + 2 :]
                    lines.extend(sub)
                else:
                    lines.append(f"{indent}-")
                    block(v, child, indent + "  ")

    block(dict(data), (), "")
    return "\n".join(lines) + "\n"
