"""A DBC file as text and as cantools reads it, every problem a diagnostic at the DBC's line.

Owns the limits a DBC statement must keep, the cheap line scan that places every message, signal, node and
attribute (DbcLines), and DbcFile: the prescan of what cantools would choke on or spend unbounded time over,
cantools' load and its errors, and the database and message attribute look-ups. The mapping to a spec is
netcfg.importers.dbc's.
"""

from __future__ import annotations

import logging
import math
import re
from decimal import Decimal
from pathlib import Path
from typing import Any

import cantools.database
from cantools.database.can import Database, Message

from netcfg.diagnostics import Collector, Position, Severity
from netcfg.inputs import read_input_bytes

ENCODING = "cp1252"  # what cantools.database.load_file and DBC tools read by default
CAN_MAX_PAYLOAD = 8
MAX_DIGITS = 40  # a number longer than this in a DBC statement is no identifier, length or time
MAX_SIGNAL_BITS = 64  # cantools' and every DBC tool's limit for one signal
MAX_FRAME_BYTES = 64  # CAN FD's largest payload: no signal starts beyond it
MAX_TIME_MS = 2**31 - 1  # DBC time attributes are INT ms; beyond is out of range

_BO = re.compile(r"^[ \t]*BO_[ \t]+(\d+)[ \t]+([A-Za-z0-9_]+)")
_SG = re.compile(r"^[ \t]*SG_[ \t]+([A-Za-z0-9_]+)")
_BU = re.compile(r"^[ \t]*BU_[ \t]*:(.*)$")
_BA_DB = re.compile(r'^[ \t]*BA_[ \t]+"(\w+)"[ \t]+[^A-Z \t]')  # database attribute: the value follows the name
_BA_BO = re.compile(r'^[ \t]*BA_[ \t]+"(\w+)"[ \t]+BO_[ \t]+(\d+)')  # message attribute
_STATEMENT = re.compile(r"^[ \t]*(BO_|SG_|BA_|BA_DEF_|BA_DEF_DEF_|VAL_|BO_TX_BU_|SG_MUL_VAL_|SIG_VALTYPE_)\b")
_LONG_NUMBER = re.compile(rf"\d{{{MAX_DIGITS + 1},}}")
_EXPONENT = re.compile(rf"(?<![A-Za-z0-9_.])\d+\.?\d*[eE]\+?(\d{{1,{MAX_DIGITS}}})")  # a float literal's exponent
MAX_EXPONENT = 308  # a double's largest decimal exponent
_SG_GEOMETRY = re.compile(r"^[ \t]*SG_[ \t]+\w+[^:]*:[ \t]*(\d+)[ \t]*\|[ \t]*(\d+)[ \t]*@")
_BA_DEF_NUMBER = re.compile(r'^[ \t]*BA_DEF_[ \t]+(?:(?:BU_|BO_|SG_|EV_)[ \t]+)?"(\w+)"[ \t]+(INT|HEX|FLOAT)\b')
_BA_VALUE = re.compile(
    r'^[ \t]*BA_[ \t]+"(\w+)"[ \t]+(?:BU_[ \t]+\w+[ \t]+|BO_[ \t]+\d+[ \t]+|SG_[ \t]+\d+[ \t]+\w+[ \t]+|'
    r"EV_[ \t]+\w+[ \t]+)?(.*?)[ \t]*;"
)
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_BO_LENGTH = re.compile(r"^[ \t]*BO_[ \t]+\d+[ \t]+\w+[ \t]*:[ \t]*(\d+)")
_WORD = re.compile(r"[A-Za-z0-9_]+")
_VAL_ENTRY = re.compile(r"VAL_ (\d{1,20}) (\w+)")
_VAL = re.compile(r"^[ \t]*VAL_[ \t]+(\d{1,20})[ \t]+(\w+)")
_IN_MESSAGE = re.compile(r"in message '?([A-Za-z0-9_]+)'?")



class DbcLines:
    """Where things are in the DBC text: a cheap scan for the lines of BO_, SG_, BU_ and BA_ entries."""

    def __init__(self, text: str) -> None:
        self.messages: dict[int, tuple[int, int]] = {}  # DBC frame id (bit 31 = extended) -> (line, column)
        self.frames: dict[tuple[int, str], tuple[int, int]] = {}  # (DBC frame id, name): two may share an id
        self.message_names: dict[str, tuple[int, int]] = {}
        self.signals: dict[tuple[int, str], tuple[int, int]] = {}
        self.nodes: dict[str, tuple[int, int]] = {}
        self.attributes: dict[str, int] = {}
        self.message_attributes: dict[tuple[str, int], int] = {}  # (attribute, DBC frame id) -> line
        self.value_tables: dict[tuple[int, str], tuple[int, int]] = {}  # VAL_ (DBC frame id, signal) -> position
        current: int | None = None
        for number, line in enumerate(text.splitlines(), start=1):
            if (m := _BO.match(line)) and len(m.group(1)) <= MAX_DIGITS:
                current = int(m.group(1))
                self.messages.setdefault(current, (number, m.start(2) + 1))
                self.frames.setdefault((current, m.group(2)), (number, m.start(2) + 1))
                self.message_names.setdefault(m.group(2), (number, m.start(2) + 1))
            elif (m := _SG.match(line)) and current is not None:
                self.signals.setdefault((current, m.group(1)), (number, m.start(1) + 1))
            elif m := _BU.match(line):
                for w in _WORD.finditer(m.group(1)):
                    self.nodes.setdefault(w.group(0), (number, m.start(1) + w.start() + 1))
            elif m := _BA_DB.match(line):
                self.attributes.setdefault(m.group(1), number)
            elif m := _VAL.match(line):
                self.value_tables.setdefault((int(m.group(1)), m.group(2)), (number, m.start(2) + 1))
                current = None
            elif m := _BA_BO.match(line):
                if len(m.group(2)) <= MAX_DIGITS:
                    self.message_attributes.setdefault((m.group(1), int(m.group(2))), number)
            elif line.strip() and not line[:1].isspace():
                current = None  # a new top-level section ends the signal list



def dbc_frame_id(msg: Message) -> int:
    """The message's identifier as the DBC writes it: bit 31 set for an extended frame."""
    return msg.frame_id | (0x8000_0000 if msg.is_extended_frame else 0)


def read_dbc(path: Path, diags: Collector) -> str | None:
    """The DBC's text through the one input guard (netcfg.inputs: a regular file within the DBC size limit, refused
    before it is read whole), decoded as DBC tools write it. InputError (an OSError) propagates: an I/O problem."""
    return read_input_bytes(path, "DBC").decode(ENCODING, errors="replace")


class DbcFile:
    """One DBC's text, where its items are, and the diagnostics that name its lines."""

    def __init__(self, path: Path, text: str, diags: Collector) -> None:
        self.path, self.text, self.diags = path, text, diags
        self.file = str(path)
        self.lines = DbcLines(text)

    # -- diagnostics ------------------------------------------------------------------------------------
    def pos(self, at: tuple[int, int] | int | None = None) -> Position:
        if isinstance(at, tuple):
            return Position(self.file, at[0], at[1])
        return Position(self.file, at or 1, 1)

    def add(self, code: str, text: str, at: tuple[int, int] | int | None, severity: Severity = "error") -> None:
        self.diags.add(code, text, self.pos(at), severity)  # the position names the file

    def message_at(self, msg: Message) -> tuple[int, int] | None:
        dbc_id = dbc_frame_id(msg)
        return (
            self.lines.frames.get((dbc_id, msg.name))
            or self.lines.messages.get(dbc_id)
            or self.lines.message_names.get(msg.name)
        )


    # -- the database -----------------------------------------------------------------------------------
    def prescan(self) -> bool:
        """What cantools would choke on or spend unbounded time over, as errors at their line; False if any."""
        ok = True
        lines = self.text.splitlines()
        numeric = {m.group(1): m.group(2) for line in lines if (m := _BA_DEF_NUMBER.match(line))}
        for number, line in enumerate(lines, start=1):
            if not _STATEMENT.match(line):
                continue
            problem = _line_problem(line, numeric)
            if problem is not None:
                code, text, column = problem
                self.add(code, text, (number, column))
                ok = False
        return ok

    def load(self) -> Database | None:
        if not self.prescan():
            return None
        try:
            # cantools logs duplicate frames as it overwrites them; netcfg reports them itself (duplicate-id)
            logging.getLogger("cantools").setLevel(logging.ERROR)
            # strict=False: read what DBC tools read; netcfg warns about what cantools only tolerates
            db = cantools.database.load_string(self.text, database_format="dbc", strict=False)
        except Exception as exc:  # cantools raises assorted errors for bad input; all mean "bad DBC"
            self.parse_error(exc)
            return None
        if not isinstance(db, Database):  # pragma: no cover - database_format='dbc' gives a CAN database
            self.add("dbc-parse", "cantools did not read it as a CAN database", None)
            return None
        return db

    def parse_error(self, exc: Exception) -> None:
        cause = getattr(exc, "e_dbc", None) or exc.__cause__ or exc  # cantools wraps the DBC parser's error
        line, column = getattr(cause, "line", None), getattr(cause, "column", None)
        text = str(cause).strip().strip('"')
        at: tuple[int, int] | None = None
        if isinstance(line, int) and isinstance(column, int):
            at = (line, column)
            lines = self.text.splitlines()
            source = lines[line - 1].strip() if 0 < line <= len(lines) else ""
            what = f"invalid DBC syntax in '{source}'" if source else "invalid DBC syntax"
            hint = (
                "; a message needs 'BO_ <id> <name>: <length> <sender>'"
                if source.startswith("BO_")
                else "; a signal needs 'SG_ <name> : <start>|<length>@<1|0><+|-> (<scale>,<offset>) [<min>|<max>] "
                '"<unit>" <receivers>\''
                if source.startswith("SG_")
                else "; is this a DBC file?"
                if line == 1
                else ""
            )
            self.add("dbc-parse", f"{what} at column {column}{hint}", at)
            return
        text = " ".join(text.split())  # one line, as every diagnostic
        if m := _IN_MESSAGE.search(text):
            at = self.lines.message_names.get(m.group(1))
        elif m := _VAL_ENTRY.search(text):  # "unused VAL_ entries in DBC: VAL_ 568 UI_mapSpeedLimit"
            at = self.lines.value_tables.get((int(m.group(1)), m.group(2)))
        if len(text) > 300:
            text = text[:300] + " ..."
        self.add("dbc-parse", f"cantools cannot read this DBC: {text}; fix the DBC", at)

    def db_attribute(self, db: Database, name: str) -> tuple[Any, str] | None:
        """A database-level attribute: (value, where from) from its BA_, else its BA_DEF_DEF_ default if set."""
        if db.dbc is None:
            return None
        attr = db.dbc.attributes.get(name)
        if attr is not None:
            line = self.lines.attributes.get(name)
            return attr.value, f'BA_ "{name}" {attr.value}' + (f", line {line}" if line else "")
        definition = db.dbc.attribute_definitions.get(name)
        if definition is not None and definition.kind is None and definition.default_value not in (None, "", 0, "0"):
            return definition.default_value, f'BA_DEF_DEF_ "{name}" {definition.default_value}, the default'
        return None

    def message_attribute(self, db: Database, msg: Message, name: str, zero: bool = False) -> float | None:
        """A time attribute of a message (ms: GenMsgDelayTime ...): its BA_ value, else the definition's
        default; None when absent or not positive. zero: netcfg's exact attributes, only the message's own BA_
        value, 0 included. A value beyond MAX_TIME_MS is an error at its line."""
        value: Any = None
        if msg.dbc is not None and name in msg.dbc.attributes:
            value = msg.dbc.attributes[name].value
        elif zero:  # netcfg's exact attributes count only where a message gives them
            return None
        elif db.dbc is not None and name in db.dbc.attribute_definitions:
            value = db.dbc.attribute_definitions[name].default_value
        if value is None or isinstance(value, bool):
            return None
        dbc_id = dbc_frame_id(msg)
        line = self.lines.message_attributes.get((name, dbc_id))
        try:
            number = float(Decimal(str(value)))  # exact for huge integers (float() of one overflows)
        except (ArithmeticError, ValueError):
            if str(value).strip():  # a text where a time belongs: say so rather than act as if it were absent
                self.add(
                    "dbc-attribute",
                    f"{name} '{value}' of message '{msg.name}' is not a number of ms; ignored",
                    (line, 1) if line else self.message_at(msg),
                    "warning",
                )
            return None
        if math.isnan(number) or number > MAX_TIME_MS:
            text = str(value) if len(str(value)) <= 20 else f"{str(value)[:12]}... ({len(str(value))} digits)"
            self.add(
                "dbc-range",
                f"{name} {text} of message '{msg.name}' is out of range (0 to {MAX_TIME_MS} ms); fix the DBC",
                (line, 1) if line else self.message_at(msg),
            )
            return None
        return number if number > 0 or (zero and number == 0) else None


def _line_problem(line: str, numeric: dict[str, str]) -> tuple[str, str, int] | None:
    """What in one DBC statement cantools would choke on: (code, message, column), or None. numeric: the
    attributes BA_DEF_ declares INT, HEX or FLOAT, by name."""
    if (m := _BA_VALUE.match(line)) and m.group(1) in numeric and not _NUMBER.match(m.group(2)):
        return (
            "dbc-attribute",
            f"attribute {m.group(1)} is {numeric[m.group(1)]} (BA_DEF_), but its value here is "
            f"{m.group(2)[:40]}, not a number; fix the value",
            m.start(2) + 1,
        )
    huge = next((e for e in _EXPONENT.finditer(line) if int(e.group(1)) > MAX_EXPONENT), None)
    if huge is not None:
        return (
            "dbc-range",
            f"the number {huge.group(0)} is out of range (beyond a double's 1e{MAX_EXPONENT}); fix the DBC",
            huge.start() + 1,
        )
    if m := _LONG_NUMBER.search(line):
        return (
            "dbc-range",
            f"a number of {len(m.group(0))} digits is out of range for a DBC identifier, length or "
            "attribute; fix the DBC",
            m.start() + 1,
        )
    if m := _SG_GEOMETRY.match(line):
        start, length = int(m.group(1)), int(m.group(2))
        name = line.split()[1]
        if not 1 <= length <= MAX_SIGNAL_BITS:
            return (
                "dbc-signal-range",
                f"signal '{name}' is {length} bits long, outside the frame: a DBC signal has 1 to "
                f"{MAX_SIGNAL_BITS} bits; fix its length",
                m.start(2) + 1,
            )
        if start >= 8 * MAX_FRAME_BYTES:
            return (
                "dbc-signal-range",
                f"signal '{name}' starts at bit {start}, outside every frame (a CAN frame has at most "
                f"{MAX_FRAME_BYTES} bytes, bits 0..{8 * MAX_FRAME_BYTES - 1}); fix its start bit",
                m.start(1) + 1,
            )
        return None
    if (m := _BO_LENGTH.match(line)) and int(m.group(1)) > MAX_FRAME_BYTES:
        return (
            "dbc-range",
            f"a message of {m.group(1)} bytes: a CAN frame has at most {MAX_FRAME_BYTES}; fix its length",
            m.start(1) + 1,
        )
    return None
