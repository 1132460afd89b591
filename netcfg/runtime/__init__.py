"""netcfg.runtime: typed, read-only access to a runtime.json, for live masters and for the simulator.

A master runs this without the compiler: it imports only the standard library and netcfg.runtime.codec
(python-can only when a CAN frame is made or read), never netcfg.spec/resolve/model/timing/emit.

    cfg = netcfg.runtime.load("generated/allex2/runtime.json")
    cmd = cfg.message("hip_l_cmd")
    frame = cmd.to_can(target_velocity=1000, velocity_offset=-5)   # a can.Message
    msg, values = cfg.decode_can(frame)

Times are integer nanoseconds ("_ns"), as in the file. A message without signals (only a size) is read and
written through one unsigned field `<message>_raw` spanning its payload, the same name the DBC files use.

Version 1 has grown without changing the meaning of any key, so it is still version 1: nodes gained `identity`,
`eds`, `dcf`, `sdo_init`, `rpdo_count`, `tpdo_count`, `heartbeat_timeout_ns`, `on_loss`, `on_emcy` and
`eds`, `dcf`, `sdo_init`, `rpdo_count`, `tpdo_count`, `heartbeat_timeout_ns`, `on_loss`, `on_emcy` and
`safe_stop`, CANopen buses `sync_overflow` and `sync_completion_ns`, PDOs `cob_id`, flows `unsync_latency_min_ns`
and `unsync_latency_max_ns`, messages `sent_by` and `wcrt_unsync_ns`, FTT-CAN buses `windows`. A file written
before them still loads: their fields are then None (`sdo_init` None means "not stated", () means "nothing to
write"; `sent_by` None: no task sends the message as it finishes, it runs free; no `windows` means the asynchronous
window first), and a master falls back to what it did without them.
"""

from __future__ import annotations

import difflib
import hashlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from netcfg.inputs import InputError, JsonInputError, parse_json, read_input_text
from netcfg.runtime import codec
from netcfg.runtime.codec import CodecError, Field, Number
from netcfg.runtime.schema import check_document

if TYPE_CHECKING:
    import can

__all__ = [
    "FORMAT",
    "SUPPORTED_VERSIONS",
    "Bus",
    "CanopenParams",
    "CodecError",
    "EcSlot",
    "EthernetParams",
    "Flow",
    "FlowStep",
    "FttParams",
    "Message",
    "Node",
    "NodeIdentity",
    "Pdo",
    "PdoEntry",
    "RuntimeConfig",
    "RuntimeConfigError",
    "SdoWrite",
    "Signal",
    "SrtEntry",
    "Switch",
    "SwitchPort",
    "Task",
    "Trigger",
    "UdpPorts",
    "UnknownNameError",
    "interpolation_period",
    "load",
    "parse",
    "raw_signal_name",
    "read_document",
]

FORMAT = "netcfg-runtime"
SUPPORTED_VERSIONS = (1,)
CAN_PROTOCOLS = ("can", "can-fd", "canopen", "ftt-can")
FD_PADDING = 0x00  # pads a CAN FD payload to its frame length, as netcfg.timing.frames.CANFD_PADDING (tested)


class RuntimeConfigError(ValueError):
    """The file is not a runtime config this netcfg can read."""


class UnknownNameError(KeyError):
    """A name that the config does not have; the message lists close matches."""

    def __str__(self) -> str:  # KeyError would print the repr of the text, quotes and all
        return str(self.args[0]) if self.args else ""


def raw_signal_name(message: str) -> str:
    """The field through which a message without signals is encoded (shared with the DBC emitter)."""
    return f"{message}_raw"


def interpolation_period(period_ns: int) -> tuple[int, int] | None:
    """(value, index) for CiA 402 0x60C2 with value * 10^index s = period exactly: in milliseconds when it can
    (20 ms -> (20, -3)), else the coarsest finer unit down to 1 us, else a coarser one up to 1 s; None when no unit
    holds it in an UNSIGNED8. Here, not in the compiler, so that runtime.json's sdo_init and a master reading an
    older runtime.json without it compute the same value."""
    for index in (-3, -4, -5, -6, -2, -1, 0):  # milliseconds first: the unit drives commonly take (EPOS4: -3)
        unit_ns = 10 ** (9 + index)
        if period_ns % unit_ns == 0 and 0 < period_ns // unit_ns <= 255:
            return period_ns // unit_ns, index
    return None


# --- the configuration ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Signal(Field):
    """A codec field with its unit (layout, byte order, multiplexing and value names: netcfg.runtime.codec)."""

    unit: str | None = None


@dataclass(frozen=True)
class PdoEntry:
    index: int
    sub: int
    bits: int
    name: str
    data_type: int  # CiA 301 data type code


@dataclass(frozen=True)
class Pdo:
    kind: str  # "tpdo" | "rpdo"
    number: int
    node: str  # the node whose TPDO/RPDO slot this is
    transmission: int
    inhibit_100us: int | None
    event_timer_ms: int | None
    sync_start: int | None
    entries: tuple[PdoEntry, ...]
    # the 32-bit value of the slot's COB-ID (0x14xx/0x18xx sub 1), CiA 301 flag bits included, as the node's DCF
    # has it; None in files written before it
    cob_id: int | None = None


@dataclass(frozen=True)
class UdpPorts:
    src_port: int
    dst_port: int


@dataclass(frozen=True)
class Message:
    name: str
    bus: str
    protocol: str  # the bus's protocol: decides between CAN frames and UDP datagrams
    producer: str
    consumers: tuple[str, ...]
    id: int  # CAN identifier, or the 1-byte application message id on Ethernet (seed 001, Table 6.1)
    extended: bool
    size: int
    kind: str  # "periodic" | "sporadic" | "on-demand"
    period_ns: int | None
    interval_ns: int | None
    offset_ns: int | None
    deadline_ns: int | None
    jitter_ns: int
    rate_hz: Fraction | None  # exact rate when the spec gave one (its period_ns is rounded)
    window: str | None  # FTT-CAN "sync" | "async"
    ftt_id: int | None
    udp: UdpPorts | None
    pdo: Pdo | None
    signals: tuple[Signal, ...]
    implicit: str | None  # "SYNC", "heartbeat": generated by netcfg
    wcrt_ns: int | None  # the analysis' worst-case response time
    sent_by: tuple[str, ...] | None = None  # tasks (node.task) that send it as they finish; else it runs free
    wcrt_unsync_ns: int | None = None  # the same bus run as free-running CAN (FTT-CAN, CANopen: plain arbitration)
    fd: bool = False  # a CAN FD frame: up to 64 bytes, sent padded to frame_size
    brs: bool = False  # CAN FD bit-rate switch
    # data bytes in the frame: a CAN FD payload padded to the next valid length (ISO 11898-1:2015); 0: size
    frame_size: int = 0
    fields: tuple[Field, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.frame_size:
            object.__setattr__(self, "frame_size", self.size)
        fields: tuple[Field, ...] = self.signals
        if not fields and self.size > 0:
            fields = (Field(raw_signal_name(self.name), 0, 8 * self.size),)
        object.__setattr__(self, "fields", fields)

    @property
    def is_can(self) -> bool:
        return self.protocol in CAN_PROTOCOLS

    def encode(self, **values: Number | str | bytes) -> bytes:
        """Physical values -> payload (size bytes). Every present field must be given (multiplexed ones: those
        the multiplexers' values select); a value name (enum) stands for its value; a raw field takes bytes."""
        plain: dict[str, Number | str] = {}
        for key, value in values.items():
            if isinstance(value, (bytes, bytearray)):
                if self.signals or key != raw_signal_name(self.name) or len(value) != self.size:
                    raise CodecError(f"{self.name}: bytes are accepted only for the raw field, {self.size} long")
                plain[key] = int.from_bytes(value, "little")
            else:
                plain[key] = value
        try:
            return codec.encode(self.fields, self.size, plain)
        except CodecError as exc:
            raise CodecError(f"message '{self.name}': {exc}") from exc

    def decode(self, data: bytes | bytearray) -> dict[str, Number]:
        """Payload -> physical values by field name. A CAN FD frame's padding bytes (beyond size) are ignored."""
        if len(data) != self.size and not (self.fd and len(data) == self.frame_size):
            raise CodecError(f"message '{self.name}' has {self.size} bytes of payload, got {len(data)}")
        return codec.decode(self.fields, bytes(data[: self.size]))

    def to_can(self, **values: Number | str | bytes) -> can.Message:
        if not self.is_can:
            raise TypeError(f"message '{self.name}' travels on {self.protocol} bus '{self.bus}'; use encode_udp()")
        import can  # only CAN masters need python-can

        data = self.encode(**values)
        if self.fd:  # padded to the frame length, so that every receiver sees the DLC the analysis timed
            data += bytes([FD_PADDING]) * (self.frame_size - self.size)
            return can.Message(
                arbitration_id=self.id,
                is_extended_id=self.extended,
                is_fd=True,
                bitrate_switch=self.brs,
                dlc=len(data),
                data=data,
            )
        return can.Message(arbitration_id=self.id, is_extended_id=self.extended, dlc=self.size, data=data)

    def encode_udp(self, **values: Number | str | bytes) -> bytes:
        """The UDP datagram's payload: the 1-byte message id, then the data (seed 001, Table 6.1)."""
        if self.protocol != "ethernet-udp":
            raise TypeError(f"message '{self.name}' travels on {self.protocol} bus '{self.bus}'; use to_can()")
        return bytes([self.id]) + self.encode(**values)


@dataclass(frozen=True)
class Task:
    node: str
    name: str
    period_ns: int | None
    offset_ns: int
    wcet_ns: int
    bcet_ns: int
    trigger: str | None  # FTT-CAN trigger that activates it
    on_message: str | None  # event-driven: runs when this message arrives
    sync_bus: str | None = None  # CANopen: runs on every SYNC of this bus, offset_ns after it

    @property
    def ref(self) -> str:
        return f"{self.node}.{self.name}"


@dataclass(frozen=True)
class Node:
    name: str
    node_id: int | None
    role: str  # "master" | "slave"
    buses: tuple[str, ...]
    ip: str | None
    device: str | None  # device profile name
    heartbeat_ns: int | None
    tx_delay_ns: int
    rx_delay_ns: int
    tasks: tuple[Task, ...]
    # CANopen device facts (None: not a device, or a file written before these keys)
    identity: NodeIdentity | None = None  # what 0x1018 holds, from the device profile or EDS
    eds: str | None = None  # canopen/<node>.eds, relative to the runtime.json's folder (see RuntimeConfig.path)
    dcf: str | None = None
    sdo_init: tuple[SdoWrite, ...] | None = None  # start-up SDO writes, in order; () nothing to write
    rpdo_count: int | None = None  # PDO communication objects the device has (0x1400.., 0x1800..)
    tpdo_count: int | None = None
    # supervision by a live master (`netcfg run`); a file written before these keys: no heartbeat consumer, every
    # fault stops the run, drives quick-stopped
    heartbeat_timeout_ns: int | None = None  # the master's consumer time for this node's heartbeat
    on_loss: str = "stop_all"  # stop_all | stop_node | continue
    on_emcy: str = "stop_all"
    safe_stop: str = "quick_stop"  # quick_stop | disable_operation (CiA 402 controlword)

    def task(self, name: str) -> Task:
        return _lookup({t.name: t for t in self.tasks}, name, f"task of node '{self.name}'")


@dataclass(frozen=True)
class NodeIdentity:
    """A device's identity object 0x1018 (CiA 301): sub 1 vendor id, sub 2 product code, sub 3 revision number.
    None: the device profile does not know it (e.g. the product code of a profile that covers several variants)."""

    vendor_id: int | None
    product_code: int | None
    revision: int | None


@dataclass(frozen=True)
class SdoWrite:
    """One start-up SDO download: data_type is the CiA 301 data type code, which fixes the value's size and sign."""

    index: int
    sub: int
    data_type: int
    value: int


@dataclass(frozen=True)
class CanopenParams:
    sync_period_ns: int
    sync_window_ns: int | None
    read_window_ns: int | None
    sync_producer: str
    sync_id: int
    master_jitter_ns: int = 0  # how late the producer's SYNC and SYNC task may come; 0 in files written before it
    sync_overflow: int = 0  # CiA 301 0x1019: 0 no counter, else SYNC carries a counter 1..sync_overflow
    sync_completion_ns: int | None = None  # analysed worst case: SYNC queued -> last synchronous TPDO received

    def collect_window_ns(self) -> int:
        """How long after SYNC a master collects the synchronous TPDOs: its read window; without one the synchronous
        window (0x1007: CiA 301 lets no synchronous PDO go out after it), else the whole SYNC period."""
        return self.read_window_ns or self.sync_window_ns or self.sync_period_ns


@dataclass(frozen=True)
class SrtEntry:
    ftt_id: int
    name: str
    kind: str  # "message" | "trigger"
    targets: tuple[str, ...]
    period_ec: int
    fastest_period_ec: int
    init_ec: int


@dataclass(frozen=True)
class EcSlot:
    ec: int
    ids: tuple[int, ...]  # FTT ids the trigger message announces
    messages: tuple[str, ...]  # synchronous window, in transmission (identifier) order
    triggers: tuple[str, ...]
    mask: int  # the TM's EC-schedule: bit i set when FTT id i is due
    sync_ns: int
    async_ns: int


@dataclass(frozen=True)
class FttParams:
    ec_ns: int
    tm_size: int
    tm_id: int
    tm_ns: int
    lsw_ns: int
    master: str
    macro_cycle_ec: int
    srt: tuple[SrtEntry, ...]
    schedule: tuple[EcSlot, ...]  # one per EC of the macro-cycle
    sync_first: bool = False  # the synchronous window right after the TM (default: it closes the EC)

    def slot(self, ec: int) -> EcSlot:
        """The EC-schedule of elementary cycle ec (counted from the first, wrapping over the macro-cycle)."""
        return self.schedule[ec % self.macro_cycle_ec]

    def window_start(self, ec: int) -> int:
        """Start of EC ec's synchronous window, from the EC start (as netcfg.timing.ftt.Schedule.window_start)."""
        if self.sync_first:
            return self.tm_ns
        return self.ec_ns - self.slot(ec).sync_ns

    def async_window(self, ec: int) -> tuple[int, int]:
        """EC ec's asynchronous window, from the EC start: (start, end by which a frame must be done)."""
        if self.sync_first:
            return self.tm_ns + self.slot(ec).sync_ns, self.ec_ns
        return 0, self.window_start(ec)


@dataclass(frozen=True)
class SwitchPort:
    port: int
    to: str
    cable_m: float


@dataclass(frozen=True)
class Switch:
    name: str
    latency_ns: int
    ports: tuple[SwitchPort, ...]


@dataclass(frozen=True)
class EthernetParams:
    switches: tuple[Switch, ...]


@dataclass(frozen=True)
class Bus:
    name: str
    protocol: str  # "can" | "can-fd" | "canopen" | "ftt-can" | "ethernet-udp"
    bitrate: int
    id_bits: int
    nodes: tuple[str, ...]
    canopen: CanopenParams | None
    ftt: FttParams | None
    ethernet: EthernetParams | None
    data_bitrate: int | None = None  # CAN FD: the data-phase rate

    @property
    def is_can(self) -> bool:
        return self.protocol in CAN_PROTOCOLS


@dataclass(frozen=True)
class Trigger:
    name: str
    bus: str
    ftt_id: int
    period_ns: int
    interval_ns: int
    offset_ns: int | None
    tasks: tuple[str, ...]  # node.task refs


@dataclass(frozen=True)
class FlowStep:
    kind: str  # "task" | "message"
    refs: tuple[str, ...]  # several: in parallel, all needed


@dataclass(frozen=True)
class Flow:
    name: str
    steps: tuple[FlowStep, ...]
    deadline_ns: int | None
    latency_min_ns: int | None  # the analysis' bounds
    latency_max_ns: int | None
    # the analysis' bounds for the same flow without SYNC alignment; None when it gave none
    unsync_latency_min_ns: int | None = None
    unsync_latency_max_ns: int | None = None


T = TypeVar("T")


def _lookup(table: Mapping[str, T], name: str, what: str) -> T:
    try:
        return table[name]
    except KeyError:
        # a name that differs only in case is the likeliest meant; difflib is case-sensitive
        same = [k for k in table if k.casefold() == name.casefold()]
        close = same + [c for c in difflib.get_close_matches(name, list(table), n=3) if c not in same]
        hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        raise UnknownNameError(f"no {what} named {name!r}{hint}") from None


@dataclass(frozen=True)
class RuntimeConfig:
    format: str
    version: int
    system: str
    spec_sha256: str
    buses: tuple[Bus, ...]
    nodes: tuple[Node, ...]
    messages: tuple[Message, ...]
    triggers: tuple[Trigger, ...]
    flows: tuple[Flow, ...]
    source: str = field(default="<memory>", compare=False)
    _index: dict[str, dict[Any, Any]] = field(init=False, repr=False, compare=False, hash=False)

    def __post_init__(self) -> None:
        can_ids: dict[tuple[str, int, bool], list[Message]] = {}
        udp_ids: dict[tuple[str, int], list[Message]] = {}
        for m in self.messages:
            if m.is_can:
                can_ids.setdefault((m.bus, m.id, m.extended), []).append(m)
            else:
                udp_ids.setdefault((m.bus, m.id), []).append(m)
        object.__setattr__(
            self,
            "_index",
            {
                "message": {m.name: m for m in self.messages},
                "bus": {b.name: b for b in self.buses},
                "node": {n.name: n for n in self.nodes},
                "trigger": {t.name: t for t in self.triggers},
                "flow": {f.name: f for f in self.flows},
                "can": can_ids,
                "udp": udp_ids,
            },
        )

    def path(self, relative: str) -> Path:
        """A file runtime.json names (node.eds, node.dcf) as a path: relative to the runtime.json's folder."""
        if self.source == "<memory>":
            raise ValueError(f"{relative}: this config was not loaded from a file, so its folder is unknown")
        return Path(self.source).parent / relative

    def matches_spec(self, spec: str | Path) -> bool:
        """Whether this config was built from exactly this spec file (a master can refuse a stale one)."""
        return hashlib.sha256(Path(spec).read_bytes()).hexdigest() == self.spec_sha256

    def message(self, name: str) -> Message:
        return _lookup(self._index["message"], name, "message")

    def bus(self, name: str) -> Bus:
        return _lookup(self._index["bus"], name, "bus")

    def node(self, name: str) -> Node:
        return _lookup(self._index["node"], name, "node")

    def trigger(self, name: str) -> Trigger:
        return _lookup(self._index["trigger"], name, "trigger")

    def flow(self, name: str) -> Flow:
        return _lookup(self._index["flow"], name, "flow")

    def task(self, ref: str) -> Task:
        """A task by its 'node.task' reference."""
        node, _, name = ref.partition(".")
        return self.node(node).task(name)

    def messages_on(self, bus: str) -> tuple[Message, ...]:
        self.bus(bus)
        return tuple(m for m in self.messages if m.bus == bus)

    def can_message(self, can_id: int, extended: bool = False, bus: str | None = None) -> Message:
        """The message sent with this CAN identifier; `bus` is needed only when several CAN buses use it."""
        if bus is not None:
            self.bus(bus)
        found = [
            m
            for (b, i, x), ms in self._index["can"].items()
            if i == can_id and x == extended and (bus is None or b == bus)
            for m in ms
        ]
        width = 8 if extended else 3
        where = f" on bus '{bus}'" if bus is not None else ""
        if not found:
            raise UnknownNameError(f"no message has CAN id 0x{can_id:0{width}X}{where} ({_frame_kind(extended)})")
        if len(found) > 1:
            names = ", ".join(f"{m.name} ({m.bus})" for m in found)
            raise LookupError(f"CAN id 0x{can_id:0{width}X} is used by {names}; say which bus the frame came from")
        return found[0]

    def decode_can(self, msg: can.Message, bus: str | None = None) -> tuple[Message, dict[str, Number]]:
        """A received python-can frame -> (its message, physical values)."""
        m = self.can_message(msg.arbitration_id, bool(msg.is_extended_id), bus)
        return m, m.decode(bytes(msg.data))

    def decode_udp(
        self, bus: str, datagram: bytes, *, src_port: int | None = None, dst_port: int | None = None
    ) -> tuple[Message, dict[str, Number]]:
        """A UDP payload (message id byte + data) -> (its message, physical values). Several messages may
        share an id (seed 001: both encoders send 0x42); the ports then tell them apart."""
        self.bus(bus)
        if not datagram:
            raise CodecError("an empty datagram has no message id")
        candidates = [
            m
            for m in self._index["udp"].get((bus, datagram[0]), [])
            if m.udp is None
            or ((src_port is None or m.udp.src_port == src_port) and (dst_port is None or m.udp.dst_port == dst_port))
        ]
        if not candidates:
            raise UnknownNameError(f"no message with id 0x{datagram[0]:02X} on bus '{bus}' matches these ports")
        if len(candidates) > 1:
            names = ", ".join(m.name for m in candidates)
            raise LookupError(f"id 0x{datagram[0]:02X} on bus '{bus}' is used by {names}; give src_port/dst_port")
        m = candidates[0]
        return m, m.decode(datagram[1:])


def _frame_kind(extended: bool) -> str:
    return "29-bit" if extended else "11-bit"


# --- reading -----------------------------------------------------------------------------------------------------


def load(path: str | Path) -> RuntimeConfig:
    """Read a runtime.json; RuntimeConfigError (naming the file) when it is not one this netcfg can read."""
    source = str(path)
    return parse(read_document(path), source)


def read_document(path: str | Path) -> Any:
    """The decoded JSON of a runtime.json, through netcfg's input guard (size, depth and number limits checked
    before parsing); RuntimeConfigError naming the file when it cannot be read or is not JSON."""
    source = str(path)
    try:
        text = read_input_text(path, "runtime config")
    except InputError as exc:
        raise RuntimeConfigError(f"{source}: cannot read the runtime config: {exc}") from exc
    try:
        return parse_json(text)
    except JsonInputError as exc:
        raise RuntimeConfigError(f"{source}: not a runtime config: {exc}") from exc


def parse(data: Any, source: str = "<memory>") -> RuntimeConfig:
    """A runtime config from its decoded JSON."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise RuntimeConfigError(f"{source}: not a netcfg runtime config (format {found!r}, expected {FORMAT!r})")
    version = data.get("version")
    if version not in SUPPORTED_VERSIONS or isinstance(version, bool):
        supported = ", ".join(map(str, SUPPORTED_VERSIONS))
        raise RuntimeConfigError(
            f"{source}: runtime config version {version!r} is not supported; this netcfg reads version "
            f"{supported}. Rebuild it with 'netcfg build' from the netcfg release the master uses."
        )
    problems = check_document(data)  # the same field table the emitter checks what it writes against
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise RuntimeConfigError(
            f"{source}: malformed runtime config: {problems[0]}{more}; rebuild it with 'netcfg build'"
        )
    try:
        cfg = _config(data, source)
    except KeyError as exc:
        raise RuntimeConfigError(
            f"{source}: malformed runtime config version {version}: missing key {exc}; rebuild it with 'netcfg build'"
        ) from exc
    except (TypeError, ValueError, AttributeError) as exc:
        raise RuntimeConfigError(f"{source}: malformed runtime config version {version}: {exc}") from exc
    problems = _problems(cfg)
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise RuntimeConfigError(
            f"{source}: malformed runtime config: {problems[0]}{more}; rebuild it with 'netcfg build'"
        )
    return cfg


_INT_FIELDS = {
    "message": (
        "id",
        "size",
        "period_ns",
        "interval_ns",
        "offset_ns",
        "deadline_ns",
        "jitter_ns",
        "wcrt_ns",
        "wcrt_unsync_ns",
    ),
    "task": ("period_ns", "offset_ns", "wcet_ns", "bcet_ns"),
    "bus": ("bitrate", "id_bits"),
}


def _problems(cfg: RuntimeConfig) -> list[str]:
    """What a hand-edited or damaged file gets wrong: numbers that are not integers, names that lead nowhere."""
    out: list[str] = []

    def ints(kind: str, name: str, obj: object) -> None:
        for attr in _INT_FIELDS[kind]:
            v = getattr(obj, attr)
            if v is not None and (not isinstance(v, int) or isinstance(v, bool) or v < 0):
                out.append(f"{kind} '{name}': {attr} must be a non-negative integer, not {v!r}")

    buses = {b.name for b in cfg.buses}
    nodes = {n.name for n in cfg.nodes}
    messages = {m.name for m in cfg.messages}
    triggers = {t.name for t in cfg.triggers}
    tasks = {t.ref for n in cfg.nodes for t in n.tasks}
    for b in cfg.buses:
        ints("bus", b.name, b)
        out += [f"bus '{b.name}': node '{n}' is not in the config" for n in b.nodes if n not in nodes]
    for n in cfg.nodes:
        out += [f"node '{n.name}': bus '{b}' is not in the config" for b in n.buses if b not in buses]
        for t in n.tasks:
            ints("task", t.ref, t)
            if t.trigger is not None and t.trigger not in triggers:
                out.append(f"task '{t.ref}': trigger '{t.trigger}' is not in the config")
            if t.on_message is not None and t.on_message not in messages:
                out.append(f"task '{t.ref}': message '{t.on_message}' is not in the config")
            if t.sync_bus is not None and t.sync_bus not in buses:
                out.append(f"task '{t.ref}': bus '{t.sync_bus}' is not in the config")
    for m in cfg.messages:
        ints("message", m.name, m)
        if m.bus not in buses:
            out.append(f"message '{m.name}': bus '{m.bus}' is not in the config")
        ends = (m.producer, *m.consumers)
        out += [f"message '{m.name}': node '{x}' is not in the config" for x in ends if x not in nodes]
        out += [f"message '{m.name}': task '{x}' is not in the config" for x in m.sent_by or () if x not in tasks]
    for trig in cfg.triggers:
        out += [f"trigger '{trig.name}': task '{x}' is not in the config" for x in trig.tasks if x not in tasks]
    for f in cfg.flows:
        for step in f.steps:
            known = tasks if step.kind == "task" else messages
            out += [f"flow '{f.name}': {step.kind} '{r}' is not in the config" for r in step.refs if r not in known]
    return out


def _config(d: dict[str, Any], source: str) -> RuntimeConfig:
    buses = tuple(_bus(b) for b in d["buses"])
    protocol = {b.name: b.protocol for b in buses}
    return RuntimeConfig(
        format=d["format"],
        version=d["version"],
        system=d["system"],
        spec_sha256=d["spec_sha256"],
        buses=buses,
        nodes=tuple(_node(n) for n in d["nodes"]),
        messages=tuple(_message(m, protocol[m["bus"]]) for m in d["messages"]),
        triggers=tuple(_trigger(t) for t in d["triggers"]),
        flows=tuple(_flow(f) for f in d["flows"]),
        source=source,
    )


def _strs(items: Iterable[Any]) -> tuple[str, ...]:
    return tuple(str(x) for x in items)


def _opt_float(x: Any) -> float | None:
    return None if x is None else float(x)


def _bus(d: dict[str, Any]) -> Bus:
    co, ft, eth = d["canopen"], d["ftt"], d["ethernet"]
    return Bus(
        name=d["name"],
        protocol=d["protocol"],
        bitrate=d["bitrate"],
        data_bitrate=d.get("data_bitrate"),
        id_bits=d["id_bits"],
        nodes=_strs(d["nodes"]),
        canopen=None
        if co is None
        else CanopenParams(
            co["sync_period_ns"],
            co["sync_window_ns"],
            co["read_window_ns"],
            co["sync_producer"],
            co["sync_id"],
            co.get("master_jitter_ns", 0),
            co.get("sync_overflow", 0),
            co.get("sync_completion_ns"),
        ),
        ftt=None if ft is None else _ftt(ft),
        ethernet=None
        if eth is None
        else EthernetParams(
            tuple(
                Switch(
                    s["name"],
                    s["latency_ns"],
                    tuple(SwitchPort(p["port"], p["to"], float(p["cable_m"])) for p in s["ports"]),
                )
                for s in eth["switches"]
            )
        ),
    )


def _ftt(d: dict[str, Any]) -> FttParams:
    return FttParams(
        ec_ns=d["ec_ns"],
        tm_size=d["tm_size"],
        tm_id=d["tm_id"],
        tm_ns=d["tm_ns"],
        lsw_ns=d["lsw_ns"],
        master=d["master"],
        macro_cycle_ec=d["macro_cycle_ec"],
        srt=tuple(
            SrtEntry(
                e["ftt_id"],
                e["name"],
                e["kind"],
                _strs(e["targets"]),
                e["period_ec"],
                e["fastest_period_ec"],
                e["init_ec"],
            )
            for e in d["srt"]
        ),
        schedule=tuple(
            EcSlot(
                s["ec"],
                tuple(s["ids"]),
                _strs(s["messages"]),
                _strs(s["triggers"]),
                s["mask"],
                s["sync_ns"],
                s["async_ns"],
            )
            for s in d["schedule"]
        ),
        sync_first=d.get("windows", "async-first") == "sync-first",
    )


def _node(d: dict[str, Any]) -> Node:
    return Node(
        name=d["name"],
        node_id=d["node_id"],
        role=d["role"],
        buses=_strs(d["buses"]),
        ip=d["ip"],
        device=d["device"],
        heartbeat_ns=d["heartbeat_ns"],
        tx_delay_ns=d["tx_delay_ns"],
        rx_delay_ns=d["rx_delay_ns"],
        tasks=tuple(
            Task(
                d["name"],
                t["name"],
                t["period_ns"],
                t["offset_ns"],
                t["wcet_ns"],
                t["bcet_ns"],
                t["trigger"],
                t["on_message"],
                t.get("sync_bus"),
            )
            for t in d["tasks"]
        ),
        identity=_identity(d.get("identity")),
        eds=d.get("eds"),
        dcf=d.get("dcf"),
        sdo_init=None
        if d.get("sdo_init") is None
        else tuple(SdoWrite(w["index"], w["sub"], w["data_type"], w["value"]) for w in d["sdo_init"]),
        rpdo_count=d.get("rpdo_count"),
        tpdo_count=d.get("tpdo_count"),
        heartbeat_timeout_ns=d.get("heartbeat_timeout_ns"),
        on_loss=d.get("on_loss", "stop_all"),
        on_emcy=d.get("on_emcy", "stop_all"),
        safe_stop=d.get("safe_stop", "quick_stop"),
    )


def _identity(d: dict[str, Any] | None) -> NodeIdentity | None:
    return None if d is None else NodeIdentity(d["vendor_id"], d["product_code"], d["revision"])


def _message(d: dict[str, Any], protocol: str) -> Message:
    pdo, udp, rate = d["pdo"], d["udp"], d["rate_hz"]
    return Message(
        name=d["name"],
        bus=d["bus"],
        protocol=protocol,
        producer=d["producer"],
        consumers=_strs(d["consumers"]),
        id=d["id"],
        extended=bool(d["extended"]),
        size=d["size"],
        kind=d["kind"],
        period_ns=d["period_ns"],
        interval_ns=d["interval_ns"],
        offset_ns=d["offset_ns"],
        deadline_ns=d["deadline_ns"],
        jitter_ns=d["jitter_ns"],
        rate_hz=None if rate is None else Fraction(rate[0], rate[1]),
        window=d["window"],
        ftt_id=d["ftt_id"],
        fd=bool(d.get("fd", False)),
        brs=bool(d.get("brs", False)),
        frame_size=d.get("frame_size", 0),
        udp=None if udp is None else UdpPorts(udp["src_port"], udp["dst_port"]),
        pdo=None
        if pdo is None
        else Pdo(
            kind=pdo["kind"],
            number=pdo["number"],
            node=pdo["node"],
            transmission=pdo["transmission"],
            inhibit_100us=pdo["inhibit_100us"],
            event_timer_ms=pdo["event_timer_ms"],
            sync_start=pdo["sync_start"],
            entries=tuple(PdoEntry(e["index"], e["sub"], e["bits"], e["name"], e["data_type"]) for e in pdo["entries"]),
            cob_id=pdo.get("cob_id"),
        ),
        signals=tuple(
            Signal(
                name=s["name"],
                start_bit=s["start_bit"],
                bits=s["bits"],
                signed=bool(s["signed"]),
                is_float=bool(s["float"]),
                scale=float(s["scale"]),
                offset=float(s["offset"]),
                minimum=_opt_float(s["min"]),
                maximum=_opt_float(s["max"]),
                unit=s["unit"],
                big_endian=s.get("byte_order", "little_endian") == "big_endian",
                mux=s.get("mux"),
                mux_values=tuple(int(v) for v in s.get("mux_values", ())),
                choices=tuple((int(raw), str(name)) for raw, name in s.get("enum", ())),
            )
            for s in d["signals"]
        ),
        implicit=d["implicit"],
        wcrt_ns=d["wcrt_ns"],
        sent_by=None if d.get("sent_by") is None else _strs(d["sent_by"]),
        wcrt_unsync_ns=d.get("wcrt_unsync_ns"),
    )


def _trigger(d: dict[str, Any]) -> Trigger:
    return Trigger(
        d["name"], d["bus"], d["ftt_id"], d["period_ns"], d["interval_ns"], d["offset_ns"], _strs(d["tasks"])
    )


def _flow(d: dict[str, Any]) -> Flow:
    return Flow(
        name=d["name"],
        steps=tuple(FlowStep(s["kind"], _strs(s["refs"])) for s in d["steps"]),
        deadline_ns=d["deadline_ns"],
        latency_min_ns=d["latency_min_ns"],
        latency_max_ns=d["latency_max_ns"],
        unsync_latency_min_ns=d.get("unsync_latency_min_ns"),
        unsync_latency_max_ns=d.get("unsync_latency_max_ns"),
    )
