"""The resolved Model: the spec with every default filled in and every reference checked.

Analyses, emitters and the runtime configuration read only this. Times are integer nanoseconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from typing import TYPE_CHECKING, Any, Literal

from netcfg.devices import DeviceProfile
from netcfg.timing.frames import QUEUE_FRAMES, canfd_padded_size

if TYPE_CHECKING:
    from netcfg.timing.ftt_schedule import Schedule
from netcfg.runtime.config import (  # the same records in runtime.json: defined once, there
    FlowStep,
    TaskTiming,
    TriggerTiming,
    TxQueue,
)
from netcfg.runtime.pdos import PdoParameters
from netcfg.spec.source import Path, SourceMap

Protocol = Literal["can", "can-fd", "canopen", "ftt-can", "ethernet-udp", "ethercat"]
Pdo = PdoParameters  # a message's PDO: runtime.json's Pdo adds the COB-ID, which the model has as the message's id
MessageKind = Literal["periodic", "sporadic", "on-demand"]


@dataclass(frozen=True)
class Task(TaskTiming):
    path: Path
    description: str | None = None
    sync_bus: str | None = None  # runs on this bus's cycle (CANopen: each SYNC; EtherCAT: the cycle, DC slaves' SYNC0)
    cycle_jitter_ns: int = 0  # ... up to this late (an EtherCAT master's send jitter; SYNC0's precision, either way)
    priority: int | None = None  # on its node's processor, 0 the highest; None: rate-monotonic


@dataclass
class Node:
    name: str
    node_id: int | None
    buses: tuple[str, ...]
    role: Literal["master", "slave"]
    device: DeviceProfile | None
    heartbeat_ns: int | None
    ip: str | None
    tx_delay_ns: int
    rx_delay_ns: int
    tasks: dict[str, Task]
    path: Path
    description: str | None = None
    scheduling: Literal["preemptive", "non-preemptive"] = "preemptive"  # fixed-priority, of its tasks
    heartbeat_timeout_ns: int | None = None  # the master's consumer time for this node's heartbeat
    on_loss: str = "stop_all"  # stop_all | stop_node | continue
    on_emcy: str = "stop_all"
    on_reboot: str = "stop_node"  # recover | stop_node | stop_all
    sdo_timeout_ns: int = 500_000_000  # the master's wait for each SDO answer
    sdo_retries: int = 0  # SDO requests repeated after a timeout
    safe_stop: str = "quick_stop"  # quick_stop | disable_operation (CiA 402 controlword)
    tx_queue: TxQueue = field(default_factory=TxQueue)
    nic_queue: int = QUEUE_FRAMES  # Ethernet: frames its NIC's transmit queue holds
    # an actuator profile's node: its plain profile, parameters and which model messages carry its commands, replies
    # and cyclic messages (netcfg.resolve.actuators; runtime.json's `actuator`, netcfg.runtime.actuators.Actuator)
    actuator: dict[str, Any] | None = None
    # the actuator's vendor ros2_control plugin, as its profile describes it (netcfg.devices.actuator_ros2); None: the
    # profile has none (or the node is no actuator)
    ros2_control: dict[str, Any] | None = None


@dataclass(frozen=True)
class Signal:
    """A field of a payload, laid out as netcfg.runtime.codec says: little-endian (Intel) by default, start_bit
    its least significant bit; big-endian (Motorola): start_bit its most significant bit."""

    name: str
    start_bit: int
    bits: int
    signed: bool
    is_float: bool = False  # IEEE 754 binary32/binary64 (bits 32 or 64)
    scale: float = 1.0
    offset: float = 0.0
    minimum: float | None = None
    maximum: float | None = None
    unit: str | None = None
    big_endian: bool = False  # Motorola: start_bit is the most significant bit (netcfg.runtime.codec)
    mux: str | None = None  # present only when this multiplexer signal ...
    mux_values: tuple[int, ...] = ()  # ... holds one of these raw values
    choices: tuple[tuple[int, str], ...] = ()  # value names (DBC VAL_), by raw value
    is_multiplexer: bool = False  # another signal of the message names this one as its mux
    # MIT packing over [lo, hi] (netcfg.runtime.actuators.span_to_raw): raw = trunc((x - lo) * (2^bits - 1) /
    # (hi - lo)); scale and offset are its linear map (what a DBC can say of it)
    span: tuple[float, float] | None = None


@dataclass
class Message:
    name: str
    bus: str
    producer: str
    consumers: tuple[str, ...]
    id: int
    extended: bool
    size: int
    kind: MessageKind
    period_ns: int | None  # nominal period (periodic)
    interval_ns: int | None  # shortest time between two releases: fastest period or min inter-arrival
    offset_ns: int | None
    offset_auto: bool
    deadline_ns: int | None
    jitter_ns: int
    path: Path
    window: Literal["sync", "async"] | None = None
    ftt_id: int | None = None
    pdo: Pdo | None = None
    signals: tuple[Signal, ...] = ()
    rate_hz: Fraction | None = None  # exact rate when the spec gave one (Ethernet)
    udp_ports: tuple[int, int] | None = None
    slowest_ns: int | None = None  # FTT-CAN period_range: the slowest admissible period (None: no range)
    implicit: str | None = None  # "SYNC", "heartbeat": generated by netcfg, not written in the spec
    description: str | None = None  # free text from the spec: emitters must escape it for their format
    fd: bool = False  # a CAN FD frame (FDF recessive); size may then be up to 64, sent padded to frame_size
    brs: bool = False  # CAN FD bit-rate switch: the data phase at the bus's data_bitrate
    may_be_lost: bool = False  # a FIFO that drops may lose some of its frames: no bound, and no error
    fixed_by: str | None = None  # what sets its identifier and release (an actuator profile): `netcfg tune` keeps both
    # a remote frame (RTR recessive, ISO 11898-1): no data field (size 0), it asks for the data frame of its identifier,
    # which wins arbitration over it; the one case two messages of a bus share an identifier (links.can)
    remote: bool = False
    # the payload a frame starts from before its signals are written, where it is not zeros: an actuator profile's
    # constant fields and padding (netcfg.runtime.actuators.MessageCodec.base)
    base_payload: bytes | None = None

    @property
    def frame_size(self) -> int:
        """Data bytes on the wire: a CAN FD payload padded to the next valid DLC length."""
        return canfd_padded_size(self.size) if self.fd else self.size


@dataclass(frozen=True)
class Trigger(TriggerTiming):
    offset_auto: bool
    tasks: tuple[str, ...]
    path: Path
    description: str | None = None
    slowest_ns: int | None = None  # period_range's slowest admissible period (None: no range)


@dataclass(frozen=True)
class FttBus:
    ec_ns: int
    tm_size: int
    lsw_ns: int  # the spec's LSW, by default EC - TM (the whole EC after the trigger message)
    tm_id: int
    master: str
    sync_first: bool = False  # the synchronous window follows the trigger message (default: it closes the EC)
    tm_fd: bool = False  # the trigger message is a CAN FD frame with bit-rate switch (on a CAN FD link)
    tm_extended: bool = False  # its identifier is a 29-bit one (netcfg.protocols.ftt.tm.TM_EXTENDED: never)


@dataclass(frozen=True)
class CanopenBus:
    sync_period_ns: int
    sync_window_ns: int | None
    read_window_ns: int | None
    sync_producer: str
    sync_id: int
    master_jitter_ns: int = 0  # how late the producer's SYNC and its SYNC task may come (its wake-up latency)
    sync_overflow: int = 0  # CiA 301 0x1019: 0 no counter in SYNC, else 2..240


@dataclass(frozen=True)
class Switch:
    name: str
    ports: dict[int, str]  # port number -> node or switch on the other end
    cables_m: dict[int, float]  # port number -> cable length
    latency_ns: int
    queues: dict[int, int] = field(default_factory=dict)  # port number -> frames its egress queue holds
    queue_paths: dict[int, Path] = field(default_factory=dict)  # port number -> where the spec sets its depth
    queue: int = QUEUE_FRAMES  # the same for a port the spec does not list (a cable listed at its other end)
    path: Path = ()


@dataclass(frozen=True)
class BitErrors:
    """At most `burst` errors at once plus one per `interval_ns` (Tindell and Burns' sporadic model); `ber` is the
    environment's bit error rate the report rates that model against."""

    burst: int
    interval_ns: int
    ber: float


@dataclass
class Bus:
    name: str
    protocol: Protocol
    bitrate: int
    id_bits: int
    nodes: list[str]
    messages: list[Message]
    path: Path
    ftt: FttBus | None = None
    canopen: CanopenBus | None = None
    switches: list[Switch] = field(default_factory=list)
    ethercat: Any = None  # EtherCAT: its segment (netcfg.protocols.ethercat.segment), which the core need not know
    description: str | None = None
    data_bitrate: int | None = None  # CAN FD: the data-phase rate
    clock_tolerance_ppm: int = 100  # CAN: senders' clocks within +-this of nominal (timing.clocks)
    errors: BitErrors | None = None  # the error model the CAN analysis allows for; None: an error-free bus
    # FTT-CAN: the SRT and the EC-schedules of one macro-cycle, built once by the analysis; the emitters read it
    ftt_schedule: Schedule | None = None
    link: str = "can"  # the physical bus the protocol runs on (netcfg.links.LINKS): can, can-fd, ethernet
    arbitrates: bool = True  # its link's frames arbitrate by identifier (netcfg.links: Link.arbitrates)

    @property
    def is_can(self) -> bool:
        """Its frames arbitrate as CAN's do (ISO 11898-1): classical CAN, CAN FD, CANopen and FTT-CAN."""
        return self.arbitrates


@dataclass(frozen=True)
class Flow:
    name: str
    steps: tuple[FlowStep, ...]
    deadline_ns: int | None
    path: Path
    description: str | None = None


@dataclass(frozen=True)
class JointSignal:
    """One interface of a joint: the message and signal that carry it, the factor from the device's value to the
    joint's SI unit (rad, rad/s, N m) and the SI range the signal's bits can hold."""

    message: str
    signal: str
    from_dev: float
    offset: float = 0.0  # the joint value at device value 0 (position: the joint's zero)
    lowest: float = 0.0
    highest: float = 0.0
    # a carrier that is no message but a bus's process data (an EtherCAT slave's PDO entry): its bus; message and
    # signal are then the PDO (0x1600) and the entry's name
    bus: str | None = None


@dataclass(frozen=True)
class Joint:
    """A robot joint moved by one axis of one drive (netcfg.resolve.joints)."""

    name: str
    node: str
    axis: int
    gear_ratio: float
    encoder_counts: int | None
    command: dict[str, JointSignal]  # interface (position, velocity, effort) -> its signal
    state: dict[str, JointSignal]
    limits: dict[str, tuple[float, float]]  # interface -> (lowest, highest), SI
    path: Path
    description: str | None = None
    velocity_unit: str = "rpm"  # the velocity signal's unit at the motor: rpm or counts/s
    rated_torque: float | None = None  # the motor's, N m: the effort signal is in per mille of it
    zero: float = 0.0  # the joint position, rad, where the device's position reads 0


@dataclass
class Model:
    system: str
    file: str
    source: SourceMap
    buses: dict[str, Bus]
    nodes: dict[str, Node]
    messages: dict[str, Message]
    triggers: dict[str, Trigger]
    flows: dict[str, Flow]
    description: str | None = None
    # message -> the tasks (node.task) that send it as they finish (netcfg.resolve.flows); others run free
    sent_by: dict[str, tuple[str, ...]] = field(default_factory=dict)
    joints: dict[str, Joint] = field(default_factory=dict)  # robot joints by name (netcfg.resolve.joints)

    def task(self, ref: str) -> Task:
        node, name = ref.split(".", 1)
        return self.nodes[node].tasks[name]

    def canopen_masters(self, bus: Bus) -> tuple[str, ...]:
        """The nodes of a CANopen bus described as its master (a DCF of their own, with the consumer heartbeat
        times 0x1016 of the nodes they supervise): the master or SYNC producer without a device profile."""
        assert bus.canopen is not None
        return tuple(
            name
            for name in bus.nodes
            if (node := self.nodes[name]).device is None
            and node.node_id is not None
            and (node.role == "master" or name == bus.canopen.sync_producer)
        )


# What the spec can give a description: free text the emitters escape for their format.
Described = Model | Bus | Node | Task | Message | Trigger | Flow
