"""YAML with source positions.

PyYAML's constructor forgets where values came from. We compose the node tree ourselves and record the
position of every mapping key and value and every sequence item under its path, so that any later error
(pydantic's or our own) can name file, line and column. Duplicate keys, which PyYAML silently overwrites,
are reported here.
"""

from __future__ import annotations

from typing import Any

import yaml

from netcfg.diagnostics import Collector, Position

Path = tuple[str | int, ...]
# libyaml's parser when PyYAML was built with it (twice as fast), the pure-Python one otherwise; both give marks.
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
MAX_ITEMS = 300_000  # values after alias expansion: refuses "billion laughs" documents
MAX_TEXT_CHARS = 16 * 1024 * 1024  # as netcfg.inputs' limit for specs and bus.yml files
MAX_DEPTH = 64  # a spec nests 6 levels; libyaml itself stops at 1,000 with a less helpful message
MAX_NUMBER_CHARS = 40  # an integer or float written with more characters is no quantity netcfg knows
# The tags a spec may carry, explicitly or implicitly: YAML's core schema. A timestamp is read as the text it is
# (the field's type check then names it); sets, pairs, binary, python/... are refused.
_SCALAR_TAGS = {
    "tag:yaml.org,2002:null",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:int",
    "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:str",
}
_TIMESTAMP = "tag:yaml.org,2002:timestamp"
_STR = "tag:yaml.org,2002:str"


class SourceMap:
    """Maps a path inside the spec, e.g. ("messages", 3, "period"), to where it was written.

    It keeps PyYAML's marks as they are and makes Positions only when asked: a large spec has ~10^5 values."""

    def __init__(self, file: str) -> None:
        self.file = file
        self._values: dict[Path, yaml.Mark] = {}
        self._keys: dict[Path, yaml.Mark] = {}

    @classmethod
    def from_positions(cls, file: str, positions: dict[Path, tuple[int, int]]) -> SourceMap:
        """A map of another format's positions ((line, column), 1-based), e.g. of the DBC a spec came from."""
        smap = cls(file)
        for path, (line, column) in positions.items():
            smap.record(path, yaml.Mark(file, 0, line - 1, column - 1, None, 0))
        return smap

    def record(self, path: Path, value: yaml.Mark, key: yaml.Mark | None = None) -> None:
        self._values[path] = value
        if key is not None:
            self._keys[path] = key

    def _position(self, mark: yaml.Mark) -> Position:
        return Position(self.file, mark.line + 1, mark.column + 1)

    def at(self, path: Path) -> Position:
        """Position of the value at path, or of its nearest recorded ancestor."""
        p = tuple(path)
        while p:
            if p in self._values:
                return self._position(self._values[p])
            p = p[:-1]
        root = self._values.get(())
        return self._position(root) if root is not None else Position(self.file, 1, 1)

    def key_at(self, path: Path) -> Position:
        """Position of the key that introduces path (falls back to the value, then to ancestors)."""
        key = self._keys.get(tuple(path))
        return self._position(key) if key is not None else self.at(path)

    def has(self, path: Path) -> bool:
        return tuple(path) in self._values


def _pos(file: str, node: yaml.Node) -> Position:
    return Position(file, node.start_mark.line + 1, node.start_mark.column + 1)


def load_yaml(text: str, file: str, diags: Collector) -> tuple[Any, SourceMap]:
    """Parse YAML text (one document). Syntax errors, duplicate keys, tags outside the accepted set, values that do
    not convert, too much nesting or size go to diags; returns (data, source map).

    The size is checked before the document is composed (MAX_TEXT_CHARS); libyaml composes up to 1,000 levels without
    recursing in Python, and the walk over the composed nodes stops at MAX_DEPTH and after MAX_ITEMS values, so a
    hostile document costs one linear pass."""
    smap = SourceMap(file)
    if len(text) > MAX_TEXT_CHARS:
        diags.add("too-large", f"the file is {len(text):,} characters; netcfg reads at most {MAX_TEXT_CHARS:,}",
                  Position(file, 1, 1))
        return None, smap
    try:
        root = yaml.compose(text, Loader=_LOADER)
    except yaml.MarkedYAMLError as exc:
        if exc.problem and "nesting depth" in exc.problem and exc.problem_mark is not None:  # libyaml's 1,000 levels
            diags.add("yaml-syntax", _TOO_DEEP, Position(file, exc.problem_mark.line + 1, exc.problem_mark.column + 1))
        else:
            diags.add("yaml-syntax", _syntax_message(exc, text), _syntax_position(exc, file))
        return None, smap
    except yaml.YAMLError as exc:  # e.g. reader errors on binary input
        diags.add("yaml-syntax", f"cannot read YAML: {exc}", Position(file, 1, 1))
        return None, smap
    except RecursionError:
        diags.add("yaml-syntax", "the YAML is nested too deep for a spec; flatten it", Position(file, 1, 1))
        return None, smap
    if root is None:
        diags.add("empty-spec", "the spec is empty; start with 'system: <name>'", Position(file, 1, 1))
        return None, smap
    constructor = yaml.SafeLoader("")
    smap.record((), root.start_mark)
    budget = [MAX_ITEMS]
    try:
        return _build(root, (), file, smap, constructor, diags, budget), smap
    except yaml.constructor.ConstructorError as exc:
        mark = exc.problem_mark
        pos = Position(file, mark.line + 1, mark.column + 1) if mark else Position(file, 1, 1)
        diags.add("yaml-value", f"cannot read this value: {exc.problem}", pos)
    except RecursionError:
        diags.add("yaml-syntax", "the YAML is nested too deep for a spec; flatten it", Position(file, 1, 1))
    except _TooBig as exc:
        diags.add("too-large", f"the spec expands to more than {MAX_ITEMS} items (through YAML aliases?)", exc.pos)
    except _TooDeep as exc:
        diags.add("yaml-syntax", _TOO_DEEP, exc.pos)
    return None, smap


_TOO_DEEP = f"the YAML is nested more than {MAX_DEPTH} levels deep; flatten it"


class _TooBig(Exception):
    def __init__(self, pos: Position) -> None:
        self.pos = pos


class _TooDeep(Exception):
    """A mapping or list nested more than MAX_DEPTH levels (aliases count where they are used)."""

    def __init__(self, pos: Position) -> None:
        self.pos = pos


def _syntax_position(exc: yaml.MarkedYAMLError, file: str) -> Position:
    # An unclosed '[' or '{' is reported where the parser gave up; point at the bracket that was left open.
    mark = exc.context_mark if exc.context and "flow" in exc.context and exc.context_mark else exc.problem_mark
    mark = mark or exc.context_mark
    return Position(file, mark.line + 1, mark.column + 1) if mark else Position(file, 1, 1)


def _syntax_message(exc: yaml.MarkedYAMLError, text: str) -> str:
    mark = exc.problem_mark
    lines = text.splitlines()
    if mark is not None and mark.line < len(lines) and "\t" in lines[mark.line][: mark.column + 1]:
        return "YAML syntax error: a tab character here; YAML indents with spaces only, replace it"
    what = exc.problem or "invalid YAML"
    if exc.context and "flow" in exc.context and exc.problem_mark:
        where = exc.problem_mark
        return (
            f"YAML syntax error: a bracket opened here is not closed ({what}, line {where.line + 1}, column "
            f"{where.column + 1}); close it or put the list on one line"
        )
    ctx = f" ({exc.context})" if exc.context else ""
    return f"YAML syntax error: {what}{ctx}; fix the indentation or quoting here"


def _build_key(node: yaml.Node, file: str, ctor: yaml.SafeLoader, diags: Collector) -> Any:
    if isinstance(node, yaml.ScalarNode):
        return _scalar(node, file, ctor, diags)
    return node  # a mapping or list as a key: refused by the caller


_PLAIN_TAGS = {"tag:yaml.org,2002:map", "tag:yaml.org,2002:seq", "tag:yaml.org,2002:omap"}


def _build(
    node: yaml.Node, path: Path, file: str, smap: SourceMap, ctor: yaml.SafeLoader, diags: Collector, budget: list[int]
) -> Any:
    budget[0] -= 1
    if budget[0] < 0:
        raise _TooBig(_pos(file, node))
    if isinstance(node, yaml.ScalarNode):
        return _scalar(node, file, ctor, diags)
    if node.tag not in _PLAIN_TAGS:
        diags.add(
            "yaml-value",
            f"cannot read this value: YAML tags such as '{node.tag}' are not allowed in a spec",
            _pos(file, node),
        )
        return None
    if isinstance(node, yaml.MappingNode):
        if len(path) >= MAX_DEPTH:  # the root mapping is level 1, at path ()
            raise _TooDeep(_pos(file, node))
        own = sum(1 for k, _ in node.value if k.tag != "tag:yaml.org,2002:merge")
        ctor.flatten_mapping(node)  # resolve YAML merge keys (<<): merged pairs first, then the mapping's own
        n_merged = len(node.value) - own
        out: dict[Any, Any] = {}
        merged_keys: set[str] = set()
        for pair_no, (key_node, value_node) in enumerate(node.value):
            reported = len(diags.items)
            key = _build_key(key_node, file, ctor, diags)
            if len(diags.items) > reported:
                continue  # a key that does not convert: already reported (every diagnostic here is an error)
            if not isinstance(key, (str, int)):
                kind = "a list or mapping" if isinstance(key, yaml.Node) else type(key).__name__
                diags.add("yaml-key", f"keys must be plain words, not {kind}", _pos(file, key_node))
                continue
            key = str(key) if not isinstance(key, bool) else str(key).lower()
            if pair_no < n_merged:
                merged_keys.add(key)
            elif key in merged_keys:
                merged_keys.discard(key)  # an explicit key overrides the merged one
                out.pop(key, None)
            if key in out:
                diags.add(
                    "duplicate-key",
                    f"key '{key}' appears twice in this mapping; keep one",
                    _pos(file, key_node),
                )
                continue
            child = (*path, key)
            smap.record(child, value_node.start_mark, key_node.start_mark)
            out[key] = _build(value_node, child, file, smap, ctor, diags, budget)
        return out
    if isinstance(node, yaml.SequenceNode):
        if len(path) >= MAX_DEPTH:
            raise _TooDeep(_pos(file, node))
        items = []
        for i, item in enumerate(node.value):
            child = (*path, i)
            smap.record(child, item.start_mark)
            items.append(_build(item, child, file, smap, ctor, diags, budget))
        return items
    return _scalar(node, file, ctor, diags)


def _scalar(node: yaml.Node, file: str, ctor: yaml.SafeLoader, diags: Collector) -> Any:
    """One scalar of the accepted tag set; a value its tag cannot take (`!!int abc`) or too long a number is an
    error at its position, never an exception."""
    tag = node.tag
    if tag == _STR:  # most scalars: the text as it is (what SafeLoader's str constructor returns)
        return node.value
    if tag == _TIMESTAMP:
        return str(node.value)
    if tag not in _SCALAR_TAGS or not isinstance(node, yaml.ScalarNode):
        diags.add(
            "yaml-value",
            f"cannot read this value: YAML tags such as '{tag}' are not allowed; write a plain value",
            _pos(file, node),
        )
        return None
    if tag in ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float") and len(str(node.value)) > MAX_NUMBER_CHARS:
        diags.add(
            "yaml-value",
            f"cannot read this value: a number of {len(str(node.value)):,} characters is out of range for any "
            f"field (at most {MAX_NUMBER_CHARS})",
            _pos(file, node),
        )
        return None
    try:
        return ctor.yaml_constructors[tag](ctor, node)
    except (ValueError, KeyError, TypeError, OverflowError, yaml.YAMLError):
        short = tag.rsplit(":", 1)[-1]
        diags.add("yaml-value", f"cannot read this value: {str(node.value)[:40]!r} is not a valid {short}",
                  _pos(file, node))
        return None
