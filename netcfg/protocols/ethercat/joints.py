"""A robot joint on an EtherCAT drive: the CiA 402 objects its slave maps carry the joint's interfaces, so a joint
names no signals (a segment's process data is its image, not messages). Axis n of a multi-axis drive has its
objects 0x800 * (n - 1) above the first axis' (CiA 402 part 2, "multiple logical devices")."""

from __future__ import annotations

from netcfg import model
from netcfg.protocols.base import JointEntries
from netcfg.protocols.ethercat.segment import AssignedPdo, Segment

# CiA 402's objects for the joint interfaces ros2_control knows: the targets the master writes, the actual values
# it reads (target position 0x607A, target velocity 0x60FF, target torque 0x6071; position actual value 0x6064,
# velocity actual value 0x606C, torque actual value 0x6077)
COMMAND = {0x607A: "position", 0x60FF: "velocity", 0x6071: "effort"}
STATE = {0x6064: "position", 0x606C: "velocity", 0x6077: "effort"}
AXIS_STEP = 0x800
# ethercat_driver_ros2's URDF entries: its hardware plugin, the CiA 402 drive plugin of each joint's <ec_module>,
# and the mode of operation (CiA 402's 0x6060) the drive runs for the joint's command: cyclic synchronous position
# 8, velocity 9, torque 10 (the driver's example configurations name the same numbers)
DRIVER_PLUGIN = "ethercat_driver/EthercatDriver"
DRIVE_PLUGIN = "ethercat_generic_plugins/EcCiA402Drive"
MODES = {"position": 8, "velocity": 9, "effort": 10}
SIGNED = {"SINT", "INT", "DINT", "LINT", "INTEGER8", "INTEGER16", "INTEGER24", "INTEGER32", "INTEGER64"}


def joint_entries(bus: model.Bus, node: str, axis: int) -> JointEntries | None:
    seg: Segment | None = bus.ethercat
    slave = next((s for s in seg.slaves if s.node == node), None) if seg is not None else None
    if slave is None:
        return None
    base = AXIS_STEP * (axis - 1)
    return {"command": _found(slave.rx, COMMAND, base), "state": _found(slave.tx, STATE, base)}


def slave_position(bus: model.Bus, node: str) -> int | None:
    seg: Segment | None = bus.ethercat
    return next((s.position for s in seg.slaves if s.node == node), None) if seg is not None else None


def mode_of_operation(commands: tuple[str, ...] | list[str]) -> int | None:
    """The cyclic synchronous mode a joint's first command interface (position before velocity before effort)."""
    return next((MODES[i] for i in MODES if i in commands), None)


def _found(pdos: list[AssignedPdo], objects: dict[int, str], base: int) -> dict[str, tuple[str, str, int, bool]]:
    out: dict[str, tuple[str, str, int, bool]] = {}
    for p in pdos:
        for index, _sub, bits, name, data_type in p.entries:
            interface = objects.get(index - base)
            if interface is not None and interface not in out:
                out[interface] = (f"0x{p.index:04X}", name, bits, data_type.upper() in SIGNED)
    return out
