"""c/<node>.h: one C header per node that sends or receives anything (every node of an FTT-CAN bus receives
the trigger message, so each gets one).

The header (templates/node.h.j2) holds the node's constants, its buses' timing, the FTT-CAN triggers that
activate its tasks, and for every message it sends or receives: identifier, size, timing, and a struct of the
signals with `static inline` pack/unpack functions. The layout is netcfg.runtime.codec's, byte for byte:
little-endian signals read the payload as one little-endian word from their least significant bit,
big-endian (Motorola) ones run down from their most significant bit in DBC numbering; integers are
unsigned or two's complement, floats IEEE 754, physical = raw * scale + offset, min/max bound the physical
value. Multiplexed signals are packed and unpacked only when their multiplexers select them; value names
become C enums (or #defines for values beyond an int). A message given only as a size is one unsigned
field `<message>_raw` spanning the payload, as in the runtime and the DBC files (payloads over 8 bytes stay raw
bytes).

Python only prepares the view below: which bytes each signal touches and with which shift, the bounds a
value must meet; the C text is all in the template. Identifiers are the spec's names (already checked to be
C identifiers and not keywords) behind a prefix per kind of name, because nodes, buses and messages each
have their own namespace in the spec: NODE_<node>_*, BUS_<bus>_*, MSG_<message>_* / msg_<message>_*,
TRIG_<trigger>_*.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from netcfg import links, model, protocols
from netcfg.records import same_named
from netcfg.runtime import codec, raw_signal_name
from netcfg.templating import environment, render
from netcfg.timing.frames import canfd_dlc

# integer widths a C99 <stdint.h> always has on our targets
_WIDTHS = (8, 16, 32, 64)


@dataclass(frozen=True)
class ByteOp:
    """One payload byte a signal touches: byte `index` holds the signal's bits from `shift` up (right shift
    of the raw value), or, for the first byte of a signal that does not start on a byte boundary, the raw
    value shifted left by `-shift`."""

    index: int
    shift: int


@dataclass(frozen=True)
class SignalView:
    name: str
    start_bit: int
    bits: int
    kind: str  # "int" (exact integer), "scaled" (raw integer, physical = raw * scale + offset), "float" (IEEE)
    signed: bool
    ctype: str
    word: str  # unsigned type of the float's bits (memcpy target)
    mask: int | None  # raw mask, None for 64-bit fields
    sign_bit: int
    ops: tuple[ByteOp, ...]
    lo: int | None  # "int", "scaled": bound on the field (raw); None = the C type's own limit
    hi: int | None
    minimum: str | None  # physical bounds as C double literals ("scaled", "float")
    maximum: str | None
    scale: str
    offset: str
    q_lo: str  # "scaled": before rounding, q = (value - offset) / scale lies in (q_lo, q_hi), [q_lo, q_hi) unsigned
    q_hi: str
    unit: str | None
    raw_only: bool  # the `<message>_raw` field of a message given only as a size
    big_endian: bool = False
    be_ops: tuple[codec.ByteOp, ...] = ()  # big-endian: the byte parts, masked (netcfg.runtime.codec.byte_ops)
    end_bit: int = 0  # one past the highest payload bit it needs (whole bytes for big-endian)
    present: str | None = None  # multiplexed: the C condition on the multiplexers' raw values
    mux_note: str | None = None  # ... in words, for the struct's comment
    is_multiplexer: bool = False
    mux_depth: int = 0  # multiplexers are packed and unpacked before the signals they select
    enum_type: str | None = None  # `enum msg_<message>_<signal>` when it has value names
    enum: tuple[EnumItem, ...] = ()
    set_lo: int | None = None  # "scaled", float setter: bounds on the rounded raw held in an int64_t / uint64_t
    set_hi: int | None = None
    fixed: FixedPoint | None = None  # "scaled": the exact rational scale and offset, when they fit int64_t
    span: tuple[str, str, str] | None = None  # MIT-packed: lo, hi and 2^bits - 1 as C double literals


@dataclass(frozen=True)
class FixedPoint:
    """physical * den = raw * scale_num + offset_num, all integers: scale and offset as the decimal fractions
    the spec wrote (0.001 is 1/1000, 1/65536 is 0.0000152587890625, both exact), over one denominator."""

    scale_num: int
    offset_num: int
    den: int


def fixed_point(scale: float, offset: float) -> FixedPoint | None:
    """None when a numerator or the denominator needs more than an int64_t (a scale like 1e-30)."""
    # repr is the shortest decimal that reads back as the float: the number the user wrote, not its binary value
    s, o = Fraction(repr(scale)), Fraction(repr(offset))
    den = math.lcm(s.denominator, o.denominator)
    view = FixedPoint(s.numerator * (den // s.denominator), o.numerator * (den // o.denominator), den)
    limit = 1 << 63
    fits = all(-limit <= n < limit for n in (view.scale_num, view.offset_num, view.den))
    return view if fits else None


def _codec_raw(sig: model.Signal, value: float) -> int | None:
    """The raw value netcfg.runtime.codec gives a physical value (None when it has none, e.g. overflow)."""
    q = (value - sig.offset) / sig.scale
    return round(q) if math.isfinite(q) else None


@dataclass(frozen=True)
class EnumItem:
    ident: str  # MSG_<MESSAGE>_<SIGNAL>_<VALUE NAME>
    value: int
    in_int: bool  # a C enum constant must fit an int; others become #defines
    name: str  # the DBC's value name, for the comment


def _double(x: float) -> str:
    """A C double literal that reads back as exactly x (repr is the shortest round-trip form)."""
    text = repr(float(x))
    return text if any(c in text for c in ".en") else text + ".0"


def _bound(x: float | None) -> float | None:
    # an infinite or NaN bound never rejects anything (the codec's comparisons are false for it too)
    return x if x is not None and math.isfinite(x) else None


def _ops(start: int, bits: int) -> tuple[ByteOp, ...]:
    return tuple(ByteOp(k, 8 * k - start) for k in range(start // 8, (start + bits - 1) // 8 + 1))


def _enum(message: str, sig: model.Signal, taken: set[str]) -> tuple[EnumItem, ...]:
    """C names for the signal's value names: MSG_<MESSAGE>_<SIGNAL>_<NAME>, letters, digits and single '_'."""
    items = []
    for raw, text in sig.choices:
        word = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9]", "_", text)).strip("_").upper() or f"VALUE_{raw}"
        base = f"MSG_{message.upper()}_{sig.name.upper()}_{word}".replace("__", "_")
        ident, n = base, 2
        while ident in taken:
            ident, n = f"{base}_{n}", n + 1
        taken.add(ident)
        items.append(EnumItem(ident, raw, -(2**31) <= raw < 2**31, text))
    return tuple(items)


def _present(sig: model.Signal, by_name: dict[str, model.Signal]) -> str | None:
    """C condition under which a multiplexed signal is in the frame, on the multiplexers' raw_<name> values."""
    terms, seen = [], set()
    while sig.mux is not None and sig.mux in by_name and sig.mux not in seen:
        seen.add(sig.mux)
        switch = by_name[sig.mux]
        mask = (1 << switch.bits) - 1
        values = sorted({v & mask for v in sig.mux_values})
        term = " || ".join(f"raw_{switch.name} == UINT64_C({v})" for v in values)
        terms.append(f"({term})" if len(values) > 1 else term)
        sig = switch
    return " && ".join(terms) if terms else None


def _depth(sig: model.Signal, by_name: dict[str, model.Signal]) -> int:
    depth, seen = 0, set()
    while sig.mux is not None and sig.mux in by_name and sig.mux not in seen:
        seen.add(sig.mux)
        sig, depth = by_name[sig.mux], depth + 1
    return depth


def signal_view(
    sig: model.Signal,
    raw_only: bool = False,
    message: str = "",
    siblings: tuple[model.Signal, ...] = (),
    taken: set[str] | None = None,
) -> SignalView:
    is_integer = not sig.is_float and sig.scale == 1 and sig.offset == 0  # codec.Field.is_integer
    by_name = {s.name: s for s in siblings}
    width = next(w for w in _WIDTHS if w >= sig.bits)
    if sig.signed:
        raw_lo, raw_hi = -(1 << (sig.bits - 1)), (1 << (sig.bits - 1)) - 1
    else:
        raw_lo, raw_hi = 0, (1 << sig.bits) - 1
    minimum, maximum = _bound(sig.minimum), _bound(sig.maximum)
    lo: int | None = raw_lo
    hi: int | None = raw_hi
    set_lo: int | None = None
    set_hi: int | None = None
    if sig.is_float:
        kind, ctype, lo, hi = "float", "float" if sig.bits == 32 else "double", None, None
    elif is_integer:
        kind = "int"
        ctype = f"{'' if sig.signed else 'u'}int{width}_t"
        # an integer v meets v >= min exactly when v >= ceil(min) (the codec compares int and float exactly)
        if minimum is not None:
            lo = max(raw_lo, math.ceil(minimum))
        if maximum is not None:
            hi = min(raw_hi, math.floor(maximum))
        type_lo = -(1 << (width - 1)) if sig.signed else 0
        type_hi = (1 << (width - 1)) - 1 if sig.signed else (1 << width) - 1
        # comparisons the C type already guarantees would trip -Wtype-limits
        lo = None if lo is not None and lo <= type_lo else lo
        hi = None if hi is not None and hi >= type_hi else hi
        minimum = maximum = None
    else:
        kind = "scaled"
        ctype = f"{'' if sig.signed else 'u'}int{width}_t"
        # the struct holds the raw value; pack accepts the raws the codec gives physical values inside
        # [min, max] (its rounding is monotone, so they lie between the raws of min and max)
        ends = [_codec_raw(sig, b) for b in (minimum, maximum) if b is not None]
        if minimum is not None and ends[0] is not None:
            bound = ends[0]
            lo, hi = (max(raw_lo, bound), hi) if sig.scale > 0 else (lo, min(raw_hi, bound))
        if maximum is not None and ends[-1] is not None:
            bound = ends[-1]
            lo, hi = (lo, min(raw_hi, bound)) if sig.scale > 0 else (max(raw_lo, bound), hi)
        type_lo = -(1 << (width - 1)) if sig.signed else 0
        type_hi = (1 << (width - 1)) - 1 if sig.signed else (1 << width) - 1
        lo = None if lo is not None and lo <= type_lo else lo
        hi = None if hi is not None and hi >= type_hi else hi
        # the float setter holds the rounded raw in an int64_t / uint64_t: only bounds inside that type need a
        # test (unsigned: the pre-test q >= -0.5 already keeps it >= 0)
        set_lo = raw_lo if sig.signed and sig.bits < 64 else None
        set_hi = raw_hi if sig.bits < 64 else None
    return SignalView(
        name=sig.name,
        start_bit=sig.start_bit,
        bits=sig.bits,
        kind=kind,
        signed=sig.signed,
        ctype=ctype,
        word="uint32_t" if sig.bits == 32 else "uint64_t",
        mask=None if sig.bits == 64 else (1 << sig.bits) - 1,
        sign_bit=1 << (sig.bits - 1),
        ops=_ops(sig.start_bit, sig.bits),
        lo=lo,
        hi=hi,
        minimum=None if minimum is None else _double(minimum),
        maximum=None if maximum is None else _double(maximum),
        scale=_double(sig.scale),
        offset=_double(sig.offset),
        # one raw step of slack each side, so the conversion to a 64-bit integer is defined; the exact test
        # follows on the rounded integer. Unsigned: round() gives 0 down to -0.5 inclusive (half to even).
        q_lo=_double(raw_lo - 1) if sig.signed else "-0.5",
        q_hi=_double(raw_hi + 1),
        set_lo=set_lo,
        set_hi=set_hi,
        fixed=fixed_point(sig.scale, sig.offset) if kind == "scaled" else None,
        unit=sig.unit,
        raw_only=raw_only,
        big_endian=sig.big_endian,
        be_ops=codec.byte_ops(sig.start_bit, sig.bits, True) if sig.big_endian else (),
        end_bit=8 * (codec.last_byte(sig.start_bit, sig.bits, True) + 1)
        if sig.big_endian
        else sig.start_bit + sig.bits,
        present=_present(sig, by_name),
        mux_note=f"{sig.mux} in {{{', '.join(map(str, sig.mux_values))}}}" if sig.mux is not None else None,
        is_multiplexer=sig.is_multiplexer,
        mux_depth=_depth(sig, by_name),
        enum_type=f"msg_{message}_{sig.name}" if sig.choices else None,
        enum=_enum(message, sig, taken if taken is not None else set()) if sig.choices else (),
        span=None if sig.span is None else (_double(sig.span[0]), _double(sig.span[1]), _double((1 << sig.bits) - 1)),
    )


@dataclass(frozen=True)
class FttView:
    ftt_id: int
    period_ec: int
    fastest_period_ec: int
    init_ec: int


@dataclass(frozen=True)
class MessageView:
    name: str
    bus: str
    protocol: str
    sends: bool
    receives: bool
    producer: str
    consumers: tuple[str, ...]
    id: int
    extended: bool
    size: int
    kind: str
    period_ns: int | None
    interval_ns: int | None
    offset_ns: int | None
    deadline_ns: int | None
    window: str | None
    ftt: FttView | None
    udp: tuple[int, int] | None
    pdo: str | None
    implicit: str | None
    signals: tuple[SignalView, ...]
    end_bit: int  # one past the last bit a signal uses
    pack_order: tuple[SignalView, ...]  # multiplexers before the signals they select
    description: str | None
    fd: bool = False  # CAN FD: sent as frame_size bytes (the payload padded with zeros), DLC dlc
    brs: bool = False
    frame_size: int = 0
    dlc: int = 0
    remote: bool = False  # a remote frame (RTR): no data, DLC dlc (the length of the data frame it asks for)
    base: tuple[str, ...] | None = None  # the bytes pack starts from (constant fields, padding), C rows; None: zeros


@dataclass(frozen=True)
class TriggerView:
    name: str
    bus: str
    ftt: FttView
    tasks: tuple[str, ...]  # this node's tasks it activates
    others: tuple[str, ...]  # the other nodes' tasks
    description: str | None


@dataclass(frozen=True)
class BusView:
    name: str
    protocol: str
    bitrate: int
    id_bits: int
    ftt: model.FttBus | None
    canopen: model.CanopenBus | None
    description: str | None
    data_bitrate: int | None = None  # CAN FD data phase


@dataclass(frozen=True)
class PeerView:
    name: str
    ip: str
    ip_u32: int


@dataclass(frozen=True)
class NodeView:
    system: str
    name: str
    node_id: int | None
    role: str
    ip: str | None
    ip_u32: int | None
    description: str | None
    tasks: tuple[tuple[str, str | None], ...]
    buses: tuple[BusView, ...]
    triggers: tuple[TriggerView, ...]
    messages: tuple[MessageView, ...]
    peers: tuple[PeerView, ...]  # other nodes this one exchanges UDP datagrams with
    big_endian: bool = False  # some payload has a big-endian (Motorola) signal: the header says how they sit
    scaled: bool = False  # some payload has a scaled signal: the header says how its raw field reads


def _description(obj: model.Described) -> str | None:
    # free text from the spec; the template passes it through c_comment
    return obj.description or None


def _ip_u32(ip: str | None) -> int | None:
    if ip is None:
        return None
    a, b, c, d = (int(p) for p in ip.split("."))
    return a << 24 | b << 16 | c << 8 | d


def _ftt_entries(m: model.Model, bus: model.Bus) -> dict[str, FttView]:
    """Period and init time in ECs of what the bus's protocol schedules, as the SRT has them (the analysis computes
    them, not us; Protocol.scheduled)."""
    entries = protocols.of(bus).scheduled(bus)
    return {name: FttView(e.ftt_id, e.period_ec, e.fastest_period_ec, e.init_ec) for name, e in entries.items()}


def message_view(msg: model.Message, node: str, bus: model.Bus, ftt_views: dict[str, FttView]) -> MessageView:
    if msg.signals:
        taken: set[str] = set()
        sigs = tuple(signal_view(s, False, msg.name, msg.signals, taken) for s in msg.signals)
    elif 0 < msg.size <= 8:
        sigs = (signal_view(model.Signal(raw_signal_name(msg.name), 0, 8 * msg.size, False), raw_only=True),)
    else:
        sigs = ()
    pdo = None
    if msg.pdo is not None:
        pdo = f"{msg.pdo.kind.upper()} {msg.pdo.number} of {msg.pdo.node}"
    return MessageView(
        **same_named(msg, "name producer consumers id extended size kind period_ns interval_ns offset_ns deadline_ns"),
        **same_named(msg, "window implicit fd brs frame_size remote"),
        bus=bus.name,
        protocol=bus.protocol,
        sends=msg.producer == node,
        receives=node in msg.consumers,
        ftt=ftt_views.get(msg.name) if msg.window == "sync" else None,  # a scheduled message's entry
        udp=msg.udp_ports,
        pdo=pdo,
        signals=sigs,
        end_bit=max((s.end_bit for s in sigs), default=0),
        pack_order=tuple(sorted(sigs, key=lambda s: s.mux_depth)),
        description=_description(msg),
        dlc=canfd_dlc(msg.size) if msg.fd else _requested_size(msg, bus) if msg.remote else msg.size,
        # a CAN FD frame's bytes beyond the payload are zeros, as everywhere (runtime Message.to_can)
        base=None if msg.base_payload is None else _byte_rows(msg.base_payload.ljust(msg.frame_size, b"\0")),
    )


def _byte_rows(data: bytes, per_row: int = 12) -> tuple[str, ...]:
    """A C initializer's rows: "0x01, 0x00, ..." (each row ends with a comma, as C99 allows of the last)."""
    return tuple(
        " ".join(f"0x{b:02X}," for b in data[k : k + per_row]) for k in range(0, len(data), per_row)
    )


def _requested_size(msg: model.Message, bus: model.Bus) -> int:
    """A remote frame's DLC: the length of the data frame of its identifier, which answers it (ISO 11898-1 asks the
    two to agree); 0 when the bus has none."""
    return next((x.size for x in bus.messages if not x.remote and (x.id, x.extended) == (msg.id, msg.extended)), 0)


# a message's view differs between nodes only in the direction: (bus, message, sends, receives); (bus, message)
# holds the first view made of it, the others are copies with their direction
ViewKey = tuple[str, str, bool, bool] | tuple[str, str]


def node_view(
    m: model.Model,
    node: model.Node,
    views: dict[ViewKey, MessageView] | None = None,
    on_bus: dict[str, dict[str, list[model.Message]]] | None = None,
) -> NodeView | None:
    """The node's view; `views` caches the message views that other nodes share (a SYNC every node hears),
    `on_bus` the messages each node sends or receives per bus (messages_by_node)."""
    views = {} if views is None else views
    buses = [m.buses[b] for b in node.buses]
    messages: list[MessageView] = []
    triggers: list[TriggerView] = []
    peers: dict[str, PeerView] = {}
    for bus in buses:
        ftt_views = _ftt_entries(m, bus)
        mine = messages_by_node(bus) if on_bus is None else on_bus[bus.name]
        for msg in mine.get(node.name, ()):
            key = (bus.name, msg.name, msg.producer == node.name, node.name in msg.consumers)
            view = views.get(key)
            if view is None:
                first = views.get(key[:2])
                if first is None:
                    view = views[key[:2]] = message_view(msg, node.name, bus, ftt_views)
                else:  # the signals' views are the same: only the direction is this node's
                    view = dataclasses.replace(first, sends=key[2], receives=key[3])
                views[key] = view
            messages.append(view)
            if links.of(bus).switched:
                for other in (msg.producer, *msg.consumers):
                    ip = m.nodes[other].ip
                    if other != node.name and ip is not None and other not in peers:
                        peers[other] = PeerView(other, ip, _ip_u32(ip) or 0)
        for t in m.triggers.values():
            tasks = tuple(r for r in t.tasks if r.split(".", 1)[0] == node.name)
            if t.bus == bus.name and tasks:
                others = tuple(r for r in t.tasks if r not in tasks)
                triggers.append(TriggerView(t.name, t.bus, ftt_views[t.name], tasks, others, _description(t)))
    # a node that hears a frame of its buses' protocols (FTT-CAN's trigger message) has a header even without messages
    hears = any(protocols.of(b).own_frames(b) for b in buses)
    if not messages and not hears:
        return None
    return NodeView(
        system=m.system,
        name=node.name,
        node_id=node.node_id,
        role=node.role,
        ip=node.ip,
        ip_u32=_ip_u32(node.ip),
        description=_description(node),
        tasks=tuple((t.name, _description(t)) for t in node.tasks.values()),
        buses=tuple(
            BusView(b.name, b.protocol, b.bitrate, b.id_bits, b.ftt, b.canopen, _description(b), b.data_bitrate)
            for b in buses
        ),
        triggers=tuple(triggers),
        messages=tuple(messages),
        peers=tuple(sorted(peers.values(), key=lambda p: p.name)),
        big_endian=any(sig.big_endian for msg in messages for sig in msg.signals),
        scaled=any(sig.kind == "scaled" for msg in messages for sig in msg.signals),
    )


def messages_by_node(bus: model.Bus) -> dict[str, list[model.Message]]:
    """node -> the bus's messages it sends or receives, in the bus's order: one pass over the bus instead of one
    per node (127 nodes that all hear the SYNC)."""
    out: dict[str, list[model.Message]] = {}
    for msg in bus.messages:
        for name in dict.fromkeys((msg.producer, *msg.consumers)):
            out.setdefault(name, []).append(msg)
    return out


def emit(m: model.Model, report: dict[str, Any]) -> dict[str, bytes]:
    """Each message's C body is rendered once and pasted into every header that has it, after a heading line that
    says whether that node sends or receives it: a frame many nodes hear (a SYNC, a broadcast) is rendered once,
    not once per node."""
    files = {}
    views: dict[ViewKey, MessageView] = {}
    on_bus = {bus.name: messages_by_node(bus) for bus in m.buses.values()}
    # encoded once each and joined as bytes: most of a header is these blocks
    headings: dict[ViewKey, bytes] = {}
    bodies: dict[tuple[str, str], bytes] = {}
    block = environment().get_template("node_message.h.j2").module  # its macros: heading(m), body(system, m)
    header = environment().get_template("node.h.j2")
    for node in m.nodes.values():
        view = node_view(m, node, views, on_bus)
        if view is None:
            continue
        parts: list[bytes] = []
        for msg in view.messages:
            key = (msg.bus, msg.name, msg.sends, msg.receives)
            if key not in headings:
                headings[key] = block.heading(msg).encode("utf-8")  # type: ignore[attr-defined]
            if key[:2] not in bodies:
                bodies[key[:2]] = block.body(m.system, msg).encode("utf-8")  # type: ignore[attr-defined]
            parts += (headings[key], bodies[key[:2]])
        text = header.render(node=view, message_blocks=_BLOCKS)
        if text.count(_BLOCKS) == 1:
            head, _, tail = text.partition(_BLOCKS)
            files[f"c/{node.name}.h"] = b"".join((head.encode("utf-8"), *parts, tail.encode("utf-8")))
        else:  # the marker also in the node's own text (a description may hold anything): the plain way
            blocks = b"".join(parts).decode("utf-8")
            files[f"c/{node.name}.h"] = render("node.h.j2", node=view, message_blocks=blocks)
    return files


# where the message blocks go in a rendered header: NULs, which its own text holds only if the spec wrote them
_BLOCKS = "\x00message blocks\x00"
