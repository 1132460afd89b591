"""The spec language: pydantic models of what a user writes in YAML.

These models check shape and types only (unknown keys are errors). Cross-references, identifiers, device
objects and timing rules are checked when the spec is resolved into the Model (netcfg.model). What a name may be
is netcfg.spec.names'.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import (
    AfterValidator,
    BeforeValidator,
    Discriminator,
    Field,
    Tag,
    model_validator,
)

from netcfg.spec.fields import BitRateField, DurationField, FrequencyField, OffsetField
from netcfg.spec.names import check_name as check_name  # the name rule, through this module
from netcfg.spec.names import safe_name as safe_name  # the resolver's, through this module
from netcfg.spec.schema_ethercat import EthercatEsi as EthercatEsi  # the resolver's, through this module
from netcfg.spec.schema_ethercat import EthercatParams
from netcfg.spec.schema_ethercat import EthercatSlave as EthercatSlave
from netcfg.spec.schema_joints import Joint
from netcfg.spec.schema_types import (
    Bool,
    Float,
    Int,
    IntKey,
    Name,
    ObjectRef,
    SpecModel,
    TaskRef,
    _non_zero,
    _ns,
)

# The bit rate a bus of these protocols runs at unless the spec says: an EtherCAT segment is 100BASE-TX (1 Gbit/s,
# EtherCAT G, when the spec says so)
DEFAULT_BITRATES = {"ethercat": "100 Mbit/s"}


class FttParams(SpecModel):
    """FTT-CAN: the master's elementary cycle and trigger message (Almeida, Pedreiras, Fonseca 2002)."""

    ec: DurationField = Field(description="elementary-cycle length")
    tm_size: Int = Field(ge=1, le=8, description="trigger-message payload in bytes; each byte announces 8 ids")
    lsw: DurationField | None = Field(None, description="maximum length of the synchronous window (LSW)")
    tm_id: Int = Field(0, ge=0, description="CAN identifier of the trigger message (the highest priority)")
    sync_id_base: Int = Field(
        0x100, ge=0, description="CAN id of a synchronous message without an explicit id = this + its FTT id"
    )
    master: Name | None = Field(None, description="node that sends the trigger message (default: role master)")
    windows: Literal["async-first", "sync-first"] = Field(
        "async-first",
        description="order of the windows after the trigger message: the asynchronous window first and the "
        "synchronous one closing the EC (the default, as the FTT-CAN papers describe it), or the synchronous "
        "window right after the trigger message",
    )


class CanopenParams(SpecModel):
    sync_period: DurationField = Field(description="communication cycle period, object 0x1006")
    sync_window: DurationField | None = Field(None, description="synchronous window length, object 0x1007")
    read_window: DurationField | None = Field(
        None, description="how long the master waits for the synchronous TPDOs after SYNC"
    )
    sync_producer: Name | None = Field(None, description="node producing SYNC (default: the node with role master)")
    sync_id: Int = Field(0x80, ge=1, le=0x7FF, description="COB-ID of SYNC, object 0x1005")
    sync_counter: Bool | Int = Field(
        False,
        description="SYNC carries a 1-byte counter (CiA 301 0x1019, the counter overflow value): false (no counter), "
        "true (overflow 240, the largest CiA 301 allows) or a number 2..240",
    )
    master_jitter: DurationField = Field(
        default_factory=lambda: _ns(0),
        description="how late the SYNC producer's waits may end (its operating system's wake-up latency): each SYNC "
        "and each start of the master's SYNC task come at most this late. The master's own work each cycle is its "
        "SYNC task (sync: true on the SYNC producer): BCET/WCET, starting `offset` after SYNC; without one, none.",
    )


class SwitchPort(SpecModel):
    port: Int = Field(ge=1, le=1024)
    to: Name = Field(description="the node or switch on the other end of the cable")
    cable: Float = Field(0.0, ge=0, le=100_000, description="cable length in metres (Tprop at 0.7 c)")
    queue: Int | None = Field(
        None,
        ge=1,
        le=1_000_000,
        description="frames the port's egress queue holds, counting the one being sent (default: the switch's "
        "queue); a frame that finds it full is dropped, and `check` refuses a spec that can fill it",
    )


class Switch(SpecModel):
    name: Name
    ports: list[SwitchPort] = Field(min_length=1)
    latency: DurationField = Field(
        default_factory=lambda: _ns(0),
        description="store-and-forward multiplexing delay Tmux after a frame is fully received",
    )
    queue: Int | None = Field(
        None,
        ge=1,
        le=1_000_000,
        description="frames each of its ports' egress queues holds, counting the one being sent, unless the port "
        "says (default 64, as the simulator's)",
    )


class EthernetParams(SpecModel):
    switches: list[Switch] = Field(default_factory=list)


class ErrorModel(SpecModel):
    """Bit errors the CAN analysis allows for: the sporadic model of Tindell and Burns (1994) and Punnekkat,
    Hansson and Norstrom (2000). Each error costs an error frame and the retransmission of the frame it hit."""

    burst: Int = Field(
        0, ge=0, le=10_000, description="n: errors that may come together at any moment (default 0: none at once)"
    )
    interval: DurationField = Field(description="T_err: besides the burst, at most one error per interval")
    ber: Float = Field(
        1e-6,
        gt=0,
        lt=1,
        description="the bit error rate of the bus's environment, against which the report rates the model: the "
        "probability per hour that more errors come than the model allows (default 1e-6, pessimistic for a "
        "shielded, well-terminated cable; set it to what your environment measures)",
    )


class Bus(SpecModel):
    name: Name
    protocol: Literal["can", "can-fd", "canopen", "ftt-can", "ethernet-udp", "ethercat"]
    link: Literal["can", "can-fd", "ethernet", "ethercat"] | None = Field(
        None,
        description="the physical bus the protocol runs over, where it differs from the protocol's own (can, can-fd, "
        "ethernet, ethercat; default: can for can, canopen and ftt-can, can-fd for can-fd, ethernet for ethernet-udp, "
        "ethercat for ethercat). `protocol: can` with `link: can-fd` is the can-fd protocol; canopen (CANopen "
        "FD) and ftt-can run over can-fd too",
    )
    bitrate: BitRateField = Field(description="bit rate, or link speed for Ethernet; on CAN FD the arbitration rate")
    data_bitrate: BitRateField | None = Field(
        None, description="CAN FD: the data-phase bit rate of frames sent with bit-rate switch (brs)"
    )
    id_bits: Literal[11, 29] = Field(11, description="default identifier length on CAN buses")
    clock_tolerance: Int = Field(
        100,
        ge=0,
        le=10_000,
        description="CAN buses: how far, in ppm, each sender's clock may run from nominal (a crystal: 50-100 ppm). "
        "The response-time analysis counts other messages' releases at the fastest clocks this allows; 0 assumes "
        "perfect clocks",
    )
    ftt: FttParams | None = None
    canopen: CanopenParams | None = None
    ethernet: EthernetParams | None = None
    ethercat: EthercatParams | None = None
    errors: ErrorModel | None = Field(
        None,
        description="CAN buses: the bit errors the response-time analysis allows for (burst, interval). Default: "
        "none, and every report says that its bounds then assume an error-free bus",
    )
    description: str | None = None
    import_: str | None = Field(
        None,
        alias="import",
        description="a DBC file (path relative to the spec) whose nodes and messages join this CAN bus; a spec "
        "message of the same name adds to or overrides the DBC's (e.g. a deadline), the bus's bitrate wins",
    )

    @model_validator(mode="before")
    @classmethod
    def _default_rate(cls, data: object) -> object:
        """A protocol whose link has a standard rate gets it when the spec gives none (DEFAULT_BITRATES)."""
        if isinstance(data, dict) and "bitrate" not in data and data.get("protocol") in DEFAULT_BITRATES:
            return {**data, "bitrate": DEFAULT_BITRATES[data["protocol"]]}
        return data


class Task(SpecModel):
    name: Name
    period: DurationField | None = Field(None, description="activation period (omit when a trigger activates it)")
    offset: DurationField = Field(default_factory=lambda: _ns(0))
    on_message: Name | None = Field(None, description="event-driven: the task runs when this message arrives")
    sync: Bool | Name = Field(
        False,
        description="the task runs on its bus's cycle, `offset` after each start: every SYNC of its CANopen bus; "
        "on an EtherCAT bus, the master's every cycle, a DC slave's every SYNC0 (`true`: its node's one bus with a "
        "cycle; a bus name where it has several)",
    )
    wcet: DurationField = Field(description="worst-case execution time")
    bcet: DurationField | None = Field(None, description="best-case execution time (default: the WCET)")
    priority: Int | None = Field(
        None,
        ge=0,
        description="priority on its node's processor, 0 the highest (default: rate-monotonic, the shortest "
        "activation interval first, ties in list order; tasks with a priority go before those without)",
    )
    description: str | None = None


class EdsDevice(SpecModel):
    eds: str = Field(description="path of a vendor EDS file, relative to the spec")


# CiA 301's basic data types a PDO can carry (7.1.4.1, table 44 ordering)
ObjectType = Literal[
    "BOOLEAN", "INTEGER8", "INTEGER16", "INTEGER24", "INTEGER32", "INTEGER40", "INTEGER48", "INTEGER56", "INTEGER64",
    "UNSIGNED8", "UNSIGNED16", "UNSIGNED24", "UNSIGNED32", "UNSIGNED40", "UNSIGNED48", "UNSIGNED56", "UNSIGNED64",
    "REAL32", "REAL64",
]


class DeviceObject(SpecModel):
    """An application object of a device without a vendor file (CiA 301 7.4.1: 0x2000-0x5FFF manufacturer-specific,
    0x6000-0x9FFF a device profile's)."""

    index: Int = Field(ge=0x2000, le=0x9FFF, description="object index, 0x2000..0x9FFF")
    sub: Int = Field(0, ge=0, le=0xFE, description="sub-index")
    name: str = Field(min_length=1, max_length=120, description="parameter name, as an EDS writes it")
    type: ObjectType = Field(description="CiA 301 data type")
    access: Literal["ro", "wo", "rw", "rwr", "rww", "const"] = Field(
        description="CiA 306 access type: ro/const read-only (TPDO), wo/rww written (RPDO), rw/rwr both"
    )
    pdo: Bool = Field(True, description="whether a PDO may map it")
    default: Int | None = Field(None, description="default value")


class ProfileDevice(SpecModel):
    """A built-in profile and the device's own objects: a device without a vendor EDS (a BMS on the generic
    'cia301', a drive on 'cia402')."""

    profile: Name = Field(description="the built-in profile it extends: cia301, cia402, epos4")
    objects: list[DeviceObject] = Field(default_factory=list, description="the application objects it adds")


class ActuatorDevice(SpecModel):
    actuator: str = Field(
        min_length=1,
        description="path of an actuator profile file (docs/how-to/actuator-profile.md), relative to the spec",
    )


# an actuator profile's name, as its file's `profile:` says it: lower-case words joined by '-' (no spec Name has one)
ActuatorName = Annotated[str, Field(pattern=r"^[a-z0-9][a-z0-9._-]*-[a-z0-9._-]*$")]


def _device_form(value: object) -> str:
    """Which of the forms a `device:` is, from its shape: one form's errors, not all of them."""
    if isinstance(value, dict):
        if "actuator" in value:
            return "ActuatorDevice"
        return "ProfileDevice" if "profile" in value else "EdsDevice"
    if isinstance(value, (EdsDevice, ProfileDevice, ActuatorDevice)):
        return type(value).__name__
    if isinstance(value, str) and "-" in value:
        return "ActuatorName"
    return "Name"


# tags are the classes' names: the error locations drop them as they drop pydantic's own union branches
DeviceField = Annotated[
    Annotated[Name, Tag("Name")]
    | Annotated[EdsDevice, Tag("EdsDevice")]
    | Annotated[ProfileDevice, Tag("ProfileDevice")]
    | Annotated[ActuatorName, Tag("ActuatorName")]
    | Annotated[ActuatorDevice, Tag("ActuatorDevice")],
    Discriminator(_device_form),
]


class ActuatorCommand(SpecModel):
    """A command of the actuator's profile that the host sends at a rate (its reply, if the profile gives one,
    follows each)."""

    message: Name = Field(description="the profile's message (from: host), e.g. mit_command")
    period: DurationField | None = None
    rate: FrequencyField | None = Field(None, description="alternative to period: commands per second")
    reply_delay: tuple[DurationField, DurationField] | None = Field(
        None,
        description="[shortest, longest] time from the command's end on the bus to the device's reply, as measured "
        "on your devices (default: the profile's delay range, which says whether it is published or assumed)",
    )
    description: str | None = None


class ActuatorCyclic(SpecModel):
    """A message the actuator sends on its own, at the rate its profile's parameter sets."""

    message: Name = Field(description="the profile's cyclic message (from: device), e.g. heartbeat")
    period: DurationField | None = None
    rate: FrequencyField | None = Field(None, description="alternative to period: messages per second")


class Actuator(SpecModel):
    """How an actuator with its own CAN protocol (`device:` an actuator profile) is set up and driven."""

    parameters: dict[Name, Float] = Field(
        default_factory=dict,
        description="the profile's parameters this actuator sets (e.g. master_id, p_max); node_id is the node's",
    )
    commands: list[ActuatorCommand] = Field(default_factory=list, description="what the host sends, at which rates")
    cyclic: list[ActuatorCyclic] = Field(
        default_factory=list,
        description="rates of the messages the device sends on its own (default: the profile's parameter defaults)",
    )
    commanded_by: Name | None = Field(None, description="the node that sends the commands (default: the bus's master)")


class TxQueue(SpecModel):
    """How a node hands its frames to the CAN controller."""

    policy: Literal["priority", "fifo"] = Field(
        "priority",
        description="priority: the highest-priority pending frame always enters arbitration next (the classical "
        "analysis's assumption: a controller with enough mailboxes); fifo: frames go in the order they were "
        "queued (a Linux master's SocketCAN queue, a controller's FIFO mailbox)",
    )
    depth: Int = Field(
        10, ge=1, le=1_000_000, description="frames the FIFO holds (SocketCAN's default txqueuelen is 10)"
    )
    on_full: Literal["block", "drop"] = Field(
        "block",
        description="what a send into a full FIFO does: block the sending task until a slot frees (a task that "
        "writes a socket), or drop the frame (counted)",
    )

    @model_validator(mode="after")
    def _fifo_fields_need_a_fifo(self) -> TxQueue:
        given = sorted(self.model_fields_set & {"depth", "on_full"})
        if self.policy == "priority" and given:
            raise ValueError(f"{' and '.join(given)} describe a FIFO queue: add 'policy: fifo' (default: priority)")
        return self


class Node(SpecModel):
    name: Name
    node_id: Int | None = Field(None, description="CANopen node id 1..127, or an FTT-CAN/CAN station number")
    buses: list[Name] = Field(min_length=1)
    role: Literal["master", "slave"] = "slave"
    device: DeviceField | None = Field(
        None,
        description="CANopen device profile: a built-in name ('epos4', the generic 'cia301' and 'cia402'), "
        "{eds: file.eds}, or {profile: cia301, objects: [...]} for a device without a vendor file",
    )
    actuator: Actuator | None = Field(
        None,
        description="an actuator profile's node (device: cubemars-ak80-9-mit ...): its parameters, commands, rates",
    )
    heartbeat: DurationField | None = Field(None, description="CANopen producer heartbeat time (0x1017)")
    heartbeat_timeout: DurationField | None = Field(
        None,
        description="CANopen: how long the master waits for this node's heartbeat before it reports the node lost "
        "(its consumer heartbeat time, 0x1016); default 3 x the producer time, as Lely's dcfgen (heartbeat_multiplier)",
    )
    on_loss: Literal["stop_all", "stop_node", "continue"] = Field(
        "stop_all",
        description="`netcfg run`: what the master does when this node's heartbeat stops (an actuator: when it has "
        "sent nothing for 3 periods of its slowest message): bring every drive to its safe state and end the run, "
        "stop only this node, or report it and carry on (an actuator: hold, commanded as before)",
    )
    on_emcy: Literal["stop_all", "stop_node", "continue"] = Field(
        "stop_all",
        description="`netcfg run`: what the master does when this node sends an emergency (EMCY), or an actuator's "
        "frame reports an error (its profile's error fields, or an error value of a state field)",
    )
    on_reboot: Literal["recover", "stop_node", "stop_all"] = Field(
        "stop_node",
        description="`netcfg run`: what the master does when this node sends a boot-up message while running (it "
        "rebooted and lost its configuration): set it up again and enable it, leave it stopped, or stop every drive",
    )
    sdo_timeout: DurationField | None = Field(
        None, description="`netcfg run`: how long the master waits for each SDO answer of this node (default 500 ms)"
    )
    sdo_retries: Int = Field(
        0, ge=0, le=10, description="`netcfg run`: how often the master repeats an SDO request that got no answer"
    )
    safe_stop: Literal["quick_stop", "disable_operation"] = Field(
        "quick_stop",
        description="CiA 402 drive: the command that brings it to a safe state when a run ends or fails "
        "(controlword 0x6040: quick stop, or disable operation)",
    )
    ip: str | None = Field(None, pattern=r"^\d{1,3}(\.\d{1,3}){3}$")
    tx_delay: DurationField | None = Field(
        None,
        description="sender processing: Ethernet Tpre (seed 001, eq. 6.3); on CAN, from a sending task's end (a "
        "drive's SYNC reception) to its frame's release",
    )
    rx_delay: DurationField | None = Field(
        None,
        description="receiver processing: Ethernet Tpost; on CAN, from a frame's reception to the start of the tasks "
        "it starts (its message, trigger message or SYNC)",
    )
    nic_queue: Int | None = Field(
        None,
        ge=1,
        le=1_000_000,
        description="Ethernet: frames the node's network interface queues for sending, counting the one being "
        "sent (default 64, as the simulator's); a frame that finds it full is dropped, and `check` refuses a spec "
        "that can fill it",
    )
    tasks: list[Task] = Field(default_factory=list)
    scheduling: Literal["preemptive", "non-preemptive"] = Field(
        "preemptive",
        description="how the node's processor runs its tasks: fixed-priority preemptive (default) or "
        "fixed-priority non-preemptive; the analysis bounds each task's response time under it",
    )
    id_range: tuple[Int, Int] | None = Field(
        None, description="CAN: [lowest, highest] identifier this node may send with; `netcfg tune` stays inside it"
    )
    # the word form is read as the mapping's policy, so a mistake gets the mapping's message alone, not one per form
    tx_queue: Annotated[
        TxQueue,
        BeforeValidator(
            lambda v: {"policy": v} if isinstance(v, str) else v,
            json_schema_input_type=Literal["priority", "fifo"] | TxQueue,
        ),
    ] = Field(
        default_factory=lambda: TxQueue.model_validate({}),
        description="CAN: the node's transmit queue: priority (default) or fifo (depth 10, on_full: block), or "
        "{policy, depth, on_full}",
    )
    description: str | None = None


class Mux(SpecModel):
    signal: Name = Field(description="the multiplexer signal of the same message")
    values: list[Int] = Field(min_length=1, description="its raw values for which this signal is present")


class Pins(SpecModel):
    """What `netcfg tune` must leave as written (default: it may change both)."""

    id: Literal["fixed", "free"] = "free"
    offset: Literal["fixed", "free"] = "free"


class Signal(SpecModel):
    name: Name
    bits: Int = Field(ge=1, le=64)
    start_bit: Int | None = Field(
        None,
        ge=0,
        le=511,
        description="little-endian: position of its least significant bit, default right after the previous "
        "signal; big-endian: position of its most significant bit (DBC numbering: bit k is bit k % 8 of byte "
        "k // 8), required",
    )
    byte_order: Literal["little_endian", "big_endian"] = Field(
        "little_endian", description="little_endian (Intel, DBC @1) or big_endian (Motorola, DBC @0)"
    )
    mux: Mux | None = Field(None, description="multiplexed: present only when another signal holds given values")
    enum: dict[IntKey, str] | None = Field(None, description="value names by raw value (DBC VAL_); C enums")
    signed: Bool = False
    float: Bool = Field(False, description="IEEE 754 float (bits 32 or 64)")
    scale: Annotated[Float, AfterValidator(_non_zero)] = 1.0
    offset: Float = 0.0
    min: Float | None = None
    max: Float | None = None
    unit: str | None = None


class PdoEntry(SpecModel):
    object: ObjectRef
    name: Name | None = Field(None, description="signal name in generated code (default: from the object name)")


class Pdo(SpecModel):
    tpdo: Int | None = Field(None, ge=1, le=512, description="this is TPDO n of the producer")
    rpdo: Int | None = Field(None, ge=1, le=512, description="this is RPDO n of the (single) consumer")
    transmission: Int = Field(255, ge=0, le=255, description="transmission type (0x1800/0x1400 sub 2)")
    inhibit: DurationField | None = Field(None, description="inhibit time, stored in units of 100 us")
    event_timer: DurationField | None = Field(None, description="event timer, stored in ms")
    sync_start: Int | None = Field(None, ge=0, le=240, description="SYNC start value (0x1800 sub 6)")
    map: list[ObjectRef | PdoEntry] = Field(min_length=0, description="mapped objects, first byte first")

    @model_validator(mode="after")
    def _one_side(self) -> Pdo:
        if (self.tpdo is None) == (self.rpdo is None):
            raise ValueError("say which PDO this is with exactly one of 'tpdo: N' or 'rpdo: N'")
        return self


class Udp(SpecModel):
    src_port: Int = Field(ge=1, le=65535)
    dst_port: Int = Field(ge=1, le=65535)


class Message(SpecModel):
    name: Name
    bus: Name | None = Field(None, description="default: the one bus producer and consumers share")
    producer: Name
    consumers: list[Name] = Field(min_length=1)
    id: Int | None = Field(None, ge=0, description="CAN identifier, or the application message id on UDP")
    extended: Bool | None = Field(None, description="29-bit identifier (default: the bus's id_bits)")
    size: Int | None = Field(None, ge=0, description="payload bytes (or give signals / a PDO map)")
    fd: Bool | None = Field(
        None, description="CAN FD buses: an FD frame (up to 64 bytes; default) or, with false, a classical one"
    )
    brs: Bool | None = Field(
        None, description="CAN FD frames: bit-rate switch, the data phase at data_bitrate (default)"
    )
    signals: list[Signal] | None = None
    pdo: Pdo | None = None
    type: Literal["periodic", "sporadic", "on-demand"] | None = Field(
        None,
        description="periodic (period), sporadic (min_interarrival) or on-demand (start-up/mode changes only, "
        "not part of the steady-state load). Default: from the keys given",
    )
    period: DurationField | None = None
    rate: FrequencyField | None = Field(None, description="alternative to period: transmissions per second")
    period_range: tuple[DurationField, DurationField] | None = Field(
        None, description="FTT-CAN on-line rate adaptation: [fastest, slowest]; load uses the fastest"
    )
    offset: OffsetField | None = None
    min_interarrival: DurationField | None = None
    deadline: DurationField | None = Field(None, description="default: the period (or min_interarrival)")
    jitter: DurationField | None = Field(None, description="queuing jitter of the release")
    may_be_lost: Bool = Field(
        False,
        description="CAN: the system tolerates losing some of its frames: when its sender's FIFO transmit queue "
        "(on_full: drop) can be full as one is queued, it gets no bound (unbounded: dropped) instead of an error",
    )
    window: Literal["sync", "async"] | None = Field(None, description="FTT-CAN window (default: sync if periodic)")
    ftt_id: Int | None = Field(None, ge=0, description="FTT-CAN synchronous id (bit in the EC-schedule)")
    udp: Udp | None = None
    tune: Pins | None = Field(None, description="what `netcfg tune` keeps: {id: fixed} and/or {offset: fixed}")
    description: str | None = None


class Trigger(SpecModel):
    name: Name
    bus: Name
    ftt_id: Int = Field(ge=0)
    period: DurationField
    period_range: tuple[DurationField, DurationField] | None = None
    offset: OffsetField = Field(default_factory=lambda: _ns(0))
    tasks: list[TaskRef] = Field(min_length=1, description="tasks this trigger activates, as node.task")
    description: str | None = None


class Flow(SpecModel):
    name: Name
    chain: list[str | list[str]] = Field(
        min_length=2,
        description="steps from the first producer to the last consumer: node.task or message names; a list is "
        "several items in parallel (all their data is needed). Tasks on one node may follow each other",
    )
    deadline: DurationField | None = None
    description: str | None = None


class Spec(SpecModel):
    system: Name
    description: str | None = None
    buses: list[Bus] = Field(min_length=1)
    nodes: list[Node] = Field(min_length=1)
    messages: list[Message] = Field(default_factory=list)
    triggers: list[Trigger] = Field(default_factory=list)
    flows: list[Flow] = Field(default_factory=list)
    joints: list[Joint] = Field(
        default_factory=list, description="robot joints and the drive axes that move them (ros2_control)"
    )
