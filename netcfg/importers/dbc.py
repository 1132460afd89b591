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
- CAN FD: a DBC with FD frames (declared by VFrameFormat StandardCAN_FD/ExtendedCAN_FD, or a frame of more than 8
  bytes, with a warning when no VFrameFormat says FD; netcfg.links.dbc_frames reads both) is a `protocol: can-fd`
  bus; its data rate comes from --data-bitrate, else the Vector attribute Baudrate_CANFD, else an error saying how
  to give one. A frame with CANFD_BRS 0 gets `brs: false`; the classical frames on that bus `fd: false`.
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

This module maps a database to spec data and merges `import: F.dbc` on a bus of a YAML spec (merge_bus_imports);
the DBC's text and cantools' reading of it are netcfg.importers.dbc_text's, when messages are sent and how fast
the bus runs netcfg.importers.dbc_timing's, the signals netcfg.importers.dbc_signals'.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cantools.database.can import Database, Message

from netcfg.diagnostics import Collector
from netcfg.importers import Imported, ImportOptions
from netcfg.importers import Path as DataPath
from netcfg.importers.dbc_signals import layout_drops, signal_entry, signal_note
from netcfg.importers.dbc_text import CAN_MAX_PAYLOAD, MAX_FRAME_BYTES, DbcFile, dbc_frame_id, read_dbc
from netcfg.importers.dbc_timing import bitrate, bitrate_text, data_bitrate, message_timing, ms_exact
from netcfg.links.dbc_frames import fd_declared, fd_frame
from netcfg.protocols import PROTOCOLS
from netcfg.spec.names import safe_name
from netcfg.spec.source import SourceMap

PLACEHOLDER_NODE = "unassigned"  # stands for DBC's Vector__XXX (no node)
PLACEHOLDER_RECEIVER = "unassigned_receiver"  # receives a message of 'unassigned' when no other node exists


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



class _Importer(DbcFile):
    """One DBC mapped to spec data, with a comment per item on where it came from."""

    def __init__(self, path: Path, text: str, options: ImportOptions, diags: Collector) -> None:
        super().__init__(path, text, diags)
        self.options = options
        self.comments: dict[DataPath, str] = {}
        self.positions: dict[DataPath, tuple[int, int]] = {}  # (line, column) in the DBC of spec items
        self.message_names = _Names("message", "msg", "_msg")
        self.index = 0  # of the next message in the spec's list (messages that fail are not in it)
        self.fd = False  # the bus has CAN FD frames

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
        rate = bitrate(self, db, self.options)
        if rate is not None:
            bus["bitrate"] = bitrate_text(rate[0])
            self.comments[("buses", 0, "bitrate")] = rate[1]
        self.fd = any(fd_frame(msg) for msg in db.messages)
        data_rate = data_bitrate(self, db, self.options) if self.fd else None
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
            errors: dict[str, Any] = {"interval": ms_exact(float(given("NetcfgErrorInterval")))}
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
        dbc_id = dbc_frame_id(msg)
        name, why = self.message_names.claim(msg.name)
        if why:
            self.add("dbc-name", f"message '{msg.name}': {why}; imported as '{name}'", at, "warning")
        if msg.length > MAX_FRAME_BYTES:
            self.add("dbc-can-fd", f"message '{msg.name}' is {msg.length} bytes: a CAN FD frame has at most 64", at)
            return None
        if msg.length > CAN_MAX_PAYLOAD and not fd_declared(msg):
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
        if self.fd and not fd_frame(msg):
            out["fd"] = False
        elif self.fd and msg.dbc is not None and "CANFD_BRS" in msg.dbc.attributes:
            out.update({} if str(msg.dbc.attributes["CANFD_BRS"].value).strip() == "1" else {"brs": False})
        # --- when it is sent
        timing = message_timing(self, db, msg, at, self.options)
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
        dropped = layout_drops(msg, ordered)
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
            self.comments[("messages", index, "signals", k)] = signal_note(self.lines, s, dbc_id)
            at = self.lines.signals.get((dbc_id, s.name))
            if at:
                self.positions[("messages", index, "signals", k)] = at
            sig = signal_entry(self, safe[s.name], s, safe, msg.name, at)
            big = s.byte_order != "little_endian"
            if big or s.start != bit:  # not right after the previous one: the signal keeps its DBC start bit
                sig = {"name": sig.pop("name"), "start_bit": s.start, **sig}
            out.append(sig)
            if not big:
                bit = s.start + s.length
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
        layer = PROTOCOLS.get(bus.get("protocol"))  # type: ignore[arg-type]
        if layer is None or not layer.link.arbitrates or layer.link.data_phase or not isinstance(name, str):
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
