"""What every part of the bus.yml importer reads with: a value and where it was written (Val), and
BusYmlReader, the file's diagnostics at their bus.yml line, the small checked readers (a whole number in range,
a mapping, a section's keys against what dcfgen knows) and the record of where each spec item came from.
"""

from __future__ import annotations

from collections.abc import Iterator, Set
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from netcfg.diagnostics import Collector, Position
from netcfg.importers import ImportOptions
from netcfg.importers import Path as SpecPath
from netcfg.importers.bus_yml_keys import BusPath, parse_annotation
from netcfg.spec.source import SourceMap


@dataclass
class Val:
    """A bus.yml value and where it was written (defaults merged into a node keep the defaults' path)."""

    value: Any
    path: BusPath



class BusYmlReader:
    """One bus.yml as read so far, and where its diagnostics and the spec items point."""

    def __init__(self, path: Path, options: ImportOptions, diags: Collector) -> None:
        self.path = path
        self.file = str(path)
        self.name = path.name
        self.folder = path.parent
        self.options = options
        self.d = diags
        self.smap = SourceMap(self.file)
        self.lines: list[str] = []
        self.origin: dict[SpecPath, BusPath] = {}  # spec path -> bus.yml path: positions of later errors
        self.comments: dict[SpecPath, str] = {}

    # -- diagnostics and small readers ---------------------------------------------------------------------------
    def link(self, spath: SpecPath, bpath: BusPath) -> None:
        """The spec item at spath came from bpath: its comment and its errors point there."""
        self.origin[spath] = bpath

    def link_note(self, spath: SpecPath, line: int) -> None:
        """The spec item at spath came from the `# netcfg-spec:` comment on this line."""
        bpath = ("# netcfg-spec", line)
        self.smap.record(bpath, mark(self.file, Position(self.file, line, 1)))
        self.link(spath, bpath)

    def warn_note(self, message: str, line: int) -> None:
        self.d.add("bus-yml-note", message, Position(self.file, line, 1), "warning")

    def at(self, bpath: BusPath, key: bool = False) -> Position:
        return self.smap.key_at(bpath) if key else self.smap.at(bpath)

    def err(self, code: str, message: str, bpath: BusPath, key: bool = False) -> None:
        self.d.add(code, message, self.at(bpath, key))

    def warn(self, code: str, message: str, bpath: BusPath, key: bool = False) -> None:
        self.d.add(code, message, self.at(bpath, key), "warning")

    def strict(self, code: str, message: str, bpath: BusPath, key: bool = False) -> None:
        """What netcfg cannot map: an error, with --lenient a warning."""
        if self.options.lenient:
            self.warn(code, message + " (--lenient: kept as a comment)", bpath, key)
        else:
            self.err(code, message + "; fix it, or pass --lenient to keep it as a comment", bpath, key)

    def where(self, bpath: BusPath) -> str:
        dotted = ".".join(str(p) for p in bpath)
        return f"{self.name} line {self.at(bpath, key=True).line}: {dotted}"

    def note(self, bpath: BusPath, key: bool = True) -> dict[str, str]:
        """The `# netcfg:` comment on the line of bpath's key (or value)."""
        line = self.at(bpath, key).line
        return parse_annotation(self.lines[line - 1]) if 0 < line <= len(self.lines) else {}

    def integer(self, val: Val, what: str, lo: int, hi: int) -> int | None:
        v = val.value
        if isinstance(v, bool) or not isinstance(v, int):
            self.err("bus-yml-value", f"{what} must be a whole number, not {v!r}", val.path)
            return None
        if not lo <= v <= hi:
            self.err("bus-yml-value", f"{what} must be {lo}..{hi}, not {v}", val.path)
            return None
        return v

    def mapping(self, val: Val, what: str) -> dict[str, Any] | None:
        if not isinstance(val.value, dict):
            self.err("bus-yml-value", f"{what} must be a mapping of keys to values", val.path)
            return None
        return val.value

    def sub(self, cfg: dict[Any, Any], path: BusPath) -> dict[str, Val]:
        return {str(k): Val(v, (*path, str(k))) for k, v in cfg.items()}

    def keys(self, cfg: dict[str, Val], used: Set[str], kept: Set[str], owner: str, into: list[str]) -> None:
        """Unknown keys are errors (--lenient: warnings); known ones netcfg does not use become comment lines."""
        for key, val in cfg.items():
            if key in used:
                continue
            shown = val.value if not isinstance(val.value, (dict, list)) else f"... (line {self.at(val.path).line})"
            if key in kept:
                into.append(f"{key}: {shown}")
                continue
            self.strict("unknown-key", f"unknown key '{key}' in {owner}", val.path, key=True)
            into.append(f"{key}: {shown} (unknown key)")


    def objects(
        self, val: Val, keys: Set[str], owner: str, shape: str, what: str
    ) -> Iterator[tuple[BusPath, dict[str, Val], int, int]]:
        """A list of {index, sub_index, ...} entries (SDO writes, PDO mapping entries; val.value a list): (its path,
        its keys, index, sub_index) of each entry that names an object, the others reported as the reader goes."""
        for i, item in enumerate(val.value):
            ipath = (*val.path, i)
            if not isinstance(item, dict):
                self.err("bus-yml-value", shape, ipath)
                continue
            cfg = self.sub(item, ipath)
            self.keys(cfg, keys, set(), owner, [])
            if "index" not in cfg:
                self.err("bus-yml-value", f"{owner} needs 'index'", ipath)
                continue
            index = self.integer(cfg["index"], f"{what} index", 0, 0xFFFF)
            sub = self.integer(cfg["sub_index"], f"{what} sub_index", 0, 0xFF) if "sub_index" in cfg else 0
            if index is None or sub is None:
                continue
            yield ipath, cfg, index, sub


def mark(file: str, pos: Position) -> yaml.Mark:
    return yaml.Mark(file, 0, pos.line - 1, pos.column - 1, None, 0)  # type: ignore[arg-type]
