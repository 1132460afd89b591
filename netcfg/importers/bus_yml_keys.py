"""bus.yml's vocabulary for the importer (netcfg.importers.bus_yml) and the bus.yml emitter: the keys each
section may hold, dcfgen's COB-ID range for 'auto', the timing a PDO gets without a `# netcfg:` note, names and
durations as the spec writes them, and the `# netcfg:` annotations."""

from __future__ import annotations

import math
import re

from netcfg import cia301
from netcfg.spec.names import is_name

BusPath = tuple[str | int, ...]
PLACEHOLDER = "@BUS_CONFIG_PATH@"
_PLACEHOLDER_ANY = re.compile(r"@[A-Za-z_][A-Za-z0-9_]*@")
_ANNOTATION = re.compile(r"#\s*netcfg:\s*(?P<body>.*?)\s*$")
NODE_ID_LIMITS = (cia301.NODE_IDS.start, cia301.NODE_IDS[-1])  # 1, 127
FIRST_AUTO_COB_ID = 0x680  # dcfgen: COB-IDs of 'auto' PDOs 5+ are taken from here upwards
LAST_AUTO_COB_ID = 0x6DF  # 0x6E0-0x6FF are restricted (CiA 301 table 74)

OPTIONS_KEYS = {"dcf_path", "heartbeat_multiplier"}
# Lely dcfgen keys (dcfgen/cli.py, ros2_canopen's master table): mapped, or kept as comments (no bus traffic)
MASTER_MAPPED = {"node_id", "baudrate", "sync_period", "sync_window", "sync_overflow", "heartbeat_producer"}
MASTER_KEPT = frozenset(
    (
        "vendor_id product_code revision_number serial_number heartbeat_multiplier heartbeat_consumer "
        "emcy_inhibit_time error_behavior nmt_inhibit_time start start_nodes start_all_nodes reset_all_nodes "
        "stop_all_nodes boot_time"
    ).split()
)
SLAVE_MAPPED = {"dcf", "node_id", "heartbeat_producer", "heartbeat_multiplier", "rpdo", "tpdo", "sdo"}
SLAVE_KEPT = frozenset(
    (
        "dcf_path revision_number serial_number heartbeat_consumer error_behavior boot "
        "mandatory reset_communication software_file software_version configuration_file "
        "restore_configuration"
    ).split()
)
# ros2_canopen's driver parameters (its user guide and the keys its drivers read): not part of the network
ROS_KEYS = frozenset(
    (
        "driver package enable_lazy_load namespace remappings period polling diagnostics sdo_timeout_ms "
        "boot_timeout_ms boot_timeout non_transmit_timeout switching_state homing_timeout_seconds "
        "position_mode velocity_mode torque_mode effort_mode num_channels channel_names channels "
        "scale_pos_to_dev scale_pos_from_dev scale_vel_to_dev scale_vel_from_dev scale_eff_from_dev "
        "offset_pos_to_dev offset_pos_from_dev"
    ).split()
)
# what a drive that moves a spec joint says in the bus.yml: ros2_canopen's CiA 402 driver and its scaling, all derived
# from the joint (its `# netcfg-spec:` line), so read against it rather than kept
JOINT_KEYS = frozenset(
    (
        "driver package scale_pos_to_dev scale_pos_from_dev scale_vel_to_dev scale_vel_from_dev scale_eff_from_dev "
        "offset_pos_to_dev offset_pos_from_dev"
    ).split()
)


def ros2_canopen_scaling(
    gear_ratio: float, encoder_counts: int | None, velocity_unit: str, rated_torque: float | None, zero: float
) -> dict[str, float]:
    """ros2_canopen's scaling keys of a joint's drive, in the order the bus.yml writes them (netcfg.emit.joint_scaling
    says what each means): position once the encoder's counts are known, velocity always, effort with a rated
    torque."""
    out: dict[str, float] = {}
    counts = encoder_counts * gear_ratio if encoder_counts is not None else None
    if counts is not None:
        to_dev = counts / (2 * math.pi)
        out["scale_pos_to_dev"] = to_dev
        out["scale_pos_from_dev"] = 2 * math.pi / counts
        out["offset_pos_to_dev"] = -zero * to_dev + 0.0  # + 0.0: no -0.0 for a zero of 0
        out["offset_pos_from_dev"] = zero
    if velocity_unit == "rpm":
        out["scale_vel_to_dev"] = 60 * gear_ratio / (2 * math.pi)
        out["scale_vel_from_dev"] = 2 * math.pi / (60 * gear_ratio)
    elif counts is not None:
        out["scale_vel_to_dev"] = counts / (2 * math.pi)
        out["scale_vel_from_dev"] = 2 * math.pi / counts
    if rated_torque is not None:
        out["scale_eff_from_dev"] = rated_torque * gear_ratio / 1000
    return out


PDO_KEYS = frozenset("enabled cob_id transmission inhibit_time event_timer event_deadline sync_start mapping".split())
MAPPING_KEYS = {"index", "sub_index"}
SDO_KEYS = {"index", "sub_index", "value"}
HEADER_KEYS = {"system", "bus", "master", "read_window_ns", "sync_id", "sync_producer"}
PDO_NOTE_KEYS = {"message", "type", "period_ns", "min_interarrival_ns"}


def default_timing(
    kind: str, transmission: int, event_timer_ms: int | None, inhibit_100us: int | None, sync_ns: int
) -> tuple[str, int | None, int | None]:
    """(kind, period_ns, interval_ns) this importer gives a PDO without a `# netcfg:` note; the bus.yml emitter writes
    a note only where the model differs. TPDOs follow the one rule for transmission types (cia301.tpdo_timing)."""
    if kind == "tpdo":
        tpdo_kind, period, mit = cia301.tpdo_timing(transmission, sync_ns, event_timer_ms, inhibit_100us)
        if tpdo_kind == "periodic":
            return "periodic", period, period
        return ("sporadic", None, mit) if mit else ("on-demand", None, None)
    if 1 <= transmission <= 240:
        return "periodic", transmission * sync_ns, transmission * sync_ns
    if transmission == 0:
        return "sporadic", None, sync_ns
    period = event_timer_ms * 1_000_000 if event_timer_ms else sync_ns
    return "periodic", period, period


def safe_name(text: str, fallback: str) -> str:
    """A netcfg name from a file or bus.yml name: other characters become '_', a leading digit or a reserved word
    gets the fallback as prefix."""
    name = re.sub(r"[^A-Za-z0-9_]+", "_", text).strip("_")[:63]
    for candidate in (name, f"{fallback}_{name}"[:63]):
        if is_name(candidate):
            return candidate
    return fallback


def duration(us: int) -> str:
    """A spec duration: whole milliseconds as ms, else microseconds."""
    return f"{us // 1000} ms" if us % 1000 == 0 else f"{us} us"


def duration_ns(ns: int) -> str:
    """A spec duration from nanoseconds (`# netcfg:` notes keep them exact)."""
    return duration(ns // 1000) if ns % 1000 == 0 else f"{ns} ns"


def parse_annotation(line: str) -> dict[str, str]:
    """`key=value` words of a `# netcfg: ...` comment on a line (empty when there is none)."""
    m = _ANNOTATION.search(line)
    if m is None:
        return {}
    out = {}
    for word in m.group("body").split():
        key, sep, value = word.partition("=")
        if sep:
            out[key] = value
    return out
