"""DBC (Vector CANdb++) -> netcfg spec data, read through cantools.

One DBC describes one CAN or CAN FD bus. The mapping, item by item (what cannot be mapped is a warning naming
it, or an error where no analysis is possible; nothing is dropped silently; --lenient is accepted but no DBC item
needs it any more):

- system: the file stem made a safe name. Bus: `protocol: can`, named from the DBName attribute (else 'can0').
- bus type: the database attribute `BusType`, when given, must be CAN or CAN FD; another (LIN, FlexRay) is an
  error.
- bit rate: --bitrate wins; else the database attribute `Baudrate`, else `BusSpeed` (a BA_ value, else the
  BA_DEF_DEF_ default when it is not 0). Every DBC we found in public repositories (cantools' writer, CANdb++
  style files, generator scripts; BusSpeed too) gives bit/s (`BA_ "Baudrate" 500000;`); a value of at most
  1000 cannot be a CAN bit rate in bit/s, so it is read as kbit/s (with a warning).
  No bit rate at all is an error that says how to give one.
- nodes: BU_ in file order, then every sender or receiver not declared there (a warning each).
- the file is read through the input guard (netcfg.inputs: size limit, regular files only) and checked line by
  line before cantools sees it: numbers of absurd length and signals that no frame can hold (over 64 bits,
  starting beyond byte 63) are errors at their line. cantools then reads it with strict=False, as most DBC tools
  do: what it only tolerates (overlapping signals, signals outside their frame, ...) is a warning naming message
  and signal.
- messages, in file order: name, id, `extended: true` for 29-bit frames (and `id_bits: 29` on the bus when all
  frames are), size = the BO_ length, producer = first sender, consumers = the receivers of its signals.
  A message without sender (Vector__XXX) is sent by the placeholder node 'unassigned' (warning dbc-no-sender);
  one without receivers (read by a logger or a gateway outside the file) is received by all other nodes
  (warning dbc-no-receiver). `netcfg check --werror CODE` makes either an error.
- CAN FD: a DBC with FD frames (cantools' is_fd, from VFrameFormat StandardCAN_FD/ExtendedCAN_FD, or a frame of
  more than 8 bytes, with a warning when no VFrameFormat says FD) is a `protocol: can-fd` bus; its data rate comes
  from --data-bitrate, else the Vector attribute Baudrate_CANFD, else an error saying how to give one. A frame with
  CANFD_BRS 0 gets `brs: false`; the classical frames on that bus `fd: false`.
- timing, from GenMsgSendType (cantools reads its enum, or the definition's default) and, in ms, GenMsgCycleTime,
  GenMsgCycleTimeFast and GenMsgDelayTime (Vector's interaction layer: DelayTime is the least time between two
  transmissions, CycleTimeFast the repetition period while active, also of the GenMsgNrOfRepetition repeats
  of an event); GenMsgStartDelayTime is the offset of a periodic message. netcfg's own exact attributes
  (NetcfgPeriod, NetcfgMinInterarrival, NetcfgOffset, NetcfgJitter, NetcfgDeadline: ms, FLOAT; written by
  `netcfg build`, see netcfg.emit.dbc) win over the rounded Gen* ones. Time values beyond MAX_TIME_MS are errors
  at their BA_ line.
    cyclic kinds (Cyclic, cyclicX, cyclicIfActive)          -> periodic, period GenMsgCycleTime (the fast
                                                               cycle for *Fast types)
    event kinds (Event, Spontaneous, triggered, IfActive,   -> sporadic, min_interarrival the smallest of
      OnChange, OnWrite, ...)                                  GenMsgDelayTime / GenMsgCycleTimeFast; none -> on-demand
    cyclic and event (CE, CA, cyclicAndSpontaneous, ...)     -> sporadic at the smallest of those and the cycle
                                                               time; no gap given -> periodic (warning: events
                                                               between cycles are not analysed)
    none (NoMsgSendType, none, NotUsed) or absent/unknown   -> periodic if GenMsgCycleTime is given (a warning for
                                                               none/unknown: when in doubt we count the load),
                                                               else on-demand
  Every on-demand message gets a warning "not analysed: ..." naming it; `--default-period T` analyses them as
  periodic at T instead (the assumption is named in a warning per message).
- signals map to `signals:` in start-bit order, each with its DBC start bit where it does not follow the
  previous one: little-endian (Intel) and big-endian (Motorola, `byte_order: big_endian`, start bit = the most
  significant bit, DBC numbering) alike, signed, float, scaled; multiplexed ones (simple and extended
  multiplexing) with `mux: {signal, values}`, value tables (VAL_) as `enum`. A message whose signals overlap
  in one frame or reach outside it keeps only its size (a warning naming message and signal).
- names (system, bus, nodes, messages, signals) are made safe (letters, digits, '_', starting with a letter, no C
  keyword) and collisions (also differing only in case) get a suffix _2, _3 ... in file order, with a warning.
- netcfg's own node and bus attributes (written by netcfg.emit.dbc): NetcfgTxQueue fifo (with NetcfgTxQueueDepth,
  NetcfgTxQueueOnFull) -> the node's tx_queue; NetcfgClockTolerance -> clock_tolerance; NetcfgErrorInterval (ms,
  with NetcfgErrorBurst, NetcfgErrorBer) -> errors. Only where the DBC gives them (BA_).
- comments: where each item came from (BO_/SG_/BU_ line, attribute values), written above it by write_spec;
  what the spec has no key for (signal comments, further BO_TX_BU_ senders) goes there too. Positions of the
  messages and signals are kept, so that `netcfg check F.dbc` places a later error (a duplicate identifier)
  at the DBC's line.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path
from typing import Any

import cantools.database
from cantools.database.can import Database, Message, Signal

from netcfg.diagnostics import Collector, Position, Severity
from netcfg.importers import Imported, ImportOptions
from netcfg.importers import Path as DataPath
from netcfg.inputs import read_input_bytes
from netcfg.runtime.codec import byte_ops, int_range, last_byte
from netcfg.spec.schema import safe_name
from netcfg.spec.source import SourceMap
from netcfg.spec.units import format_ns

ENCODING = "cp1252"  # what cantools.database.load_file and DBC tools read by default
PLACEHOLDER_NODE = "unassigned"  # stands for DBC's Vector__XXX (no node)
PLACEHOLDER_RECEIVER = "unassigned_receiver"  # receives a message of 'unassigned' when no other node exists
CAN_MAX_PAYLOAD = 8
KBIT_LIMIT = 1000  # Baudrate/BusSpeed values up to this are kbit/s: no CAN bus runs at 1000 bit/s or less
# the largest public DBC files are a few MB; anything far beyond is not a database (or /dev/zero)
MAX_DIGITS = 40  # a number longer than this in a DBC statement is no identifier, length or time
MAX_SIGNAL_BITS = 64  # cantools' and every DBC tool's limit for one signal
MAX_FRAME_BYTES = 64  # CAN FD's largest payload: no signal starts beyond it
MAX_TIME_MS = 2**31 - 1  # DBC time attributes are INT ms; beyond is out of range
TIME_ATTRIBUTES = (
    "GenMsgCycleTime",
    "GenMsgCycleTimeFast",
    "GenMsgDelayTime",
    "GenMsgStartDelayTime",
    "NetcfgPeriod",
    "NetcfgMinInterarrival",
    "NetcfgOffset",
    "NetcfgJitter",
    "NetcfgDeadline",
)

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

# GenMsgSendType values seen in DBCs in the wild, lower-cased without punctuation (see send_kind)
_NONE_KINDS = ("none", "nomsgsendtype", "nosendtype", "notused", "reserved", "")
_EVENT_WORDS = ("event", "spontan", "trigger", "ifactive", "onchange", "onwrite", "request")


class _Lines:
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


@dataclass
class _Timing:
    data: dict[str, Any]  # period / min_interarrival / type keys of the spec message
    note: str  # for the provenance comment


class _Names:
    """Safe, unique names for one kind of item; the first in file order keeps its name."""

    def __init__(self, kind: str, prefix: str, suffix: str) -> None:
        self.kind, self.prefix, self.suffix = kind, prefix, suffix
        self.taken: set[str] = set()

    def claim(self, raw: str) -> tuple[str, str | None]:
        """-> (name, why it differs from raw, or None)."""
        name = safe_name(raw, self.prefix, self.suffix)
        why = (
            None if name == raw else f"'{raw}' is not a safe name (letters, digits, '_', a letter first, no C keyword)"
        )
        base, n = name, 2
        while name.lower() in self.taken:  # names become file names: they must differ in more than case
            tail = f"_{n}"
            name = base[: 63 - len(tail)] + tail
            n += 1
        if name != base:
            why = f"{self.kind} name '{base}' is already used (names may not differ only in case)"
        self.taken.add(name.lower())
        return name, why

    def reserve(self, name: str) -> None:
        self.taken.add(name.lower())


def send_kind(send_type: str | None) -> str:
    """GenMsgSendType -> 'cyclic', 'event', 'mixed', 'none', 'absent' or 'unknown' (see the module docstring)."""
    if send_type is None:
        return "absent"
    key = re.sub(r"[^a-z]", "", send_type.lower())
    if key in _NONE_KINDS or key.startswith("notused"):
        return "none"
    if key in ("ce", "ca"):  # Vector's short forms: Cyclic+Event, Cyclic+IfActive
        return "mixed"
    if key.startswith("cyclic"):
        rest = key[len("cyclic") :].removeprefix("ifactive")  # cyclicIfActive: cyclic while active, no events
        return "mixed" if "and" in rest or any(w in rest for w in _EVENT_WORDS) else "cyclic"
    if any(w in key for w in _EVENT_WORDS):
        return "event"
    return "unknown"


def ms_text(ms: float) -> str:
    """A DBC time attribute (ms) as a spec duration, exact: 10 -> '10 ms', 2.5 -> '2.5 ms'."""
    value = Decimal(str(ms))
    text = format(value.normalize(), "f") if value != value.to_integral_value() else str(int(value))
    return f"{text} ms"


def _ms_exact(ms: float) -> str:
    """netcfg's own FLOAT ms attributes carry whole nanoseconds: back to the exact duration."""
    return format_ns(round(ms * 1_000_000))


# netcfg's exact timing attributes (ms, FLOAT), by spec key
_EXACT = {
    "period": "NetcfgPeriod",
    "min_interarrival": "NetcfgMinInterarrival",
    "offset": "NetcfgOffset",
    "jitter": "NetcfgJitter",
    "deadline": "NetcfgDeadline",
}


def bitrate_text(bps: int) -> str:
    for unit, scale in (("Mbit/s", 1_000_000), ("kbit/s", 1_000)):
        if bps % scale == 0:
            return f"{bps // scale} {unit}"
    return f"{bps} bit/s"


def _number(value: float) -> float | int:
    """Integral floats as ints: the spec reads the same, and the YAML says '1' rather than '1.0'."""
    return int(value) if isinstance(value, float) and abs(value) < 2**53 and value.is_integer() else value


class _Importer:
    def __init__(self, path: Path, text: str, options: ImportOptions, diags: Collector) -> None:
        self.path, self.text, self.options, self.diags = path, text, options, diags
        self.file = str(path)
        self.lines = _Lines(text)
        self.comments: dict[DataPath, str] = {}
        self.positions: dict[DataPath, tuple[int, int]] = {}  # (line, column) in the DBC of spec items
        self.message_names = _Names("message", "msg", "_msg")
        self.index = 0  # of the next message in the spec's list (messages that fail are not in it)
        self.fd = False  # the bus has CAN FD frames

    # -- diagnostics ------------------------------------------------------------------------------------
    def pos(self, at: tuple[int, int] | int | None = None) -> Position:
        if isinstance(at, tuple):
            return Position(self.file, at[0], at[1])
        return Position(self.file, at or 1, 1)

    def add(self, code: str, text: str, at: tuple[int, int] | int | None, severity: Severity = "error") -> None:
        self.diags.add(code, text, self.pos(at), severity)  # the position names the file

    def message_at(self, msg: Message) -> tuple[int, int] | None:
        dbc_id = msg.frame_id | (0x8000_0000 if msg.is_extended_frame else 0)
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
            if (m := _BA_VALUE.match(line)) and m.group(1) in numeric and not _NUMBER.match(m.group(2)):
                self.add(
                    "dbc-attribute",
                    f"attribute {m.group(1)} is {numeric[m.group(1)]} (BA_DEF_), but its value here is "
                    f"{m.group(2)[:40]}, not a number; fix the value",
                    (number, m.start(2) + 1),
                )
                ok = False
                continue
            huge = next((e for e in _EXPONENT.finditer(line) if int(e.group(1)) > MAX_EXPONENT), None)
            if huge is not None:
                self.add(
                    "dbc-range",
                    f"the number {huge.group(0)} is out of range (beyond a double's 1e{MAX_EXPONENT}); fix the DBC",
                    (number, huge.start() + 1),
                )
                ok = False
            elif m := _LONG_NUMBER.search(line):
                self.add(
                    "dbc-range",
                    f"a number of {len(m.group(0))} digits is out of range for a DBC identifier, length or "
                    "attribute; fix the DBC",
                    (number, m.start() + 1),
                )
                ok = False
            elif m := _SG_GEOMETRY.match(line):
                start, length = int(m.group(1)), int(m.group(2))
                name = line.split()[1]
                if not 1 <= length <= MAX_SIGNAL_BITS:
                    self.add(
                        "dbc-signal-range",
                        f"signal '{name}' is {length} bits long, outside the frame: a DBC signal has 1 to "
                        f"{MAX_SIGNAL_BITS} bits; fix its length",
                        (number, m.start(2) + 1),
                    )
                    ok = False
                elif start >= 8 * MAX_FRAME_BYTES:
                    self.add(
                        "dbc-signal-range",
                        f"signal '{name}' starts at bit {start}, outside every frame (a CAN frame has at most "
                        f"{MAX_FRAME_BYTES} bytes, bits 0..{8 * MAX_FRAME_BYTES - 1}); fix its start bit",
                        (number, m.start(1) + 1),
                    )
                    ok = False
            elif (m := _BO_LENGTH.match(line)) and int(m.group(1)) > MAX_FRAME_BYTES:
                self.add(
                    "dbc-range",
                    f"a message of {m.group(1)} bytes: a CAN frame has at most {MAX_FRAME_BYTES}; fix its length",
                    (number, m.start(1) + 1),
                )
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
        dbc_id = msg.frame_id | (0x8000_0000 if msg.is_extended_frame else 0)
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

    @staticmethod
    def is_fd(msg: Message) -> bool:
        return bool(msg.is_fd) or msg.length > CAN_MAX_PAYLOAD

    def data_bitrate(self, db: Database) -> tuple[int, str] | None:
        """The CAN FD data rate: --data-bitrate, else Vector's Baudrate_CANFD attribute."""
        if self.options.data_bitrate is not None:
            return self.options.data_bitrate, "from the command line (--data-bitrate), which wins over the DBC"
        fd_names = [f"message '{m.name}'" for m in db.messages if self.is_fd(m)]
        more = f" and {len(fd_names) - 3} more" if len(fd_names) > 3 else ""
        got = self.db_attribute(db, "Baudrate_CANFD")
        if got is not None:
            try:
                number = round(float(str(got[0]).strip()))
            except ValueError:
                number = 0
            if number > 0:
                return number, f"{got[1]}, in bit/s"
        self.add(
            "dbc-data-bitrate",
            f"the DBC has CAN FD frames ({', '.join(fd_names[:3])}{more}) but no data bit rate (no Baudrate_CANFD "
            "attribute); give one on the command "
            'line, e.g. `--data-bitrate 2M`, or add `BA_ "Baudrate_CANFD" 2000000;` to the DBC',
            self.lines.attributes.get("Baudrate_CANFD"),
        )
        return None

    def bitrate(self, db: Database) -> tuple[int, str] | None:
        if self.options.bitrate is not None:
            return self.options.bitrate, "from the command line (--bitrate), which wins over the DBC"
        for name in ("Baudrate", "BusSpeed"):
            got = self.db_attribute(db, name)
            if got is None:
                continue
            value, where = got
            at = self.lines.attributes.get(name)
            try:
                number = float(str(value).strip())
            except ValueError:
                self.add("dbc-bitrate", f"cannot read {where} as a bit rate; give one with --bitrate 500k", at)
                return None
            if number <= 0:
                continue
            if number <= KBIT_LIMIT:
                bps = round(number * 1000)
                self.add(
                    "dbc-bitrate",
                    f"{where}: read as {number:g} kbit/s (values up to {KBIT_LIMIT} cannot be bit/s); "
                    "give --bitrate to override",
                    at,
                    "warning",
                )
                return bps, f"{where}, read as kbit/s"
            return round(number), f"{where}, in bit/s"
        self.add(
            "dbc-bitrate",
            "no bit rate: the DBC has no Baudrate or BusSpeed attribute; give one on the command line, e.g. "
            "`--bitrate 500k` (netcfg check FILE.dbc --bitrate 500k, netcfg import dbc FILE.dbc --bitrate 500k -o "
            'SPEC), or add `BA_ "Baudrate" 500000;` to the DBC',
            None,
        )
        return None

    # -- the spec -------------------------------------------------------------------------------------------
    def run(self) -> Imported | None:
        db = self.load()
        if db is None:
            return None
        system, why = _Names("system", "dbc", "_net").claim(self.path.stem)
        self.comments[("system",)] = f"from the file name {self.path.name}"
        if why:
            self.add("dbc-name", f"system name: {why}; imported as '{system}'", None, "warning")

        bus: dict[str, Any] = {"name": "can0", "protocol": "can"}
        db_name = self.db_attribute(db, "DBName")
        raw_bus = str(db_name[0]) if db_name and str(db_name[0]).strip() else None
        if raw_bus is not None and db_name is not None:
            bus["name"], why = _Names("bus", "can", "_bus").claim(raw_bus)
            self.comments[("buses", 0)] = f"one classical CAN bus: the DBC's {db_name[1]}"
            if why:
                self.add(
                    "dbc-name",
                    f"bus name: {why}; imported as '{bus['name']}'",
                    self.lines.attributes.get("DBName"),
                    "warning",
                )
        else:
            self.comments[("buses", 0)] = "one classical CAN bus; the DBC has no DBName attribute, so it is 'can0'"
        bus_type = self.db_attribute(db, "BusType")
        if bus_type is not None and not str(bus_type[0]).strip().upper().startswith("CAN"):
            self.add(
                "dbc-bus-type",
                f"the DBC describes a {str(bus_type[0]).strip()} bus ({bus_type[1]}); netcfg analyses CAN buses",
                self.lines.attributes.get("BusType"),
            )
            return None
        rate = self.bitrate(db)
        if rate is not None:
            bus["bitrate"] = bitrate_text(rate[0])
            self.comments[("buses", 0, "bitrate")] = rate[1]
        self.fd = any(self.is_fd(msg) for msg in db.messages)
        data_rate = self.data_bitrate(db) if self.fd else None
        if self.fd:
            bus["protocol"] = "can-fd"
            if data_rate is not None:
                bus["data_bitrate"] = bitrate_text(data_rate[0])
                self.comments[("buses", 0, "data_bitrate")] = data_rate[1]
        if db.buses and db.buses[0].comment:
            bus["description"] = db.buses[0].comment.strip()
        self.bus_model(db, bus)

        nodes = self.nodes(db)
        messages = [m for m in (self.message(db, msg, nodes) for msg in db.messages) if m is not None]
        if messages and all(m.get("extended") for m in messages):
            bus["id_bits"] = 29
        node_list = [
            {
                "name": n.name,
                "buses": [bus["name"]],
                **({"description": n.description} if n.description else {}),
                **({"tx_queue": n.tx_queue} if n.tx_queue else {}),
            }
            for n in nodes.values()
        ]
        for i, n in enumerate(nodes.values()):
            self.comments[("nodes", i)] = n.origin
        if not node_list:
            self.add(
                "dbc-node", "no nodes: the DBC declares no BU_ and no message names a sender; add a BU_ line", None
            )
        if rate is None or (self.fd and data_rate is None) or self.diags.errors:
            return None
        data: dict[str, Any] = {"system": system, "buses": [bus], "nodes": node_list, "messages": messages}
        return data, self.comments

    def bus_model(self, db: Database, bus: dict[str, Any]) -> None:
        """netcfg's bus attributes (written by netcfg.emit.dbc where the spec differs from the defaults): the
        senders' clock tolerance and the error model, only where the DBC gives them (BA_)."""
        attrs = db.dbc.attributes if db.dbc is not None else {}

        def given(name: str) -> Any:
            return attrs[name].value if name in attrs else None

        def origin(name: str) -> str:
            line = self.lines.attributes.get(name)
            return f'BA_ "{name}" {attrs[name].value}' + (f", line {line}" if line else "")

        if given("NetcfgClockTolerance") is not None:
            bus["clock_tolerance"] = int(given("NetcfgClockTolerance"))
            self.comments[("buses", 0, "clock_tolerance")] = origin("NetcfgClockTolerance")
        if given("NetcfgErrorInterval") is not None:
            errors: dict[str, Any] = {"interval": _ms_exact(float(given("NetcfgErrorInterval")))}
            if given("NetcfgErrorBurst") is not None:
                errors["burst"] = int(given("NetcfgErrorBurst"))
            if given("NetcfgErrorBer") is not None:
                errors["ber"] = float(given("NetcfgErrorBer"))
            bus["errors"] = errors
            self.comments[("buses", 0, "errors")] = origin("NetcfgErrorInterval")

    def nodes(self, db: Database) -> dict[str, _Node]:
        """Declared nodes (BU_) first, then the senders and receivers nobody declared, in file order."""
        names = _Names("node", "node", "_node")
        names.reserve(PLACEHOLDER_NODE)
        names.reserve(PLACEHOLDER_RECEIVER)
        out: dict[str, _Node] = {}
        for node in db.nodes:
            if node.name == "Vector__XXX":  # "no node", even where BU_ lists it
                continue
            at = self.lines.nodes.get(node.name)
            name, why = names.claim(node.name)
            line = f", line {at[0]}" if at else ""
            out[node.name] = _Node(name, f"BU_ {node.name}{line}", (node.comment or "").strip() or None)
            queue = _tx_queue(db, node)
            if queue is not None:
                out[node.name].tx_queue = queue
                out[node.name].origin += ", NetcfgTxQueue (netcfg's node attributes)"
            if why:
                self.add("dbc-name", f"node '{node.name}': {why}; imported as '{name}'", at, "warning")
        for msg in db.messages:
            for role, raw in [("sender", s) for s in msg.senders[:1]] + [
                ("receiver", r) for s in msg.signals for r in s.receivers
            ]:
                if raw in out or raw == "Vector__XXX":
                    continue
                at = self.message_at(msg)
                name, why = names.claim(raw)
                line = f" (line {at[0]})" if at else ""
                out[raw] = _Node(name, f"not declared in BU_: {role} of BO_ {msg.name}{line}", None)
                self.add(
                    "dbc-node",
                    f"node '{raw}', {role} of message '{msg.name}', is not declared in BU_; imported as node "
                    f"'{name}' (add it to BU_ to silence this)",
                    at,
                    "warning",
                )
        return out

    def placeholder(self, nodes: dict[str, _Node], name: str = PLACEHOLDER_NODE) -> str:
        key = "Vector__XXX" if name == PLACEHOLDER_NODE else f"Vector__XXX/{name}"  # no DBC name has a '/'
        if key not in nodes:
            nodes[key] = _Node(name, "placeholder for DBC's Vector__XXX (no node)", None)
        return name

    def message(self, db: Database, msg: Message, nodes: dict[str, _Node]) -> dict[str, Any] | None:
        at = self.message_at(msg)
        line = f", line {at[0]}" if at else ""
        dbc_id = msg.frame_id | (0x8000_0000 if msg.is_extended_frame else 0)
        name, why = self.message_names.claim(msg.name)
        if why:
            self.add("dbc-name", f"message '{msg.name}': {why}; imported as '{name}'", at, "warning")
        if msg.length > MAX_FRAME_BYTES:
            self.add("dbc-can-fd", f"message '{msg.name}' is {msg.length} bytes: a CAN FD frame has at most 64", at)
            return None
        if msg.length > CAN_MAX_PAYLOAD and not msg.is_fd:
            self.add(
                "dbc-can-fd",
                f"message '{msg.name}' has {msg.length} bytes but no VFrameFormat saying CAN FD; imported as a CAN FD "
                "frame (set VFrameFormat StandardCAN_FD or ExtendedCAN_FD to silence this)",
                at,
                "warning",
            )
        out: dict[str, Any] = {"name": name}
        # --- who sends and who receives
        if msg.senders:
            producer = nodes[msg.senders[0]].name
            others = msg.senders[1:]
        else:
            self.add(
                "dbc-no-sender",
                f"message '{msg.name}' has no sender (Vector__XXX); analysed as sent by the placeholder node "
                f"'{PLACEHOLDER_NODE}' (name the sending node in its BO_ line)",
                at,
                "warning",
            )
            producer, others = self.placeholder(nodes), []
        # Vector__XXX among receivers means "no node"; it never stands for the placeholder sender
        receivers = {nodes[r].name for s in msg.signals for r in s.receivers if r in nodes and r != "Vector__XXX"}
        # node order, not signal order: the same set always gives the same list
        consumers = [n.name for n in nodes.values() if n.name in receivers and n.name != producer]
        receivers_note = ""  # the usual case (the receivers of its signals) needs no note
        if not consumers:
            # common and legal: read by a logger or a gateway outside the file; the bus load is the same
            rest = [n.name for n in nodes.values() if n.name not in (producer, PLACEHOLDER_NODE, PLACEHOLDER_RECEIVER)]
            if not rest:
                rest = [PLACEHOLDER_NODE if producer != PLACEHOLDER_NODE else PLACEHOLDER_RECEIVER]
                self.placeholder(nodes, rest[0])
            self.add(
                "dbc-no-receiver",
                f"message '{msg.name}' has no receiver (no signal names a receiving node, or only Vector__XXX); "
                f"analysed as received by {', '.join(rest)} (list the receivers at the end of its SG_ lines)",
                at,
                "warning",
            )
            consumers, receivers_note = rest, "no receivers in the DBC: consumers are all other nodes"
        out["producer"] = producer
        out["consumers"] = consumers
        out["id"] = msg.frame_id
        if msg.is_extended_frame:
            out["extended"] = True
        out["size"] = msg.length
        if self.fd and not self.is_fd(msg):
            out["fd"] = False
        elif self.fd and msg.dbc is not None and "CANFD_BRS" in msg.dbc.attributes:
            out.update({} if str(msg.dbc.attributes["CANFD_BRS"].value).strip() == "1" else {"brs": False})
        # --- when it is sent
        timing = self.timing(db, msg, at)
        out.update(timing.data)
        # --- what it carries
        signals = self.signals(msg, dbc_id)
        if signals is not None:
            out["signals"] = signals
        if msg.comment and msg.comment.strip():
            out["description"] = msg.comment.strip()
        frame = f"0x{msg.frame_id:X}" + (", extended" if msg.is_extended_frame else "")
        senders = f"sender {msg.senders[0]}" if msg.senders else "no sender"
        if others:
            senders += " (also sent by " + ", ".join(others) + "; netcfg keeps the first)"
        note = f"BO_ {dbc_id} {msg.name} ({frame}){line}, {senders}\n{timing.note}"
        if at is not None:
            for key in ((), ("name",), ("id",), ("size",), ("producer",)):
                item: DataPath = ("messages", self.index, *key)
                self.positions[item] = at
        self.comments[("messages", self.index)] = note + (f"\n{receivers_note}" if receivers_note else "")
        self.index += 1
        return out

    def timing(self, db: Database, msg: Message, at: tuple[int, int] | None) -> _Timing:
        exact = {key: self.message_attribute(db, msg, name, zero=True) for key, name in _EXACT.items()}
        if exact["period"] is not None or exact["min_interarrival"] is not None:
            # netcfg's own attributes: the spec's timing, exactly (written by netcfg.emit.dbc); the rounded
            # Gen* attributes beside them are for other tools
            key = "period" if exact["period"] is not None else "min_interarrival"
            timing = _Timing({key: _ms_exact(exact[key] or 0)}, f"{_EXACT[key]} {_ms_exact(exact[key] or 0)}")
        elif "period" in (timing := self.send_timing(db, msg, at)).data:
            start = self.message_attribute(db, msg, "GenMsgStartDelayTime")
            if start is not None:
                timing.data["offset"] = ms_text(start)
                timing.note += f", GenMsgStartDelayTime {ms_text(start)} (offset)"
        for key in ("offset", "jitter", "deadline"):
            if exact[key] is not None and "type" not in timing.data:
                timing.data[key] = _ms_exact(exact[key] or 0)
                timing.note += f", {_EXACT[key]} {_ms_exact(exact[key] or 0)}"
        return timing

    def send_timing(self, db: Database, msg: Message, at: tuple[int, int] | None) -> _Timing:
        send_type = msg.send_type
        kind = send_kind(send_type)
        cycle = self.message_attribute(db, msg, "GenMsgCycleTime")
        fast = self.message_attribute(db, msg, "GenMsgCycleTimeFast")
        delay = self.message_attribute(db, msg, "GenMsgDelayTime")
        said = f"GenMsgSendType {send_type}" if send_type is not None else "no GenMsgSendType"
        cyc = f"GenMsgCycleTime {ms_text(cycle)}" if cycle else "no GenMsgCycleTime"

        def on_demand(why: str) -> _Timing:
            assumed = self.options.default_period_ns
            if assumed is not None:
                self.add(
                    "dbc-default-period",
                    f"message '{msg.name}': {why}; analysed as periodic every {format_ns(assumed)} "
                    "(--default-period)",
                    at,
                    "warning",
                )
                return _Timing({"period": format_ns(assumed)}, f"{said}, {cyc}: --default-period assumed")
            self.add(
                "dbc-not-analysed",
                f"message '{msg.name}' not analysed: {why}; imported as 'type: on-demand' (give it a period or "
                "min_interarrival in the spec if it is sent regularly, or assume one with --default-period)",
                at,
                "warning",
            )
            return _Timing({"type": "on-demand"}, f"{said}, {cyc}: on-demand, not analysed")

        repeats = self.message_attribute(db, msg, "GenMsgNrOfRepetition")
        fast_name = "GenMsgCycleTimeFast" + (f" (also between the {repeats:g} repetitions)" if repeats else "")
        gaps = [(v, n) for v, n in ((delay, "GenMsgDelayTime"), (fast, fast_name)) if v]
        if kind == "cyclic":
            period = fast if "fast" in (send_type or "").lower() and fast else cycle
            if period is None:
                return on_demand(f"{said} but no GenMsgCycleTime")
            src = "GenMsgCycleTimeFast" if period is not cycle else "GenMsgCycleTime"
            return _Timing({"period": ms_text(period)}, f"{said}, {src} {ms_text(period)}")
        if kind == "event" or (kind == "mixed" and cycle is None):
            if not gaps:
                return on_demand(f"{said} with no GenMsgDelayTime or GenMsgCycleTimeFast to bound its rate")
            gap, src = min(gaps)
            return _Timing({"min_interarrival": ms_text(gap)}, f"{said}: sporadic, {src} {ms_text(gap)} apart")
        if kind == "mixed":
            assert cycle is not None
            if not gaps:
                self.add(
                    "dbc-event-timing",
                    f"message '{msg.name}': {said} also sends on events, but no GenMsgDelayTime or "
                    f"GenMsgCycleTimeFast bounds them; analysed as periodic at {cyc} only",
                    at,
                    "warning",
                )
                return _Timing({"period": ms_text(cycle)}, f"{said}, {cyc}: events between cycles not analysed")
            gap, src = min([*gaps, (cycle, "GenMsgCycleTime")])
            return _Timing(
                {"min_interarrival": ms_text(gap)}, f"{said}, {cyc}: sporadic, at least {src} {ms_text(gap)} apart"
            )
        # none, unknown or absent send type: the cycle time decides
        if cycle is None:
            return on_demand("no GenMsgCycleTime" + (f" ({said})" if send_type is not None else ""))
        if kind != "absent":
            self.add(
                "dbc-send-type",
                f"message '{msg.name}': {said} is not a cyclic send type, but {cyc} is given; analysed as periodic",
                at,
                "warning",
            )
        return _Timing({"period": ms_text(cycle)}, f"{said}, {cyc}")

    def signals(self, msg: Message, dbc_id: int) -> list[dict[str, Any]] | None:
        index = self.index
        if not msg.signals:
            return None
        names = _Names(f"signal of {msg.name}", "sig", "_sig")
        ordered, seen = [], set()
        for s in msg.signals:  # a second signal of the same name: cantools keeps both, nothing can tell them apart
            if s.name in seen:
                self.add(
                    "dbc-signal-layout",
                    f"signal '{s.name}' of message '{msg.name}' appears twice (cantools only tolerates this); the "
                    "second is left out of the message's signals",
                    self.message_at(msg),
                    "warning",
                )
                continue
            seen.add(s.name)
            ordered.append(s)
        ordered.sort(key=lambda s: (s.start, s.name))
        safe: dict[str, str] = {}
        for s in ordered:  # the DBC's own names first: a filler never takes one of them
            name, why = names.claim(s.name)
            safe[s.name] = name
            if why:
                at = self.lines.signals.get((dbc_id, s.name))
                self.add(
                    "dbc-name", f"signal '{s.name}' of message '{msg.name}': {why}; imported as '{name}'", at, "warning"
                )
        dropped = self.layout_drops(msg, ordered)
        for gone, why in dropped.items():
            self.add(
                "dbc-signal-layout",
                f"signal '{gone}' of message '{msg.name}' {why} (cantools only tolerates this); left out of the "
                "message's signals",
                self.lines.signals.get((dbc_id, gone)) or self.message_at(msg),
                "warning",
            )
        ordered = [s for s in ordered if s.name not in dropped]
        if not ordered:
            return None
        out: list[dict[str, Any]] = []
        bit = 0
        for s in ordered:
            k = len(out)
            self.comments[("messages", index, "signals", k)] = self.signal_note(s, dbc_id)
            at = self.lines.signals.get((dbc_id, s.name))
            if at:
                self.positions[("messages", index, "signals", k)] = at
            sig = self.signal(safe[s.name], s, safe, msg.name, at)
            big = s.byte_order != "little_endian"
            if big or s.start != bit:  # not right after the previous one: the signal keeps its DBC start bit
                sig = {"name": sig.pop("name"), "start_bit": s.start, **sig}
            out.append(sig)
            if not big:
                bit = s.start + s.length
        return out

    def layout_drops(self, msg: Message, signals: list[Signal]) -> dict[str, str]:
        """The signals netcfg cannot lay out, with the reason: reaching outside the frame, a float of other than
        32 or 64 bits, a multiplexer that is not a signal, or overlapping a signal that can be in the same
        frame. Of overlapping signals the narrower ones are kept (a wide one is often a group of the others)."""
        names = {s.name: s for s in signals}
        drops: dict[str, str] = {}
        masks: dict[str, int] = {}
        for s in signals:
            big = s.byte_order != "little_endian"
            if s.conversion.scale == 0:
                drops[s.name] = "has a scale of 0 (every raw value would mean the offset)"
            elif s.is_float and s.length not in (32, 64):
                drops[s.name] = f"is a float of {s.length} bits (IEEE 754 floats have 32 or 64)"
            elif s.multiplexer_signal is not None and s.multiplexer_signal not in names:
                drops[s.name] = f"is multiplexed by '{s.multiplexer_signal}', which is not a signal of the message"
            elif big and s.length > s.start % 8 + 1 + 8 * (MAX_FRAME_BYTES - 1 - s.start // 8):
                drops[s.name] = "runs past the end of the largest frame"
            elif last_byte(s.start, s.length, big) >= msg.length:
                drops[s.name] = f"reaches outside the frame of {msg.length} bytes"
            else:
                masks[s.name] = sum(op.mask << (8 * op.index) for op in byte_ops(s.start, s.length, big))

        def conditions(s: Signal) -> dict[str, set[int]]:
            out: dict[str, set[int]] = {}
            while s.multiplexer_signal is not None and s.multiplexer_signal in names:
                if s.multiplexer_signal in out:
                    break
                out[s.multiplexer_signal] = set(s.multiplexer_ids or ())
                s = names[s.multiplexer_signal]
            return out

        kept: list[Signal] = []
        for s in sorted((s for s in signals if s.name in masks), key=lambda s: (s.length, s.start, s.name)):
            cond = conditions(s)
            clash = next(
                (
                    k
                    for k in kept
                    if masks[k.name] & masks[s.name]
                    and not any(m in cond and not (v & cond[m]) for m, v in conditions(k).items())
                ),
                None,
            )
            if clash is None:
                kept.append(s)
            else:
                drops[s.name] = f"overlaps signal '{clash.name}'"
        # a signal multiplexed by a left-out multiplexer cannot be placed either
        changed = True
        while changed:
            changed = False
            for s in signals:
                if s.name not in drops and s.multiplexer_signal in drops:
                    drops[s.name] = f"is multiplexed by '{s.multiplexer_signal}', which is left out"
                    changed = True
        return drops

    def signal_note(self, s: Signal, dbc_id: int) -> str:
        """Where the signal is, and what the spec has no place for: its DBC comment and value names (VAL_)."""
        at = self.lines.signals.get((dbc_id, s.name))
        note = f"SG_ {s.name}" + (f", line {at[0]}" if at else "")
        if s.comment and s.comment.strip():
            note += ": " + " ".join(s.comment.split())
        return note

    def signal(
        self, name: str, s: Signal, safe: dict[str, str], message: str = "", at: tuple[int, int] | None = None
    ) -> dict[str, Any]:
        out: dict[str, Any] = {"name": name, "bits": s.length}
        if s.byte_order != "little_endian":
            out["byte_order"] = "big_endian"
        if s.is_float:
            out["float"] = True
        elif s.is_signed:
            out["signed"] = True
        scale, offset = s.conversion.scale, s.conversion.offset
        if scale != 1:
            out["scale"] = _number(float(scale))
        if offset != 0:
            out["offset"] = _number(float(offset))
        low, high = s.minimum, s.maximum
        if low is not None and high is not None and low > high:
            self.add(
                "dbc-signal-range",
                f"signal '{s.name}' of message '{message}': its range [{low}|{high}] has min above max (cantools "
                "only tolerates this); imported without a range",
                at,
                "warning",
            )
            low = high = None
        for key, bound in (("min", low), ("max", high)):
            if bound is not None and math.isfinite(float(bound)):
                out[key] = _number(float(bound))
        if s.unit:
            out["unit"] = s.unit
        if s.multiplexer_signal is not None:
            out["mux"] = {"signal": safe[s.multiplexer_signal], "values": sorted(set(s.multiplexer_ids or ()))}
        if s.choices:
            lo, hi = int_range(s.length, s.is_signed)
            fits = {int(raw): str(text) for raw, text in s.choices.items() if lo <= int(raw) <= hi}
            if len(fits) < len(s.choices):
                self.add(
                    "dbc-signal-enum",
                    f"signal '{s.name}' of message '{message}': {len(s.choices) - len(fits)} of its value names "
                    f"(VAL_) are for values that {s.length} bits cannot hold ({lo}..{hi}); left out",
                    at,
                    "warning",
                )
            if fits:
                out["enum"] = dict(sorted(fits.items()))
        return out


@dataclass
class _Node:
    name: str
    origin: str
    description: str | None
    tx_queue: dict[str, Any] | None = None  # the spec's tx_queue, from netcfg's node attributes


TX_QUEUE_ATTRIBUTES = {"policy": "NetcfgTxQueue", "depth": "NetcfgTxQueueDepth", "on_full": "NetcfgTxQueueOnFull"}


def _tx_queue(db: Database, node: Any) -> dict[str, Any] | None:
    """A node's transmit queue from netcfg's node attributes (written by netcfg.emit.dbc), or None: ENUM values
    are read by their index into the definition's choices, as cantools keeps them."""
    attrs = node.dbc.attributes if node.dbc is not None else {}
    if TX_QUEUE_ATTRIBUTES["policy"] not in attrs:
        return None
    out: dict[str, Any] = {}
    for key, name in TX_QUEUE_ATTRIBUTES.items():
        if name not in attrs:
            continue
        value = attrs[name].value
        choices = getattr(db.dbc.attribute_definitions.get(name) if db.dbc else None, "choices", None)
        if choices and isinstance(value, int) and 0 <= value < len(choices):
            value = choices[value]
        out[key] = value
    return out if out.get("policy") == "fifo" else None


Positions = dict[DataPath, tuple[int, int]]


def read_dbc(path: Path, diags: Collector) -> str | None:
    """The DBC's text through the one input guard (netcfg.inputs: a regular file within the DBC size limit, refused
    before it is read whole), decoded as DBC tools write it. InputError (an OSError) propagates: an I/O problem."""
    return read_input_bytes(path, "DBC").decode(ENCODING, errors="replace")


def import_dbc_located(path: Path, options: ImportOptions, diags: Collector) -> tuple[Imported | None, Positions]:
    """import_dbc, and where each message and signal of the spec is in the DBC: (line, column) by spec path."""
    text = read_dbc(path, diags)
    if text is None:
        return None, {}
    importer = _Importer(path, text, options, diags)
    return importer.run(), importer.positions


def import_dbc(path: Path, options: ImportOptions, diags: Collector) -> Imported | None:
    """The spec a user would write for this DBC, with comments saying where each item came from; None (with
    errors in diags) when it cannot be mapped. OSError propagates (the CLI reports it as an I/O problem)."""
    return import_dbc_located(path, options, diags)[0]


# keys that say when a message is sent: a spec message that gives one replaces all of the DBC's
_TIMING_KEYS = ("period", "rate", "period_range", "min_interarrival", "type", "offset")


def merge_bus_imports(data: dict[str, Any], smap: SourceMap, base: Path, diags: Collector) -> dict[str, Any]:
    """`import: file.dbc` on a bus of a YAML spec: the DBC's nodes and messages join that bus.

    A node of the DBC that the spec declares keeps the spec's entry (the bus is added to its buses); a message
    of the spec with the name of a DBC message adds its keys to the DBC's (a deadline, jitter, ...) and, when it
    says when the message is sent, its timing replaces the DBC's. The spec's own bus entry (bitrate ...) wins.
    Errors in the DBC name the DBC's file and line; a missing file names the spec's `import` line."""
    data = dict(data)
    buses = list(data.get("buses") or [])
    nodes = [dict(n) if isinstance(n, dict) else n for n in data.get("nodes") or []]
    messages = [dict(m) if isinstance(m, dict) else m for m in data.get("messages") or []]
    for i, bus in enumerate(buses):
        if not isinstance(bus, dict) or "import" not in bus:
            continue
        at = ("buses", i, "import")
        bus = dict(bus)
        source = bus.pop("import")
        buses[i] = bus
        name = bus.get("name")
        if not isinstance(source, str) or not source.lower().endswith(".dbc"):
            diags.add("import", "'import' names a DBC file, e.g. import: vehicle.dbc", smap.at(at))
            continue
        if bus.get("protocol") not in ("can", "canopen", "ftt-can") or not isinstance(name, str):
            diags.add("import", "a DBC describes a CAN bus: import it on a bus with protocol can", smap.at(at))
            continue
        path = base / source
        try:
            got = import_dbc(path, ImportOptions(bitrate=1), diags)  # the spec's bus gives the bit rate
        except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
            diags.add("import", f"cannot read {source!r}: {getattr(exc, 'strerror', None) or exc}", smap.at(at))
            continue
        if got is None:
            continue
        dbc = got[0]
        declared = {n.get("name", "").lower(): n for n in nodes if isinstance(n, dict)}
        for node in dbc["nodes"]:
            mine = declared.get(node["name"].lower())
            if mine is None:
                nodes.append({**node, "buses": [name]})
            elif isinstance(mine.get("buses"), list) and name not in mine["buses"]:
                mine["buses"] = [*mine["buses"], name]
        by_name = {m.get("name"): k for k, m in enumerate(messages) if isinstance(m, dict)}
        for imported in dbc["messages"]:
            imported = {**imported, "bus": name}
            k = by_name.get(imported["name"])
            if k is None:
                messages.append(imported)
                continue
            ours = messages[k]
            if any(key in ours for key in _TIMING_KEYS):
                imported = {key: v for key, v in imported.items() if key not in _TIMING_KEYS}
            messages[k] = {**imported, **ours}
    data["buses"], data["nodes"], data["messages"] = buses, nodes, messages
    return data
