"""The runtime config's data classes: buses, nodes, messages (with their CAN and UDP encoding), tasks, triggers,
flows, and RuntimeConfig with its lookups. Re-exported by netcfg.runtime; read from a file by netcfg.runtime.loader."""

from __future__ import annotations

import difflib
import hashlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, TypeVar

from netcfg.runtime import codec
from netcfg.runtime.codec import CodecError, Field, Number

if TYPE_CHECKING:
    import can

    from netcfg.runtime.actuators import Actuator

# How the frames of the links runtime.json names travel. The runtime imports without the compiler's layers, so it
# cannot ask netcfg.links; a test ties these to the links' own `arbitrates` and `switched`.
CAN_LINKS = ("can", "can-fd")  # CAN frames (ISO 11898-1) that arbitrate by identifier: python-can carries them
SWITCHED_LINKS = ("ethernet",)  # switched Ethernet, which carries UDP datagrams (the one protocol netcfg runs there)
FD_PADDING = 0x00  # pads a CAN FD payload to its frame length, as netcfg.timing.frames.CANFD_PADDING (tested)


class _Carried:
    """How a bus's or a message's frames travel: by the link runtime.json gives the bus (the table above)."""

    link: str

    @property
    def is_can(self) -> bool:
        return self.link in CAN_LINKS

    @property
    def is_udp(self) -> bool:
        return self.link in SWITCHED_LINKS


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


DEFAULT_CLOCK_TOLERANCE_PPM = 100  # a bus without clock_tolerance_ppm: its senders' clocks within +-100 ppm


@dataclass(frozen=True)
class Signal(Field):
    """A codec field with its unit (layout, byte order, multiplexing and value names: netcfg.runtime.codec)."""

    unit: str | None = None


@dataclass(frozen=True)
class MappedObject:
    """An object-dictionary entry a PDO maps: index, sub-index, length and name. CiA 301 PDOs and EtherCAT's
    (CANopen over EtherCAT, ETG.2000: netcfg.protocols.ethercat.esi) address their objects alike."""

    index: int
    sub: int
    bits: int
    name: str


@dataclass(frozen=True)
class PdoEntry(MappedObject):  # the spec's model maps the same records (netcfg.model.Pdo)
    data_type: int  # CiA 301 data type code


@dataclass(frozen=True)
class PdoParameters:
    """A PDO slot's communication and mapping parameters (CiA 301 0x14xx/0x18xx, 0x16xx/0x1Axx): the spec's model
    holds a message's PDO as this (netcfg.model.Pdo), runtime.json as the Pdo below."""

    kind: Literal["tpdo", "rpdo"]
    number: int
    node: str  # the node whose TPDO/RPDO slot this is
    transmission: int
    inhibit_100us: int | None
    event_timer_ms: int | None
    sync_start: int | None
    entries: tuple[PdoEntry, ...]


@dataclass(frozen=True)
class Pdo(PdoParameters):
    # the 32-bit value of the slot's COB-ID (0x14xx/0x18xx sub 1), CiA 301 flag bits included, as the node's DCF
    # has it (the model's is its message's id); None in files written before it
    cob_id: int | None = None


@dataclass(frozen=True)
class UdpPorts:
    src_port: int
    dst_port: int


@dataclass(frozen=True)
class Message(_Carried):
    name: str
    bus: str
    protocol: str  # the bus's protocol
    link: str  # the bus's link: decides between CAN frames and UDP datagrams
    producer: str
    consumers: tuple[str, ...]
    # CAN identifier; the 1-byte application message id on Ethernet (seed 001, Table 6.1); on EtherCAT the PDO's
    # logical address (its byte offset in the process image, as its slave's FMMU has it)
    id: int
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
    # a remote frame (RTR, ISO 11898-1): no data field, size 0; it asks for the data frame of its identifier
    remote: bool = False
    fields: tuple[Field, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.frame_size:
            object.__setattr__(self, "frame_size", self.size)
        fields: tuple[Field, ...] = self.signals
        if not fields and self.size > 0:
            fields = (Field(raw_signal_name(self.name), 0, 8 * self.size),)
        object.__setattr__(self, "fields", fields)

    @property
    def min_gap_ns(self) -> int:
        """How close two sends of it may come: a sporadic message's minimum inter-arrival time (a send that a task
        raises sooner is skipped), 0 for the others."""
        return self.interval_ns if self.kind == "sporadic" and self.interval_ns else 0

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
        return self._decode(bytes(data[: self.size]))

    @cached_property
    def _decode(self) -> Callable[[bytes], dict[str, Number]]:
        return codec.decoder(self.fields)

    def to_can(self, **values: Number | str | bytes) -> can.Message:
        if not self.is_can:
            raise TypeError(f"message '{self.name}' travels on {self.protocol} bus '{self.bus}'; use encode_udp()")
        return self.frame(self.encode(**values))

    def frame(self, data: bytes) -> can.Message:
        """The CAN frame carrying this payload (from encode()), as to_can() sends it."""
        from netcfg.links import pycan_frames  # only CAN masters need python-can

        if self.fd:  # padded to the frame length, so that every receiver sees the DLC the analysis timed
            data += bytes([FD_PADDING]) * (self.frame_size - self.size)
            return pycan_frames.message(self.id, self.extended, data, fd=True, brs=self.brs, dlc=len(data))
        if self.remote:  # no data field; the DLC a requester gives is the length it asks for, unknown here: 0
            return pycan_frames.message(self.id, self.extended, None, remote=True, dlc=0)
        return pycan_frames.message(self.id, self.extended, data, dlc=self.size)

    def encode_udp(self, **values: Number | str | bytes) -> bytes:
        """The UDP datagram's payload: the 1-byte message id, then the data (seed 001, Table 6.1)."""
        if not self.is_udp:
            raise TypeError(f"message '{self.name}' travels on {self.protocol} bus '{self.bus}'; use to_can()")
        return bytes([self.id]) + self.encode(**values)


@dataclass(frozen=True)
class TaskTiming:
    """What a task is in time, as runtime.json and the spec's model (netcfg.model.Task) both hold it."""

    node: str
    name: str
    period_ns: int | None
    offset_ns: int
    wcet_ns: int
    bcet_ns: int
    trigger: str | None  # FTT-CAN trigger that activates it
    on_message: str | None  # event-driven: runs when this message arrives

    @property
    def ref(self) -> str:
        return f"{self.node}.{self.name}"


@dataclass(frozen=True)
class Task(TaskTiming):
    sync_bus: str | None = None  # CANopen: runs on every SYNC of this bus, offset_ns after it


@dataclass(frozen=True)
class TxQueue:
    """How a node hands frames to its CAN controller: in priority order, or FIFO with a depth and what a send into
    a full queue does (block the writer, or drop the frame). The spec's model (netcfg.model) uses it too."""

    policy: Literal["priority", "fifo"] = "priority"
    depth: int = 10  # frames a FIFO holds (SocketCAN's default txqueuelen)
    on_full: Literal["block", "drop"] = "block"

    @property
    def fifo(self) -> bool:
        return self.policy == "fifo"


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
    on_reboot: str = "stop_node"  # recover | stop_node | stop_all: a boot-up message while running
    sdo_timeout_ns: int = 500_000_000  # the master's wait for each SDO answer (files written before it: 500 ms)
    sdo_retries: int = 0  # SDO requests repeated after a timeout
    safe_stop: str = "quick_stop"  # quick_stop | disable_operation (CiA 402 controlword)
    # CAN transmit queue; a file written before this key: priority-queued
    tx_queue: TxQueue = TxQueue()
    # an actuator profile's node (None: not one, or a file written before the key)
    actuator: Actuator | None = None

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
    allowance_ns: int = 0  # the synchronous window's bit-error allowance: the window opens this much earlier


@dataclass(frozen=True)
class ErrorAssumption:
    """At most `burst` bit errors at once plus one per `interval_ns`: what the bus's bounds allow for."""

    burst: int
    interval_ns: int


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
        return self.ec_ns - self.slot(ec).sync_ns - self.slot(ec).allowance_ns

    def async_window(self, ec: int) -> tuple[int, int]:
        """EC ec's asynchronous window, from the EC start: (start, end by which a frame must be done)."""
        if self.sync_first:
            return self.tm_ns + self.slot(ec).sync_ns + self.slot(ec).allowance_ns, self.ec_ns
        return 0, self.window_start(ec)


@dataclass(frozen=True)
class SwitchPort:
    port: int
    to: str
    cable_m: float
    queue: int | None = None  # frames its egress queue holds (None: a file written before the key)


@dataclass(frozen=True)
class Switch:
    name: str
    latency_ns: int
    ports: tuple[SwitchPort, ...]
    queue: int | None = None  # the egress queue's depth of a port not listed (None: a file written before the key)


@dataclass(frozen=True)
class EthernetParams:
    switches: tuple[Switch, ...]
    # (node, frames its NIC's transmit queue holds) per node of the bus; None: a file written before the key
    nic_queues: tuple[tuple[str, int], ...] | None = None

    def nic_queue(self, node: str) -> int | None:
        return dict(self.nic_queues or ()).get(node)


@dataclass(frozen=True)
class Bus(_Carried):
    name: str
    protocol: str  # "can" | "can-fd" | "canopen" | "ftt-can" | "ethernet-udp" | "ethercat"
    link: str  # the physical bus it runs over: "can" | "can-fd" | "ethernet" | "ethercat" (netcfg.links)
    bitrate: int
    id_bits: int
    nodes: tuple[str, ...]
    canopen: CanopenParams | None
    ftt: FttParams | None
    ethernet: EthernetParams | None
    data_bitrate: int | None = None  # CAN FD: the data-phase rate
    errors: ErrorAssumption | None = None  # the bit errors the analysis allowed for; None: an error-free bus
    clock_tolerance_ppm: int = DEFAULT_CLOCK_TOLERANCE_PPM  # senders' clocks within +-this, as analysed
    # EtherCAT: the segment's section as runtime.json has it (netcfg.runtime.schema.ETHERCAT), for a SOEM master
    ethercat: Mapping[str, Any] | None = None


@dataclass(frozen=True)
class TriggerTiming:
    """An FTT-CAN trigger in time, as runtime.json and the spec's model (netcfg.model.Trigger) both hold it."""

    name: str
    bus: str
    ftt_id: int
    period_ns: int
    interval_ns: int
    offset_ns: int | None


@dataclass(frozen=True)
class Trigger(TriggerTiming):
    tasks: tuple[str, ...]  # node.task refs


@dataclass(frozen=True)
class FlowStep:
    kind: Literal["task", "message"]
    refs: tuple[str, ...]  # node.task or message names; several: in parallel, all needed


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
