"""ros2_canopen's scaling of a drive that moves a joint: the bus.yml keys its CiA 402 driver reads
(canopen_402_driver's node_canopen_402_driver_impl.hpp: scale_pos_to_dev, scale_pos_from_dev, scale_vel_to_dev,
scale_vel_from_dev, scale_eff_from_dev, offset_pos_to_dev, offset_pos_from_dev). The driver computes

    joint position = device position * scale_pos_from_dev + offset_pos_from_dev
    device target  = joint target * scale_pos_to_dev + offset_pos_to_dev     (velocity: the scale alone)

and defaults to 1000 and 0.001 where a key is missing, so every key the joint's figures give is written: position
once its encoder counts are known, velocity always (rpm need only the gear), effort once its rated torque is.
The factors are netcfg.resolve.joints' (2 pi over the counts of one joint revolution, and so on), computed in
netcfg.importers.bus_yml_keys, which reads them back.
"""

from __future__ import annotations

from netcfg.importers.bus_yml_keys import ros2_canopen_scaling
from netcfg.model import Bus, Joint, Model

DRIVER = "ros2_canopen::Cia402Driver"  # the driver canopen_ros2_control/RobotSystem accepts for a joint
PACKAGE = "canopen_402_driver"


def scaling(j: Joint) -> tuple[tuple[str, float], ...]:
    """(key, value) in the order the bus.yml writes them."""
    return tuple(ros2_canopen_scaling(j.gear_ratio, j.encoder_counts, j.velocity_unit, j.rated_torque, j.zero).items())


def joint_bus(m: Model, j: Joint) -> Bus | None:
    """The bus a joint's drive is driven over: the one its command or state messages travel."""
    for carrier in (*j.command.values(), *j.state.values()):
        return m.buses[carrier.bus or m.messages[carrier.message].bus]
    return None


def bus_joints(m: Model, bus: Bus) -> dict[str, Joint]:
    """The joints driven over the bus, by their drive's name: axis 1 only, as a bus.yml scales a drive, not an axis."""
    return {j.node: j for j in m.joints.values() if j.axis == 1 and (b := joint_bus(m, j)) is not None and b is bus}
