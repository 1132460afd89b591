"""dbc/<bus>.dbc for every CAN bus (can, canopen, ftt-can), written by cantools from its database model.

What goes in: the bus's nodes; every frame on it (the spec's messages, the implicit SYNC and heartbeats, and on
FTT-CAN the master's trigger message) with its identifier, length, sender and timing; the signals with their
byte order (Intel @1 / Motorola @0), sign, IEEE float type (SIG_VALTYPE_), scale, offset, range, unit,
receivers, multiplexing (M / mN, SG_MUL_VAL_ for extended multiplexing) and value names (VAL_).

Timing, as attributes of the message (BA_ ... BO_):
    GenMsgSendType        ENUM Cyclic (periodic), Spontaneous (sporadic), NoMsgSendType (on-demand)
    GenMsgCycleTime       INT ms, half up, at least 1: the period (Vector's interaction layer and most tools read it)
    GenMsgDelayTime       INT ms, rounded down, at least 1: a sporadic message's minimum inter-arrival time
    GenMsgStartDelayTime  INT ms, half up: a periodic message's offset
    NetcfgPeriod, NetcfgMinInterarrival, NetcfgOffset, NetcfgJitter, NetcfgDeadline
                          FLOAT ms, exact (whole nanoseconds): what the Gen* attributes round, and the release
                          jitter and deadline, which they cannot say. netcfg's DBC importer reads them first,
                          so spec -> DBC -> spec keeps every timing field. NetcfgJitter is the release jitter
                          the analysis gave the message: its own and, for a message a task sends, that task's
                          response-time spread (a DBC has no tasks), so `check` of the DBC times it the same.
Beside them, netcfg's node and bus attributes carry what else check's bounds depend on, where the spec differs
from what a DBC implies: a node's FIFO transmit queue (BU_ NetcfgTxQueue fifo, NetcfgTxQueueDepth,
NetcfgTxQueueOnFull), the senders' clock tolerance (NetcfgClockTolerance, ppm) and the error model
(NetcfgErrorBurst, NetcfgErrorInterval in ms, NetcfgErrorBer). What no attribute carries (a protocol's schedule)
unsaid() lists and build prints.
A message given only as a size gets one unsigned signal spanning its payload, `<message>_raw` (netcfg.runtime
reads and writes it under the same name), so a bus monitor still shows its bytes; a CAN FD payload of more than 8
bytes gets `<message>_raw0`, `_raw1`, ... of 8 bytes each (a DBC signal has at most 64 bits). Comments say what
netcfg knows of each frame (PDO slot, FTT id, implicit role). CAN FD buses carry BusType "CAN FD" and
Baudrate_CANFD, FD frames their VFrameFormat (cantools writes it) and, without bit-rate switch, CANFD_BRS 0.

cantools keeps lists in the order it is given them; messages are sorted by identifier and nodes keep the
spec's order, so the output is byte-identical across builds.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping
from typing import Any

import cantools.database.can as cdb
from cantools.database.can.formats.dbc import DbcSpecifics, dump_string
from cantools.database.can.formats.dbc.dbc_attribute import DbcAttribute
from cantools.database.can.formats.dbc.dbc_attribute_definition import DbcAttributeDefinition
from cantools.database.can.internal_database import InternalDatabase
from cantools.database.conversion import BaseConversion
from cantools.database.namedsignalvalue import NamedSignalValue

from netcfg import links, model, protocols
from netcfg.links import dbc_frames
from netcfg.protocols.base import Unsaid
from netcfg.runtime import raw_signal_name
from netcfg.runtime.codec import Field
from netcfg.templating import field_of

ENCODING = "cp1252"  # what DBC tools (and cantools.database.load_file) read by default


class _Attribute(DbcAttribute):
    """A message's attribute, made for the one write of its database (see _WrittenOnce). cantools' writer deep-copies
    every message's attributes, and with each its definition, before it reads them; a copy of this one would say the
    same (126 drives: 505 messages, 38,000 deepcopy calls, most of the DBC emitter's time)."""

    def __deepcopy__(self, memo: dict[int, Any]) -> _Attribute:
        return self


# Vector's CAN FD attributes
BUS_TYPE = DbcAttributeDefinition("BusType", default_value="CAN", type_name="STRING")
BAUDRATE_CANFD = DbcAttributeDefinition(
    "Baudrate_CANFD", default_value=2_000_000, type_name="INT", minimum=0, maximum=16_000_000
)
CANFD_BRS = DbcAttributeDefinition("CANFD_BRS", default_value="1", kind="BO_", type_name="ENUM", choices=["0", "1"])
# netcfg's node attributes: a FIFO transmit queue (spec: tx_queue), which the analysis bounds otherwise
# netcfg's bus attributes, written where the spec says what the importer's defaults do not: the senders' clock
# tolerance (ppm) and the error model (burst, interval in ms exact to the ns, the environment's bit error rate)
CLOCK_TOLERANCE = DbcAttributeDefinition(
    "NetcfgClockTolerance", default_value=100, type_name="INT", minimum=0, maximum=10_000
)
ERROR_BURST = DbcAttributeDefinition("NetcfgErrorBurst", default_value=0, type_name="INT", minimum=0, maximum=10_000)
ERROR_INTERVAL = DbcAttributeDefinition(
    "NetcfgErrorInterval", default_value=0, type_name="FLOAT", minimum=0, maximum=2**31 - 1
)
ERROR_BER = DbcAttributeDefinition("NetcfgErrorBer", default_value=1e-6, type_name="FLOAT", minimum=0, maximum=1)
DEFAULT_CLOCK_TOLERANCE_PPM = 100  # the spec's default (and so the importer's): written only when another
QUEUE_POLICIES = ["priority", "fifo"]  # the ENUMs' values, in order (the spec's tx_queue policy and on_full)
QUEUE_ON_FULL = ["block", "drop"]
TX_QUEUE = DbcAttributeDefinition(
    "NetcfgTxQueue", default_value="priority", kind="BU_", type_name="ENUM", choices=QUEUE_POLICIES
)
TX_QUEUE_DEPTH = DbcAttributeDefinition(
    "NetcfgTxQueueDepth", default_value=10, kind="BU_", type_name="INT", minimum=1, maximum=2**31 - 1
)
TX_QUEUE_ON_FULL = DbcAttributeDefinition(
    "NetcfgTxQueueOnFull", default_value="block", kind="BU_", type_name="ENUM", choices=QUEUE_ON_FULL
)


def emit(m: model.Model, report: dict[str, Any]) -> dict[str, bytes]:
    files = {}
    for bus in m.buses.values():
        if links.of(bus).arbitrates:
            files[f"dbc/{bus.name}.dbc"] = dbc_text(m, bus, release_jitter(report)).encode(ENCODING, errors="replace")
    return files


def unsaid(m: model.Model) -> dict[str, list[Unsaid]]:
    """Per DBC file, what of its bus's timing a DBC cannot say, so that `netcfg check` of that file does not judge
    it (everything else it says: frames, periods, offsets, release jitter, deadlines, bit rates, and in netcfg's
    attributes FIFO transmit queues, clock tolerance and the error model). `netcfg build` prints these."""
    out: dict[str, list[Unsaid]] = {}
    for bus in m.buses.values():
        if not links.of(bus).arbitrates:
            continue
        lost = list(protocols.of(bus).dbc_unsaid(m, bus))
        remote = [msg.name for msg in bus.messages if msg.remote]
        if remote:  # a DBC's BO_ is a data frame; a remote frame of the same identifier has no line of its own
            lost.append(Unsaid(f"remote frames (RTR) {', '.join(remote)}: a DBC has no remote frames, so they are left "
                               "out and the DBC's bounds leave out their load", False))
        if lost:
            out[f"dbc/{bus.name}.dbc"] = lost
    return out


def release_jitter(report: dict[str, Any]) -> dict[str, int]:
    """Each CAN message's release jitter as the analysis took it (check's jitter_ns): the spec's and what the task
    that sends it adds, which a DBC, having no tasks, can only say as the message's own (NetcfgJitter)."""
    rows = (row for bus in report.get("buses", ()) for row in bus["messages"])
    return {row["name"]: row["jitter_ns"] for row in rows if "jitter_ns" in row}


CANTOOLS_SHORT_NAME = 32  # cantools shortens longer names as it writes (keeping the long one as an attribute)
_NO_NODES = "\r\nBU_: \r\n"  # the node line cantools writes for a database without nodes


class _WrittenOnce(InternalDatabase):
    """A database built for one pass through cantools' DBC writer and dropped after it. The writer deep-copies
    what it is given, so that the names it may shorten stay as they were in the caller's database; copying this
    one would keep nothing anyone reads again, and it was most of the writing time (1,000 frames: 0.16 s)."""

    def __deepcopy__(self, memo: dict[int, Any]) -> _WrittenOnce:
        return self


def write(db: cdb.Database) -> str:
    """db as cantools writes it (Database.as_dbc_string), without its copy first: db is built for this one write,
    and cantools may rename what it must in it (names netcfg gives need no renaming)."""
    # cantools' default re-sorts signals in the comment section; keep the start-bit order of the messages
    once = _WrittenOnce(db.messages, db.nodes, db.buses, db.version, db.dbc)
    return dump_string(once, sort_signals=None, sort_attribute_signals=None)


def dbc_text(m: model.Model, bus: model.Bus, jitter: Mapping[str, int] | None = None) -> str:
    """The bus's DBC file as cantools writes it.

    Before writing, cantools renames every node throughout every frame's sender and receiver lists: nodes x
    frames x receivers steps, most of the writing on a bus of many nodes that hear many frames. For netcfg's
    names, which are DBC names already, that pass changes nothing; so when no node name is long enough for
    cantools to shorten, it writes the database without its nodes and their one line, `BU_:`, is filled in.
    Nodes carry no comment or attribute here, so the bytes are those of the long way (a test compares)."""
    if any(len(name) > CANTOOLS_SHORT_NAME or m.nodes[name].tx_queue.fifo for name in bus.nodes):
        return write(database(m, bus, jitter=jitter))  # a node with attributes is written by cantools
    text = write(database(m, bus, with_nodes=False, jitter=jitter))
    if text.count(_NO_NODES) != 1:  # a cantools that writes the line differently: take the long way
        return write(database(m, bus, jitter=jitter))
    return text.replace(_NO_NODES, f"\r\nBU_: {' '.join(bus.nodes)}\r\n")


SEND_TYPES = ["Cyclic", "Spontaneous", "NoMsgSendType"]  # GenMsgSendType's values, in enum order
_SEND_TYPE = DbcAttributeDefinition(
    "GenMsgSendType", default_value="NoMsgSendType", kind="BO_", type_name="ENUM", choices=SEND_TYPES
)
_INT_MS = {
    name: DbcAttributeDefinition(name, default_value=0, kind="BO_", type_name="INT", minimum=0, maximum=2**31 - 1)
    for name in ("GenMsgDelayTime", "GenMsgStartDelayTime")
}
_EXACT_MS = {
    name: DbcAttributeDefinition(name, default_value=0, kind="BO_", type_name="FLOAT", minimum=0, maximum=2**31 - 1)
    for name in ("NetcfgPeriod", "NetcfgMinInterarrival", "NetcfgOffset", "NetcfgJitter", "NetcfgDeadline")
}


def database(
    m: model.Model, bus: model.Bus, with_nodes: bool = True, jitter: Mapping[str, int] | None = None
) -> cdb.Database:
    """The bus as a cantools database; `jitter`: each message's release jitter as analysed (release_jitter),
    else the spec's own."""
    messages = [_message(m, msg, (jitter or {}).get(msg.name, msg.jitter_ns)) for msg in bus.messages
                if not msg.remote]  # a remote frame is no BO_ (unsaid)
    messages += _own_frames(m, bus)
    messages.sort(key=lambda x: (x.is_extended_frame, x.frame_id, x.name))
    nodes = [_node(m.nodes[name]) for name in bus.nodes] if with_nodes else []
    # DBName (Vector's database attribute) carries the bus name; cantools writes Baudrate itself from the Bus
    db_name = DbcAttributeDefinition("DBName", default_value="", type_name="STRING")
    specifics = DbcSpecifics(
        attributes=OrderedDict(DBName=DbcAttribute(bus.name, db_name)),
        attribute_definitions=OrderedDict(DBName=db_name, GenMsgSendType=_SEND_TYPE, **_INT_MS, **_EXACT_MS),
    )
    for name, definition, value in _bus_attributes(bus):
        specifics.attribute_definitions[name] = definition
        specifics.attributes[name] = DbcAttribute(value, definition)
    if any(m.nodes[name].tx_queue.fifo for name in bus.nodes):
        specifics.attribute_definitions.update(
            NetcfgTxQueue=TX_QUEUE, NetcfgTxQueueDepth=TX_QUEUE_DEPTH, NetcfgTxQueueOnFull=TX_QUEUE_ON_FULL
        )
    if links.of(bus).data_phase:
        # Vector's CAN FD attributes: BusType "CAN FD" makes cantools write each frame's VFrameFormat (its CAN FD
        # format, read back by netcfg.links.dbc_frames); Baudrate_CANFD is the data rate; CANFD_BRS (default 1) marks
        # frames without bit-rate switch
        assert bus.data_bitrate is not None
        specifics.attribute_definitions.update(BusType=BUS_TYPE, Baudrate_CANFD=BAUDRATE_CANFD, CANFD_BRS=CANFD_BRS)
        specifics.attributes["BusType"] = DbcAttribute("CAN FD", BUS_TYPE)
        specifics.attributes["Baudrate_CANFD"] = DbcAttribute(bus.data_bitrate, BAUDRATE_CANFD)
    return cdb.Database(
        messages=messages,
        nodes=nodes,
        buses=[cdb.Bus(bus.name, baudrate=bus.bitrate)],
        version="",
        dbc_specifics=specifics,
        sort_signals=None,  # our signals are already in start-bit order; keep it
    )


def _bus_attributes(bus: model.Bus) -> list[tuple[str, DbcAttributeDefinition, Any]]:
    """netcfg's bus attributes of this bus: what of its timing model differs from what a DBC implies."""
    out: list[tuple[str, DbcAttributeDefinition, Any]] = []
    if bus.clock_tolerance_ppm != DEFAULT_CLOCK_TOLERANCE_PPM:
        out.append(("NetcfgClockTolerance", CLOCK_TOLERANCE, bus.clock_tolerance_ppm))
    if bus.errors is not None:
        out += [
            ("NetcfgErrorBurst", ERROR_BURST, bus.errors.burst),
            ("NetcfgErrorInterval", ERROR_INTERVAL, _ms(bus.errors.interval_ns)),
            ("NetcfgErrorBer", ERROR_BER, bus.errors.ber),
        ]
    return out


def _node(node: model.Node) -> cdb.Node:
    """A node; one with a FIFO transmit queue says so in netcfg's node attributes (NetcfgTxQueue, its depth and
    what a full queue does), which netcfg's DBC importer reads back as the node's tx_queue."""
    q = node.tx_queue
    if not q.fifo:
        return cdb.Node(node.name)
    attrs: OrderedDict[str, DbcAttribute] = OrderedDict()  # an ENUM's value is its index, as GenMsgSendType's
    attrs["NetcfgTxQueue"] = DbcAttribute(QUEUE_POLICIES.index("fifo"), TX_QUEUE)
    attrs["NetcfgTxQueueDepth"] = DbcAttribute(q.depth, TX_QUEUE_DEPTH)
    attrs["NetcfgTxQueueOnFull"] = DbcAttribute(QUEUE_ON_FULL.index(q.on_full), TX_QUEUE_ON_FULL)
    return cdb.Node(node.name, dbc_specifics=DbcSpecifics(attributes=attrs))


def sanitise(text: str) -> str:
    """A DBC comment or unit: one line, no double quote or backslash (cantools escapes quotes with a backslash,
    which many DBC readers do not understand), only characters the file's code page has."""
    text = " ".join(text.replace('"', "'").replace("\\", "/").split())
    return text.encode(ENCODING, errors="replace").decode(ENCODING)


def _whole_ms(ns: int) -> int:
    """Whole milliseconds, half up, in exact integer arithmetic (2.5 ms -> 3)."""
    return (ns + 500_000) // 1_000_000


def _cycle_ms(period_ns: int | None) -> int | None:
    if period_ns is None:
        return None
    return max(1, _whole_ms(period_ns))


def _ms(ns: int) -> float:
    return ns / 1_000_000  # a double holds every whole-ns duration below 2^53 ns exactly enough to round back


def _timing(msg: model.Message, jitter_ns: int) -> DbcSpecifics:
    """The message's timing attributes (see the module docstring)."""
    attrs: OrderedDict[str, DbcAttribute] = OrderedDict()
    kind = {"periodic": 0, "sporadic": 1}.get(msg.kind, 2)
    attrs["GenMsgSendType"] = _Attribute(kind, _SEND_TYPE)
    # an offset is a CAN message's phase inside its period (FTT-CAN's count across the macro-cycle: left out)
    offset_ns = msg.offset_ns if msg.period_ns is not None and (msg.offset_ns or 0) < msg.period_ns else None
    if msg.kind == "periodic" and msg.period_ns is not None:
        attrs["NetcfgPeriod"] = _Attribute(_ms(msg.period_ns), _EXACT_MS["NetcfgPeriod"])
        if offset_ns:
            attrs["GenMsgStartDelayTime"] = _Attribute(_whole_ms(offset_ns), _INT_MS["GenMsgStartDelayTime"])
    elif msg.kind == "sporadic" and msg.interval_ns is not None:
        gap = max(1, msg.interval_ns // 1_000_000)
        attrs["GenMsgDelayTime"] = _Attribute(gap, _INT_MS["GenMsgDelayTime"])
        attrs["NetcfgMinInterarrival"] = _Attribute(_ms(msg.interval_ns), _EXACT_MS["NetcfgMinInterarrival"])
    if offset_ns is not None and msg.kind == "periodic":
        attrs["NetcfgOffset"] = _Attribute(_ms(offset_ns), _EXACT_MS["NetcfgOffset"])
    if jitter_ns:
        attrs["NetcfgJitter"] = _Attribute(_ms(jitter_ns), _EXACT_MS["NetcfgJitter"])
    if msg.deadline_ns is not None:
        attrs["NetcfgDeadline"] = _Attribute(_ms(msg.deadline_ns), _EXACT_MS["NetcfgDeadline"])
    return DbcSpecifics(attributes=attrs)


def _message(m: model.Model, msg: model.Message, jitter_ns: int) -> cdb.Message:
    receivers = sorted(msg.consumers)
    if msg.signals:
        signals = [
            _signal(field_of(s), s.unit, receivers, _entry_comment(msg, k), s.is_multiplexer)
            for k, s in enumerate(msg.signals)
        ]
    elif 0 < msg.size <= 8:
        raw = Field(raw_signal_name(msg.name), 0, 8 * msg.size)
        signals = [_signal(raw, None, receivers, "the whole payload (the spec gives only a size)")]
    elif msg.size:  # a CAN FD payload: a DBC signal has at most 64 bits, so the raw bytes go in 8-byte pieces
        signals = [
            _signal(
                Field(f"{raw_signal_name(msg.name)}{k}", 64 * k, min(64, 8 * msg.size - 64 * k)),
                None,
                receivers,
                f"payload bytes {8 * k}..{min(8 * k + 7, msg.size - 1)} (the spec gives only a size)",
            )
            for k in range((msg.size + 7) // 8)
        ]
    else:
        signals = []
    specifics = _timing(msg, jitter_ns)
    if msg.fd and not msg.brs:
        specifics.attributes["CANFD_BRS"] = _Attribute("0", CANFD_BRS)
    return dbc_frames.message(
        msg.fd,  # the length a DBC gives an FD frame is its padded data length
        frame_id=msg.id,
        name=msg.name,
        length=msg.frame_size,
        signals=signals,
        comment=_message_comment(m, msg),
        senders=[msg.producer],
        cycle_time=_cycle_ms(msg.period_ns) if msg.kind == "periodic" else None,
        is_extended_frame=msg.extended,
        bus_name=msg.bus,
        sort_signals=None,
        dbc_specifics=specifics,
    )


def _signal(
    f: Field, unit: str | None, receivers: list[str], comment: str | None, is_multiplexer: bool = False
) -> cdb.Signal:
    choices: OrderedDict[int, str | NamedSignalValue] | None = (
        OrderedDict((raw, sanitise(name)) for raw, name in f.choices) if f.choices else None
    )
    return cdb.Signal(
        name=f.name,
        start=f.start_bit,  # DBC's start bit is ours: the least (Intel) or most (Motorola) significant bit
        length=f.bits,
        byte_order="big_endian" if f.big_endian else "little_endian",
        is_signed=f.signed or f.is_float,  # an IEEE float carries its sign: DBC tools write floats as signed
        conversion=BaseConversion.factory(scale=f.scale, offset=f.offset, choices=choices, is_float=f.is_float),
        is_multiplexer=is_multiplexer,
        multiplexer_ids=list(f.mux_values) if f.mux is not None else None,
        multiplexer_signal=f.mux,
        minimum=f.minimum,
        maximum=f.maximum,
        unit=sanitise(unit) if unit else None,
        receivers=receivers,
        comment=sanitise(comment) if comment else None,
    )


def _entry_comment(msg: model.Message, k: int) -> str | None:
    if msg.pdo is None:
        return None
    e = msg.pdo.entries[k]
    return f"object 0x{e.index:04X}:{e.sub}"


def _message_comment(m: model.Model, msg: model.Message) -> str | None:
    parts = []
    if msg.description:
        parts.append(msg.description)
    if msg.implicit == "SYNC":
        parts.append("CANopen SYNC")
    elif msg.implicit == "heartbeat":
        parts.append(f"CANopen heartbeat of {msg.producer}")
    if msg.pdo is not None:
        node = m.nodes[msg.pdo.node]
        parts.append(
            f"{msg.pdo.kind.upper()}{msg.pdo.number} of {node.name} (node {node.node_id}), "
            f"transmission type {msg.pdo.transmission}"
        )
    if msg.window == "sync":
        parts.append(f"FTT-CAN synchronous message, FTT id {msg.ftt_id}")
    elif msg.window == "async":
        parts.append("FTT-CAN asynchronous message")
    if msg.kind != "periodic" and msg.interval_ns is not None:
        parts.append(f"{msg.kind}, at least {msg.interval_ns / 1e6:g} ms apart")
    return sanitise("; ".join(parts)) if parts else None


def _own_frames(m: model.Model, bus: model.Bus) -> list[cdb.Message]:
    """The frames the bus's protocol sends besides the spec's messages (FTT-CAN's trigger message,
    Protocol.own_frames), each with one unsigned field spanning its payload."""
    out = []
    for f in protocols.of(bus).own_frames(bus):
        if f.name in m.messages or any(x.name == f.name for x in bus.messages):
            continue  # the name is taken by a spec message; leave the frame out rather than rename it
        out.append(
            dbc_frames.message(
                f.fd,
                frame_id=f.id,
                name=f.name,
                length=f.size,
                signals=[_signal(Field(f.field, 0, 8 * f.size), None, list(f.receivers), None)],
                comment=f.comment,
                senders=[f.sender],
                cycle_time=_cycle_ms(f.period_ns),
                is_extended_frame=f.extended,
                bus_name=bus.name,
                sort_signals=None,
            )
        )
    return out
