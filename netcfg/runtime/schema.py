"""The schema of runtime.json, with ranges: one field table that the emitter checks what it writes against
(netcfg.emit.runtime_json) and netcfg.runtime.load checks what it reads against.

Standard library only, on purpose: a live master imports netcfg.runtime without the compiler, and pydantic is a
compiler dependency. The table is small and flat enough that a checker of forty lines walks it; pydantic models
would state the same ranges twice. Problems come back as "where: what" strings, e.g.
"messages[3] 'm1'.signals[0].bits: 10000000000 is out of range 1..64".

Beyond single fields (`check_document`): names unique per kind, each bus's protocol section present, payloads
within the protocol's frame, signals and PDO entries inside their payload.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from netcfg.runtime.codec import CodecError, byte_ops

MAX_NS = 10**15  # the longest duration netcfg handles (netcfg.spec.units.MAX_DURATION_NS; a test ties the two)
U8, U16, U32 = 0xFF, 0xFFFF, 0xFFFF_FFFF
MAX_NAME_CHARS = 255
PROTOCOLS = ("can", "can-fd", "canopen", "ftt-can", "ethernet-udp", "ethercat")
LINKS = ("can", "can-fd", "ethernet", "ethercat")  # the links a bus runs over (netcfg.links.LINKS; tested)
# The link of a bus in a file written before buses stated it: each of these protocols ran over one link, its own
# (netcfg.protocols.PROTOCOLS[name].link; a test ties the two), so the bus's protocol named its link
EARLIER_LINKS = {
    "can": "can", "can-fd": "can-fd", "canopen": "can", "ftt-can": "can", "ethernet-udp": "ethernet",
    "ethercat": "ethercat",
}
# CAN 2.0; CAN FD (ISO 11898-1:2015); UDP without fragmentation; an EtherCAT PDO within one frame's datagram (1,486
# bytes: netcfg.links.ethercat.MAX_DATAGRAM_DATA)
MAX_PAYLOAD = {"can": 8, "can-fd": 64, "canopen": 8, "ftt-can": 8, "ethernet-udp": 1472, "ethercat": 1486}
# CAN FD data lengths (ISO 11898-1:2015), as netcfg.timing.frames has them (a master does not import the compiler;
# a test keeps the two equal)
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)
MAX_ID = {11: 0x7FF, 29: 0x1FFF_FFFF}


@dataclass(frozen=True)
class F:
    """One field: its kind and range. kind: int | float | bool | str | name | enum | list | obj | json (any value,
    checked by its reader)."""

    kind: str
    lo: float | None = None
    hi: float | None = None
    null: bool = False  # may be null
    optional: bool = False  # may be absent: added later within version 1 (see netcfg.runtime)
    choices: tuple[Any, ...] = ()
    item: F | None = None  # list items
    fields: Mapping[str, F] | None = None  # object fields
    parts: tuple[F, ...] = ()  # a tuple: a list of exactly these


def i(lo: int, hi: int, null: bool = False, optional: bool = False) -> F:
    return F("int", lo, hi, null, optional)


def ns(lo: int = 0, null: bool = False, optional: bool = False) -> F:
    return F("int", lo, MAX_NS, null, optional)


def name(null: bool = False, optional: bool = False) -> F:
    return F("name", null=null, optional=optional)


def text(null: bool = False, optional: bool = False) -> F:
    return F("str", null=null, optional=optional)


def enum(*choices: Any, null: bool = False, optional: bool = False) -> F:
    return F("enum", null=null, optional=optional, choices=choices)


def lst(item: F, null: bool = False, optional: bool = False, hi: int = 1_000_000) -> F:
    return F("list", 0, hi, null, optional, item=item)


def obj(null: bool = False, optional: bool = False, **fields: F) -> F:
    return F("obj", null=null, optional=optional, fields=fields)


def num(lo: float, hi: float, null: bool = False, optional: bool = False) -> F:
    return F("float", lo, hi, null, optional)


BOOL = F("bool")
BIG = 1e300  # finite: scale, offset and limits of a signal may be anything a float holds

SIGNAL = obj(
    name=name(), start_bit=i(0, 8 * 1472 - 1), bits=i(1, 64), signed=BOOL, float=BOOL,
    scale=num(-BIG, BIG), offset=num(-BIG, BIG), min=num(-BIG, BIG, null=True), max=num(-BIG, BIG, null=True),
    unit=text(null=True),
    # written only when used (netcfg.emit.runtime_json): Motorola byte order, multiplexing, value names
    byte_order=F("enum", choices=("little_endian", "big_endian"), optional=True),
    mux=name(optional=True), mux_values=lst(i(0, 2**64 - 1), optional=True),
    enum=lst(F("tuple", parts=(i(-(2**63), 2**64 - 1), text())), optional=True),
)
PDO_ENTRY = obj(index=i(0x1000, U16), sub=i(0, U8), bits=i(1, 64), name=name(), data_type=i(1, U16))
PDO = obj(
    null=True, kind=enum("rpdo", "tpdo"), number=i(1, 512), node=name(), transmission=i(0, U8),
    inhibit_100us=i(0, U16, null=True), event_timer_ms=i(0, U16, null=True), sync_start=i(0, U8, null=True),
    cob_id=i(0, U32, null=True, optional=True), entries=lst(PDO_ENTRY, hi=64),
)
MESSAGE = obj(
    name=name(), bus=name(), producer=name(), consumers=lst(name()), id=i(0, MAX_ID[29]), extended=BOOL,
    size=i(0, max(MAX_PAYLOAD.values())), kind=enum("periodic", "sporadic", "on-demand"),
    period_ns=ns(1, null=True), interval_ns=ns(1, null=True), offset_ns=ns(null=True), deadline_ns=ns(1, null=True),
    jitter_ns=ns(), rate_hz=lst(i(1, 10**18), null=True, hi=2), window=enum("sync", "async", null=True),
    ftt_id=i(0, 10**6, null=True), udp=obj(null=True, src_port=i(0, U16), dst_port=i(0, U16)), pdo=PDO,
    signals=lst(SIGNAL, hi=8 * 1472), implicit=text(null=True), wcrt_ns=ns(null=True),
    wcrt_unsync_ns=ns(null=True, optional=True),
    sent_by=lst(name(), null=True, optional=True),
    fd=F("bool", optional=True), brs=F("bool", optional=True), frame_size=i(0, 64, optional=True),
    remote=F("bool", optional=True),
)
TASK = obj(
    name=name(), period_ns=ns(1, null=True), offset_ns=ns(), wcet_ns=ns(1), bcet_ns=ns(),
    trigger=name(null=True), on_message=name(null=True), sync_bus=name(null=True, optional=True),
)
NODE = obj(
    name=name(), node_id=i(0, 255, null=True), role=enum("master", "slave"), buses=lst(name()), ip=text(null=True),
    device=text(null=True), heartbeat_ns=ns(1, null=True), tx_delay_ns=ns(), rx_delay_ns=ns(), tasks=lst(TASK),
    identity=obj(null=True, optional=True, vendor_id=i(0, U32, null=True), product_code=i(0, U32, null=True),
                 revision=i(0, U32, null=True)),
    eds=text(null=True, optional=True), dcf=text(null=True, optional=True),
    rpdo_count=i(0, 512, null=True, optional=True), tpdo_count=i(0, 512, null=True, optional=True),
    heartbeat_timeout_ns=ns(1, null=True, optional=True),
    on_loss=F("enum", choices=("stop_all", "stop_node", "continue"), optional=True),
    on_emcy=F("enum", choices=("stop_all", "stop_node", "continue"), optional=True),
    on_reboot=F("enum", choices=("recover", "stop_node", "stop_all"), optional=True),
    sdo_timeout_ns=ns(1, optional=True), sdo_retries=i(0, 10, optional=True),
    safe_stop=F("enum", choices=("quick_stop", "disable_operation"), optional=True),
    tx_queue=obj(optional=True, policy=enum("priority", "fifo"), depth=i(1, 1_000_000), on_full=enum("block", "drop")),
    sdo_init=lst(obj(index=i(0, U16), sub=i(0, U8), data_type=i(1, U16), value=i(-(2**63), 2**64 - 1)),
                 null=True, optional=True),
    # an actuator profile's node: the profile's plain form (netcfg.runtime.actuators reads and checks it), its
    # parameters, and the messages of this file that carry its commands, replies and cyclic messages
    actuator=obj(
        null=True, optional=True, profile=F("json"), parameters=lst(F("tuple", parts=(name(), num(-BIG, BIG)))),
        commanded_by=name(),
        commands=lst(obj(command=name(), message=name(), reply=name(null=True), reply_message=name(null=True))),
        cyclic=lst(obj(profile_message=name(), message=name())),
    ),
)
CANOPEN = obj(
    null=True, sync_period_ns=ns(1), sync_window_ns=ns(null=True), read_window_ns=ns(null=True),
    sync_producer=name(null=True), sync_id=i(0, MAX_ID[29]), master_jitter_ns=ns(optional=True),
    sync_completion_ns=ns(null=True, optional=True), sync_overflow=i(0, 240, null=True, optional=True),
)
FTT = obj(
    null=True, ec_ns=ns(1), tm_size=i(0, 8), tm_id=i(0, MAX_ID[29]), tm_ns=ns(), lsw_ns=ns(), master=name(),
    macro_cycle_ec=i(1, 1_000_000), windows=enum("async-first", "sync-first", optional=True),
    srt=lst(obj(ftt_id=i(0, 10**6), name=name(), kind=enum("message", "trigger"), targets=lst(name()),
                period_ec=i(1, 1_000_000), fastest_period_ec=i(1, 1_000_000), init_ec=i(0, 1_000_000))),
    schedule=lst(obj(ec=i(0, 1_000_000), ids=lst(i(0, 10**6)), messages=lst(name()), triggers=lst(name()),
                     mask=i(0, 2**512), sync_ns=ns(), async_ns=ns(),
                     allowance_ns=ns(optional=True))),
)
ETHERNET = obj(
    null=True,
    switches=lst(obj(name=name(), latency_ns=ns(), queue=i(1, 1_000_000, optional=True),
                     ports=lst(obj(port=i(0, U16), to=name(), cable_m=num(0, 1e6),
                                   queue=i(1, 1_000_000, optional=True))))),
    nics=lst(obj(node=name(), queue=i(1, 1_000_000)), optional=True),
)
# An EtherCAT segment, as a SOEM master (pysoem) applies it in its configuration hook: each slave's identity, its
# CoE start-up SDOs (PDO mappings, then the 0x1C12/0x1C13 assignment), sync managers, FMMUs and DC settings, and
# where each entry sits in the process image (the IOmap: every slave's outputs, then every slave's inputs).
ECAT_SLAVE = obj(
    node=name(), position=i(0, 65534), vendor_id=i(0, U32), product_code=i(0, U32), revision=i(0, U32),
    device=text(), rxpdo=lst(i(0x1600, 0x17FF)), txpdo=lst(i(0x1A00, 0x1BFF)),
    sdo=lst(obj(index=i(0, U16), sub=i(0, U8), bits=enum(8, 16, 32), value=i(0, U32))),
    sm=lst(obj(number=i(0, 15), kind=text(), start=i(0, U16), length=i(0, U16), control=i(0, U8))),
    fmmu=lst(obj(direction=enum("outputs", "inputs"), logical=i(0, U32), length=i(0, U16), physical=i(0, U16))),
    dc=obj(assign_activate=i(0, U16), sync0_cycle_ns=ns(), sync0_shift_ns=ns()),
    entries=lst(obj(direction=enum("outputs", "inputs"), pdo=i(0x1600, 0x1BFF), index=i(0, U16), sub=i(0, U8),
                    bits=i(1, 64), name=text(), bit_offset=i(0, 8 * U32))),
    # what the simulator runs the cycle with, and the analysis' bound it holds the frame's passing against
    forwarding_ns=ns(optional=True), cable_m=num(0, 1e6, optional=True), frame_passed_ns=ns(optional=True),
)
ETHERCAT = obj(
    optional=True, cycle_ns=ns(1), sync0_cycle_ns=ns(1), sync0_shift_ns=ns(), master=name(null=True),
    master_jitter_ns=ns(), out_bytes=i(0, U32), in_bytes=i(0, U32), slaves=lst(ECAT_SLAVE),
    # the cycle's frames (each one LRW datagram of the image) and the analysis' bounds the simulator holds them to
    frames=lst(obj(data_bytes=i(0, U16), wire_bytes=i(1, U16)), optional=True), latency_ns=ns(optional=True),
    dc_precision_ns=ns(optional=True),
    # the messages that are slaves' PDOs (netcfg.protocols.ethercat.messages): the slave, its inputs or outputs, and
    # when, after the master's send, the frame reads a slave's inputs
    messages=lst(
        obj(name=name(), slave=i(0, U16), direction=enum("inputs", "outputs"), read_offset_ns=ns()), optional=True
    ),
)
BUS = obj(
    name=name(), protocol=enum(*PROTOCOLS), bitrate=i(1, 10**12), id_bits=enum(11, 29), nodes=lst(name()),
    canopen=CANOPEN, ftt=FTT, ethernet=ETHERNET, ethercat=ETHERCAT, data_bitrate=i(1, 10**12, optional=True),
    errors=obj(null=True, optional=True, burst=i(0, 10_000), interval_ns=ns(1)),
    clock_tolerance_ppm=i(0, 10_000, optional=True), link=enum(*LINKS, optional=True),
)
TRIGGER = obj(
    name=name(), bus=name(), ftt_id=i(0, 10**6), period_ns=ns(1), interval_ns=ns(1, null=True), offset_ns=ns(),
    tasks=lst(name()),
)
FLOW = obj(
    name=name(), steps=lst(obj(kind=enum("task", "message"), refs=lst(name()))), deadline_ns=ns(1, null=True),
    latency_min_ns=ns(null=True), latency_max_ns=ns(null=True), unsync_latency_min_ns=ns(null=True, optional=True),
    unsync_latency_max_ns=ns(null=True, optional=True),
)
DOCUMENT = obj(
    format=text(), version=i(1, 1_000), system=name(), spec_sha256=text(), buses=lst(BUS), nodes=lst(NODE),
    messages=lst(MESSAGE), triggers=lst(TRIGGER), flows=lst(FLOW),
)


# Where a value is, as (where its container is, its key or (item, index) in it); None is the document. The text
# ("messages[3] 'odometry'.period_ns") is made only for a problem: a large document has ~10^5 values.
Where = tuple[Any, Any] | None


def _text(where: Where) -> str:
    parts: list[Any] = []
    while where is not None:
        where, part = where
        parts.append(part)
    text = ""
    for part in reversed(parts):
        if isinstance(part, str):
            text = f"{text}.{part}" if text else part
        else:
            text += _label(*part)
    return text


def _label(item: Any, index: int) -> str:
    n = item.get("name") if isinstance(item, dict) else None
    return f"[{index}] {n!r}" if isinstance(n, str) else f"[{index}]"


def _within(value: float, f: F) -> bool:
    return (f.lo is None or f.lo <= value) and (f.hi is None or value <= f.hi)


def _check(value: Any, f: F, where: Where, out: list[str], strict: bool) -> None:
    if value is None:
        if not f.null:
            out.append(f"{_text(where)}: must not be null")
        return
    k = f.kind
    if k == "int" or (k == "enum" and all(isinstance(c, int) for c in f.choices)):
        if not isinstance(value, int) or isinstance(value, bool):
            out.append(f"{_text(where)}: must be a whole number, not {type(value).__name__}")
        elif k == "enum" and value not in f.choices:
            out.append(f"{_text(where)}: {value} is not one of {', '.join(map(str, f.choices))}")
        elif k == "int" and not _within(value, f):
            shown = str(value) if len(str(value)) <= 24 else f"a number of {len(str(value))} digits"
            out.append(f"{_text(where)}: {shown} is out of range {f.lo:,}..{f.hi:,}")
    elif k == "float":
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            out.append(f"{_text(where)}: must be a number, not {type(value).__name__}")
        elif not math.isfinite(value) or not _within(value, f):
            out.append(f"{_text(where)}: {value!r} is out of range {f.lo:g}..{f.hi:g}")
    elif k == "bool":
        if not isinstance(value, bool):
            out.append(f"{_text(where)}: must be true or false, not {type(value).__name__}")
    elif k in ("str", "name", "enum"):
        if not isinstance(value, str):
            out.append(f"{_text(where)}: must be a string, not {type(value).__name__}")
        elif k == "enum" and value not in f.choices:
            out.append(f"{_text(where)}: {value[:40]!r} is not one of {', '.join(f.choices)}")
        elif k == "name" and not 0 < len(value) <= MAX_NAME_CHARS:
            out.append(f"{_text(where)}: a name must have 1..{MAX_NAME_CHARS} characters")
    elif k == "list":
        if not isinstance(value, list):
            out.append(f"{_text(where)}: must be a list, not {type(value).__name__}")
        elif f.hi is not None and len(value) > f.hi:
            out.append(f"{_text(where)}: {len(value):,} items, at most {int(f.hi):,}")
        else:
            assert f.item is not None
            for n, item in enumerate(value):
                _check(item, f.item, (where, (item, n)), out, strict)
    elif k == "tuple":
        if not isinstance(value, list) or len(value) != len(f.parts):
            out.append(f"{_text(where)}: must be a list of {len(f.parts)} items")
        else:
            for n, (item, part) in enumerate(zip(value, f.parts)):
                _check(item, part, (where, (None, n)), out, strict)
    elif k == "json":
        pass  # any JSON value: its reader checks it (an actuator profile: netcfg.runtime.actuators)
    elif k == "obj":
        if not isinstance(value, dict):
            out.append(f"{_text(where)}: must be an object, not {type(value).__name__}")
            return
        assert f.fields is not None
        for key, sub in f.fields.items():
            if key in value:
                _check(value[key], sub, (where, key), out, strict)
            elif not sub.optional:
                out.append(f"{_text(where) or 'the file'}: missing key '{key}'")
        if strict:
            unknown = [key for key in value if key not in f.fields]
            out += [f"{_text(where) or 'the file'}: key '{key}' is not in the schema" for key in unknown]


def _actuator_problems(node: dict[str, Any], messages: set[str]) -> list[str]:
    """An actuator node's profile must build its codec with its parameters, and name messages of the file."""
    from netcfg.runtime.actuators import ActuatorCodec

    where, a = f"node {node['name']!r}.actuator", node["actuator"]
    try:
        ActuatorCodec(a["profile"], **dict(a["parameters"]))
    except (CodecError, KeyError, TypeError, ValueError) as exc:
        return [f"{where}: its profile and parameters do not make a codec: {exc}"]
    named = [c["message"] for c in a["commands"]] + [c["reply_message"] for c in a["commands"] if c["reply_message"]]
    named += [c["message"] for c in a["cyclic"]]
    return [f"{where}: message {x!r} is not in the file" for x in named if x not in messages]


def bus_link(bus: Mapping[str, Any]) -> str:
    """The link a bus of the document runs over: its own key, else (a file written before the key) the one its
    protocol ran over (EARLIER_LINKS; check_document refuses a bus that has neither)."""
    return str(bus["link"]) if "link" in bus else EARLIER_LINKS[bus["protocol"]]


def check_document(doc: Any, strict: bool = False) -> list[str]:
    """Every problem of a runtime.json document, as "where: what". strict: also keys the schema does not know
    (the emitter's check; a reader tolerates them, so that an older master reads a newer file)."""
    out: list[str] = []
    _check(doc, DOCUMENT, None, out, strict)
    if out:
        return out
    for kind in ("buses", "nodes", "messages", "triggers", "flows"):
        seen: set[str] = set()
        for item in doc[kind]:
            if item["name"] in seen:
                out.append(f"{kind}: duplicate name {item['name']!r}")
            seen.add(item["name"])
    protocol = {b["name"]: b["protocol"] for b in doc["buses"]}
    # the buses over the CAN FD link, which carries CAN FD frames (a bus of neither link nor earlier protocol is
    # refused below)
    fd_link = {b["name"] for b in doc["buses"] if b.get("link", EARLIER_LINKS.get(b["protocol"])) == "can-fd"}
    for b in doc["buses"]:
        where = f"bus {b['name']!r}"
        section = {"canopen": "canopen", "ftt-can": "ftt", "ethernet-udp": "ethernet", "ethercat": "ethercat"}.get(
            b["protocol"]
        )
        if section is not None and b.get(section) is None:
            out.append(f"{where}: a {b['protocol']} bus needs its '{section}' section")
        if "link" not in b and b["protocol"] not in EARLIER_LINKS:
            out.append(f"{where}: a {b['protocol']} bus needs its 'link' (rebuild the file with netcfg build)")
        if b["name"] in fd_link and "data_bitrate" not in b:
            out.append(f"{where}: a bus over can-fd needs its data_bitrate")
        ftt = b["ftt"]
        if ftt is not None and ftt["ec_ns"] <= ftt["tm_ns"]:
            out.append(f"{where}: the elementary cycle ({ftt['ec_ns']} ns) must be longer than its trigger message "
                       f"({ftt['tm_ns']} ns)")
    for n in doc["nodes"]:
        tasks = [t["name"] for t in n["tasks"]]
        if len(set(tasks)) != len(tasks):
            out.append(f"node {n['name']!r}: duplicate task names")
        if n.get("actuator") is not None:
            out += _actuator_problems(n, {m["name"] for m in doc["messages"]})
    for m in doc["messages"]:
        where = f"message {m['name']!r}"
        proto = protocol.get(m["bus"])
        fd = m.get("fd", False)
        on_fd = m["bus"] in fd_link
        limit = FD_LENGTHS[-1] if fd and on_fd else MAX_PAYLOAD[proto] if proto not in (None, "can-fd") else 8
        if proto is not None and m["size"] > limit:
            out.append(f"{where}: {m['size']} bytes do not fit a {proto} frame (at most {limit})")
        if fd and proto is not None and not on_fd:
            out.append(f"{where}: a CAN FD frame on {proto} bus {m['bus']!r}, which is not over can-fd")
        frame_size = m.get("frame_size", m["size"])
        if (frame_size not in FD_LENGTHS or frame_size < m["size"]) if fd else frame_size != m["size"]:
            out.append(f"{where}: a frame of {frame_size} bytes cannot carry {m['size']}")
        if m.get("remote") and (m["size"] or fd):
            out.append(f"{where}: a remote frame carries no data (size 0) and is no CAN FD frame")
        if m["kind"] == "periodic" and m["period_ns"] is None:
            out.append(f"{where}: a periodic message needs period_ns")
        for s in m["signals"]:
            touched = [op.index for op in byte_ops(s["start_bit"], s["bits"], s.get("byte_order") == "big_endian")]
            if min(touched) < 0 or max(touched) >= m["size"]:
                out.append(f"{where}: signal {s['name']!r} (bits {s['start_bit']}..{s['start_bit'] + s['bits'] - 1}) "
                           f"does not fit its {m['size']}-byte payload")
        # CiA 301's 8 bytes; CANopen FD's (CiA 1301) 64; an EtherCAT PDO's, what its message's frame carries
        pdo_bits = 8 * max(limit, FD_LENGTHS[-1] if on_fd else 8)
        if m["pdo"] is not None and sum(e["bits"] for e in m["pdo"]["entries"]) > pdo_bits:
            out.append(f"{where}: its PDO maps more than {pdo_bits} bits")
    return out
