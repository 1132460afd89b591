"""The spec language's robot joints: the drive axis that moves each, its gear, encoder and limits, and the
signals of its ros2_control interfaces."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from netcfg.spec.schema_types import Float, Int, Name, SpecModel

# "message.signal": a signal of a message, as a joint names the PDO entries that carry its interfaces
SignalRef = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*\.[A-Za-z][A-Za-z0-9_]*$")]



class JointSignals(SpecModel):
    """The signals that carry a joint's interfaces, as message.signal (a PDO entry's signal name); the interfaces
    named here are the ones the joint offers to ros2_control."""

    position: SignalRef | None = Field(None, description="position, in the device's counts (encoder increments)")
    velocity: SignalRef | None = Field(None, description="velocity, in the device's velocity unit (velocity_unit)")
    effort: SignalRef | None = Field(None, description="torque, in per mille of the motor's rated torque (CiA 402)")



class JointLimits(SpecModel):
    position: tuple[Float, Float] | None = Field(None, description="[lowest, highest] joint position, rad")
    velocity: Float | None = Field(None, gt=0, description="highest joint speed, rad/s")
    effort: Float | None = Field(None, gt=0, description="highest joint torque, N m")



class Joint(SpecModel):
    """A robot joint and the drive axis that moves it: what ros2_control's description of the robot needs and the
    scaling between the joint's SI units and the device's."""

    name: Name = Field(description="the joint's name in the robot's URDF")
    node: Name = Field(description="the drive that moves it")
    axis: Int = Field(1, ge=1, le=8, description="the drive's axis, for multi-axis drives (CiA 402: 1..8)")
    gear_ratio: Float = Field(1.0, gt=0, description="motor revolutions per joint revolution")
    encoder_counts: Int | None = Field(
        None,
        ge=1,
        le=1 << 31,
        description="position counts per motor revolution (a quadrature encoder: 4 x its pulses); required when "
        "a position signal is given",
    )
    velocity_unit: Literal["rpm", "counts/s"] = Field(
        "rpm", description="the velocity signal's unit at the motor: rpm (the EPOS4's default, 0x60A9) or counts/s"
    )
    rated_torque: Float | None = Field(
        None, gt=0, description="the motor's rated torque in N m (0x6076), required when an effort signal is given"
    )
    zero: Float = Field(0.0, description="the joint position, rad, at which the device's position reads 0")
    command: JointSignals = Field(
        default_factory=lambda: JointSignals.model_validate({}), description="command interfaces and their signals"
    )
    state: JointSignals = Field(
        default_factory=lambda: JointSignals.model_validate({}), description="state interfaces and their signals"
    )
    limits: JointLimits = Field(default_factory=lambda: JointLimits.model_validate({}))
    description: str | None = None
