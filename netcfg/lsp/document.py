"""What the language server knows about one spec's text, without the protocol: where the cursor is in the YAML,
which names the spec defines and where, what a hover says, which keys and names fit at the cursor.

The cursor's place is read from the text's indentation and brackets, not from a YAML parser: while a person
types, the buffer is often not valid YAML (`    per` on its own line), and completion matters most then.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from types import UnionType
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel

from netcfg.report_text import num, rate
from netcfg.spec.schema import Spec
from netcfg.spec.source import SourceMap

# A name, a key, a duration word, a path: hyphens only inside (so the `-` of a list item is no part of a word).
_WORD = re.compile(r"[\w./]+(?:-[\w./]+)*")
_KEY = re.compile(r"""(?:"([^"]*)"|'([^']*)'|([^\s:#,\[\]{}'"][^:#,\[\]{}]*?))\s*:(?=\s|$)""")
DID_YOU_MEAN = re.compile(r"did you mean '([^']+)'\?")

# The spec's top-level lists of named items -> the kind of name they define.
KINDS = {"buses": "bus", "nodes": "node", "messages": "message", "flows": "flow", "triggers": "trigger"}
# Keys whose values name an item of the spec (below the top level) -> the kind of name they expect.
NAME_KEYS = {
    "producer": "node", "consumers": "node", "master": "node", "sync_producer": "node", "to": "node",
    "bus": "bus", "buses": "bus", "on_message": "message", "chain": "step",
}


@dataclass(frozen=True)
class Word:
    line: int  # 0-based
    start: int  # 0-based code points
    end: int
    text: str


def word_at(line_text: str, col: int) -> tuple[int, int, str]:
    """The word around column col (code points), or (col, col, '') when there is none."""
    for m in _WORD.finditer(line_text):
        if m.start() <= col <= m.end():
            return m.start(), m.end(), m.group()
        if m.start() > col:
            break
    return col, col, ""


def utf16_column(line_text: str, col: int) -> int:
    """A code point column as LSP counts it by default (UTF-16 code units)."""
    return col + sum(1 for ch in line_text[:col] if ord(ch) > 0xFFFF)


def code_point_column(line_text: str, col16: int) -> int:
    """An LSP (UTF-16) column as a code point column."""
    units = 0
    for i, ch in enumerate(line_text):
        if units >= col16:
            return i
        units += 2 if ord(ch) > 0xFFFF else 1
    return len(line_text)


@dataclass(frozen=True)
class Cursor:
    """Where a position is in the spec's structure. path: the keys from the top, '-' for a list item. key: the key
    whose value the cursor is in (path ends with it), None where a key (or a list item) is written."""

    path: tuple[str, ...]
    key: str | None
    word: Word


def cursor_at(lines: list[str], row: int, col: int) -> Cursor:
    """The structure around (row, col), read from block indentation and, on the cursor's line, flow brackets."""
    stack: list[tuple[int, str, bool]] = []  # (column, key or '-', whether its value is on lines of its own)
    for r in range(min(row, len(lines))):
        _block_tokens(lines[r], stack, None)
    text = lines[row] if row < len(lines) else ""
    start, end, word = word_at(text, col)
    own = _block_tokens(text[:col], stack, col)
    path = tuple(k for _, k, _ in stack)
    key: str | None = None
    if own is not None:  # after `key:` or an opening bracket on the cursor's line
        path, key = _flow(text[own:col], path)
    elif path and path[-1] == "-" and not any(_is_model(t) for t in types_at(path)):
        key = next((k for k in reversed(path) if k != "-"), None)  # an item of a list of names (chain, buses)
    return Cursor(path, key, Word(row, start, end, word))


def _is_model(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def _block_tokens(text: str, stack: list[tuple[int, str, bool]], cursor: int | None) -> int | None:
    """Update the stack with one line's dashes and key. On the cursor's line (cursor given): the column where the
    value after the line's `key:` (or a flow bracket) starts when the cursor is past it, else None."""
    body = text.split(" #", 1)[0]
    stripped = body.lstrip(" ")
    if not stripped or stripped.startswith("#"):
        if cursor is not None:
            _pop(stack, len(text), dash=False)
        return None
    i = len(body) - len(stripped)
    while body.startswith("-", i) and (i + 1 == len(body) or body[i + 1] == " "):
        _pop(stack, i, dash=True)
        stack.append((i, "-", True))
        i += 1
        while i < len(body) and body[i] == " ":
            i += 1
    if i < len(body) and body[i] in "[{":
        if cursor is not None:
            _pop(stack, i, dash=False)
            return i
        return None
    m = _KEY.match(body, i)
    if m is None:
        if cursor is not None:
            _pop(stack, i, dash=False)
        return None
    key = next(g for g in m.groups() if g is not None).strip()
    _pop(stack, i, dash=False)
    stack.append((i, key, not body[m.end():].strip()))
    return m.end() if cursor is not None else None


def _pop(stack: list[tuple[int, str, bool]], col: int, dash: bool) -> None:
    """Leave the entries that enclose column col. A list's dash may stand at its key's own column."""
    while stack:
        c, k, block = stack[-1]
        if c < col or (dash and c == col and k != "-" and block):
            return
        stack.pop()


def _flow(rest: str, path: tuple[str, ...]) -> tuple[tuple[str, ...], str | None]:
    """The path inside a value's flow brackets up to the cursor, and the key whose value the cursor is in (None
    where a key of a flow mapping is written)."""
    frames: list[tuple[str, tuple[str, ...]]] = []  # (list or map, the path where it opened)
    keys: list[str | None] = []  # per frame: the flow mapping's key being written
    token = quote = ""

    def here() -> tuple[str, ...]:
        if not frames:
            return path
        kind, base = frames[-1]
        if kind == "list":
            return (*base, "-")
        return (*base, keys[-1]) if keys[-1] is not None else base

    for ch in rest:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "[{":
            frames.append(("list" if ch == "[" else "map", here()))
            keys.append(None)
            token = ""
        elif ch in "]}" and frames:
            frames.pop()
            keys.pop()
            token = ""
        elif ch == ",":
            if frames and frames[-1][0] == "map":
                keys[-1] = None
            token = ""
        elif ch == ":" and frames and frames[-1][0] == "map" and keys[-1] is None:
            keys[-1] = token.strip()
            token = ""
        else:
            token += ch
    inner = here()
    if frames and frames[-1][0] == "map":
        return inner, keys[-1]
    return inner, next((k for k in reversed(inner) if k != "-"), None)


# The schema, walked by path -------------------------------------------------------------------------------------


def _members(tp: Any) -> list[Any]:
    while get_origin(tp) is Annotated:
        tp = get_args(tp)[0]
    if get_origin(tp) in (Union, UnionType):
        out: list[Any] = []
        for arg in get_args(tp):
            if arg is not type(None):
                out.extend(_members(arg))
        return out
    return [tp]


def _field(model: type[BaseModel], key: str) -> Any:
    for name, info in model.model_fields.items():
        if key in (name, info.alias):
            return info.annotation
    return None


def types_at(path: tuple[str, ...]) -> list[Any]:
    """The schema's types a value at path may have (several where a field is a union)."""
    current: list[Any] = [Spec]
    for part in path:
        nxt: list[Any] = []
        for tp in current:
            for member in _members(tp):
                if part == "-" and get_origin(member) in (list, tuple):
                    nxt.extend(a for a in get_args(member) if a is not Ellipsis)
                elif isinstance(member, type) and issubclass(member, BaseModel):
                    found = _field(member, part)
                    if found is not None:
                        nxt.append(found)
        current = nxt
    return [m for tp in current for m in _members(tp)]


def keys_at(path: tuple[str, ...]) -> dict[str, str]:
    """The keys the schema allows in the mapping at path -> their description ('' if none)."""
    out: dict[str, str] = {}
    for tp in types_at(path):
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            for name, info in tp.model_fields.items():
                out.setdefault(info.alias or name, info.description or "")
    return out


def literals_at(path: tuple[str, ...]) -> list[str]:
    """The words a Literal field at path allows (protocol: can, canopen ...)."""
    out: list[str] = []
    for tp in types_at(path):
        for member in [tp, *(a for a in get_args(tp) if get_origin(tp) in (list, tuple))]:
            if get_origin(member) is Literal:
                out.extend(str(v) for v in get_args(member) if str(v) not in out)
    return out


def expected_kind(cursor: Cursor) -> str | None:
    """The kind of name the value at the cursor refers to: node, bus, message, task, step (a message or a task),
    file, or None."""
    key, path = cursor.key, cursor.path
    if key is None:
        return None
    top = path[0] if path else ""
    if key in ("eds", "import"):
        return "file"
    if key == "tasks" and top == "triggers":
        return "task"
    if key == "name" and len(path) == 3 and top in KINDS:
        return KINDS[top]  # the definition itself
    if len(path) > 1 and key in NAME_KEYS:
        return NAME_KEYS[key]
    return None


# The names a spec defines ---------------------------------------------------------------------------------------


@dataclass
class Index:
    """The names of one spec and where each is defined (0-based line and code point column of the name)."""

    names: dict[str, dict[str, tuple[int, int]]] = field(default_factory=dict)

    def find(self, kind: str, name: str) -> tuple[int, int] | None:
        if kind == "step":
            return self.find("task" if "." in name else "message", name)
        return self.names.get(kind, {}).get(name)

    def of(self, kind: str) -> list[str]:
        if kind == "step":
            return [*self.of("message"), *self.of("task")]
        return list(self.names.get(kind, {}))


def build_index(data: Any, smap: SourceMap) -> Index:
    """The spec's names from its YAML data, placed by the source map the check made of the same text."""
    index = Index({kind: {} for kind in (*KINDS.values(), "task")})
    if not isinstance(data, dict):
        return index

    def place(path: tuple[str | int, ...]) -> tuple[int, int]:
        pos = smap.at(path)
        return pos.line - 1, pos.column - 1

    for key, kind in KINDS.items():
        items = data.get(key)
        for i, item in enumerate(items if isinstance(items, list) else ()):
            if isinstance(item, dict) and isinstance(item.get("name"), str):
                index.names[kind].setdefault(item["name"], place((key, i, "name")))
                if key == "nodes" and isinstance(item.get("tasks"), list):
                    for j, task in enumerate(item["tasks"]):
                        if isinstance(task, dict) and isinstance(task.get("name"), str):
                            ref = f"{item['name']}.{task['name']}"
                            index.names["task"].setdefault(ref, place((key, i, "tasks", j, "name")))
    return index


def target_of(cursor: Cursor, index: Index) -> tuple[str, str] | None:
    """(kind, name) the word at the cursor stands for: by the key it is written under, else by the names it
    matches (a message first, then a node, a bus, a flow)."""
    word = cursor.word.text
    if not word:
        return None
    kind = expected_kind(cursor)
    if kind == "step":
        kind = "task" if "." in word else "message"
    if kind not in (None, "file") and index.find(kind, word) is not None:
        return kind, word
    if kind is None:
        for k in ("message", "node", "bus", "flow", "task"):
            if index.find(k, word) is not None:
                return k, word
    return None


# Hover text from the check report -------------------------------------------------------------------------------


def hover_text(kind: str, name: str, report: dict[str, Any]) -> str | None:
    """Markdown for a message, flow, node or bus, with the figures of the check report."""
    if not report.get("buses") and report.get("errors"):
        return f"**{kind} {name}**\n\nno analysis: the spec has {len(report['errors'])} error(s)"
    if kind == "message":
        return _message_hover(name, report)
    if kind == "flow":
        return _flow_hover(name, report)
    if kind == "node":
        return _node_hover(name, report)
    if kind == "bus":
        return _bus_hover(name, report)
    return None


def _message_hover(name: str, report: dict[str, Any]) -> str | None:
    for bus in report["buses"]:
        for m in bus["messages"]:
            if m["name"] == name:
                ident = f"0x{m['id']:X}" if m.get("id", -1) >= 0 else "-"
                ok = {True: "schedulable", False: "**not schedulable**", None: "no deadline"}[m["schedulable"]]
                lines = [
                    f"**message {name}** on bus {bus['name']} ({bus['protocol']}), id {ident}, {m['size']} bytes, "
                    f"{m['kind']}",
                    "",
                    f"- frame time: {num(m['frame_us_worst'])} us ({m['frame_bits_worst']} bits, worst case)",
                    f"- worst-case response time: {num(m['wcrt_us'])} us",
                    f"- deadline: {num(m['deadline_us'])} us, slack {num(m['slack_us'])} us ({ok})",
                    f"- bus load it adds: {m['utilization']:.2%} of {bus['name']}",
                ]
                return "\n".join(lines)
    return None


def _flow_hover(name: str, report: dict[str, Any]) -> str | None:
    for f in report["flows"]:
        if f["name"] == name:
            u = f["unsynchronised"]
            s = f.get("synchronised")
            lines = [f"**flow {name}** ({f['mode']})", ""]
            if s:
                lines.append(f"- synchronised: {num(s['latency_min_us'])} .. {num(s['latency_max_us'])} us")
            lines.append(f"- unsynchronised: {num(u['latency_min_us'])} .. {num(u['latency_max_us'])} us")
            met = {True: "met", False: "**missed**", None: ""}[f.get("meets_deadline")]
            lines.append(f"- deadline: {num(f['deadline_us'])} us {met}".rstrip())
            return "\n".join(lines)
    return None


def _node_hover(name: str, report: dict[str, Any]) -> str:
    sent = [m["name"] for b in report["buses"] for m in b["messages"] if m.get("producer") == name]
    got = [m["name"] for b in report["buses"] for m in b["messages"] if name in (m.get("consumers") or ())]
    lines = [f"**node {name}**", "", f"- sends {len(sent)} message(s), receives {len(got)}"]
    for n in report.get("nodes") or ():
        if n["name"] == name:
            tasks = ", ".join(f"{t['name']} {num(t['wcrt_us'], false='-')} us" for t in n["tasks"])
            lines.append(f"- processor: {n['scheduling']}, load {n['utilization']:.1%}")
            lines.append(f"- tasks' worst-case response: {tasks or '-'}")
    return "\n".join(lines)


def _bus_hover(name: str, report: dict[str, Any]) -> str | None:
    for bus in report["buses"]:
        if bus["name"] == name:
            return (
                f"**bus {name}** ({bus['protocol']}, {rate(bus['bitrate'])})\n\n"
                f"- utilisation: {bus['utilization']:.1%} worst case\n"
                f"- messages: {len(bus['messages'])}"
            )
    return None


# Diagnostics' ranges and their did-you-mean fixes --------------------------------------------------------------


def diagnostic_word(lines: list[str], line: int, col: int, message: str) -> Word:
    """The word a diagnostic at (line, col) is about: the one there, or, when it names a misspelt word that stands
    elsewhere on the line (a list written in brackets), that word."""
    text = lines[line] if 0 <= line < len(lines) else ""
    start, end, word = word_at(text, col)
    meant = DID_YOU_MEAN.search(message)
    if meant is not None:
        quoted = [q for q in re.findall(r"'([^']+)'", message) if q != meant.group(1)]
        if word not in quoted:
            for q in quoted:
                for m in _WORD.finditer(text):
                    if m.group() == q and m.start() >= min(col, start):
                        return Word(line, m.start(), m.end(), q)
    return Word(line, start, end, word)


def suggested(message: str) -> str | None:
    """The name a diagnostic's "(did you mean 'x'?)" offers."""
    m = DID_YOU_MEAN.search(message)
    return m.group(1) if m else None
