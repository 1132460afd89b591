"""Joints: the robot joints the spec binds to drive axes, checked against the network and scaled to SI units.

A joint names its drive (and axis), the signals that carry its command and state interfaces and its limits (a drive
whose process data is its bus's image, an EtherCAT slave, carries the interfaces of the CiA 402 objects it maps:
its protocol's joint_entries; the joint names no signals then). This
module checks each reference (the node, the message and its signal, the side of the message the drive is on), that
the limits fit the range the signal's bits can carry, and that no axis moves two joints; and it derives the factors
between the device's values and the joint's SI units from the gear ratio and the encoder's counts:

    position  rad    = counts * 2 pi / (encoder_counts * gear_ratio) + zero
    velocity  rad/s  = rpm * 2 pi / (60 * gear_ratio)                (velocity_unit rpm, at the motor)
                     = counts/s * 2 pi / (encoder_counts * gear_ratio)  (velocity_unit counts/s)
    effort    N m    = per mille * rated_torque * gear_ratio / 1000  (CiA 402 0x6077, of the motor's 0x6076)

A signal with a unit of its interface's quantity (an actuator profile's field: rev, rev/s, deg, rad, Nm, ...) is
scaled from that unit instead (netcfg.runtime.actuators.SI_UNITS), at the motor as the others are:

    position, velocity = value * SI factor / gear_ratio;  effort = value * SI factor * gear_ratio
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from netcfg import model, protocols
from netcfg.protocols.base import JointEntries
from netcfg.spec import schema
from netcfg.spec.source import Path
from netcfg.spec.suggest import did_you_mean

if TYPE_CHECKING:
    from netcfg.resolve.core import Resolver

INTERFACES = ("position", "velocity", "effort")


def resolve_joints(r: Resolver) -> None:
    seen: dict[str, int] = {}
    axes: dict[tuple[str, int], str] = {}
    for i, j in enumerate(r.spec.joints):
        path: Path = ("joints", i)
        if j.name in seen:
            first = seen[j.name]
            r.err("duplicate-name", f"joint '{j.name}' appears twice (first as joints[{first}])", (*path, "name"))
            continue
        seen[j.name] = i
        if j.node not in r.model.nodes:
            if j.node in r.spec_nodes:  # a node the spec has but could not resolve: its own error says why
                continue
            hint = did_you_mean(j.node, r.model.nodes)
            r.err("unknown-node", f"joint '{j.name}': there is no node '{j.node}'{hint}", (*path, "node"))
            continue
        other = axes.get((j.node, j.axis))
        if other is not None:
            r.err(
                "joint-axis",
                f"joint '{j.name}': axis {j.axis} of node '{j.node}' already moves joint '{other}'",
                r.key_or_item(path, "node") if "axis" not in j.model_fields_set else (*path, "axis"),
            )
            continue
        axes[(j.node, j.axis)] = j.name
        joint = _joint(r, j, path)
        if joint is not None:
            r.model.joints[j.name] = joint


def _joint(r: Resolver, j: schema.Joint, path: Path) -> model.Joint | None:
    named = any(getattr(side, name) for side in (j.command, j.state) for name in INTERFACES)
    sides: dict[str, dict[str, model.JointSignal]] = {"command": {}, "state": {}}
    image = None if named else _image_entries(r, j)
    if image is not None:  # a drive whose process data is its bus's image: the interfaces it maps
        bus, entries = image
        sides = _image_sides(j, bus, entries)
        if not any(sides.values()):
            r.err(
                "joint-interfaces",
                f"joint '{j.name}': node '{j.node}' maps no CiA 402 target or actual value whose scale the joint's "
                "figures give (position and counts/s velocity: encoder_counts; effort: rated_torque)",
                path,
            )
            return None
    elif not named:
        r.err("joint-interfaces", f"joint '{j.name}' names no command or state signal: give one", path)
        return None
    ok = True
    for side_name, side in (("command", j.command), ("state", j.state)):
        for interface in INTERFACES:
            ref = getattr(side, interface)
            if ref is None:
                continue
            spath: Path = (*path, side_name, interface)
            found = _signal(r, j, ref, side_name, spath)
            if found is None:
                ok = False
                continue
            factor = _unit_factor(r, j, interface, found, spath)
            if factor is None:
                factor = _factor(r, j, interface, path)
            if factor is None or factor == 0:
                ok = False
                continue
            lo, hi = _device_range(found)
            offset = j.zero if interface == "position" else 0.0
            sides[side_name][interface] = model.JointSignal(
                ref.partition(".")[0], found.name, factor, offset, lo * factor + offset, hi * factor + offset
            )
    buses = {c.bus or r.model.messages[c.message].bus for side in sides.values() for c in side.values()}
    if len(buses) > 1:  # one hardware block drives a joint: its signals travel one bus
        r.err("joint-bus", f"joint '{j.name}': its signals travel several buses ({', '.join(sorted(buses))})", path)
        ok = False
    limits = _limits(r, j, sides, path)
    if not ok or limits is None:
        return None
    plugin = r.model.nodes[j.node].ros2_control
    if plugin is not None and not plugin["applies_gear_ratio"] and j.gear_ratio != 1:
        r.warn("joint-gear", f"joint '{j.name}': {plugin['plugin']} applies no gear ratio (the device reports the "
               f"joint's side once its gearbox is configured), so its figures are the signals' times their unit "
               f"alone; with gear_ratio {j.gear_ratio:g} netcfg's differ: configure the gearbox on the device and "
               "give gear_ratio 1", r.key_or_item(path, "gear_ratio"))
    return model.Joint(
        j.name,
        j.node,
        j.axis,
        j.gear_ratio,
        j.encoder_counts,
        sides["command"],
        sides["state"],
        limits,
        path,
        j.description,
        j.velocity_unit,
        j.rated_torque,
        j.zero,
    )


def _image_entries(r: Resolver, j: schema.Joint) -> tuple[str, JointEntries] | None:
    """The entries that carry the joint's interfaces where its drive's bus has no messages for them (its protocol's
    joint_entries: an EtherCAT slave's mapped CiA 402 objects); None: the joint must name signals."""
    for name in r.model.nodes[j.node].buses:
        bus = r.model.buses.get(name)
        found = protocols.of(bus).joint_entries(bus, j.node, j.axis) if bus is not None else None
        if found is not None:
            return name, found
    return None


def _image_sides(j: schema.Joint, bus: str, entries: JointEntries) -> dict[str, dict[str, model.JointSignal]]:
    """Each mapped interface whose factor the joint's figures give, scaled as a signal's would be."""
    from netcfg.runtime.codec import int_range  # the runtime package only when a spec has joints

    out: dict[str, dict[str, model.JointSignal]] = {"command": {}, "state": {}}
    for side, found in entries.items():
        for interface, (pdo, entry, bits, signed) in found.items():
            factor = _scale(j, interface)
            if factor is None:
                continue
            lo, hi = int_range(bits, signed)
            offset = j.zero if interface == "position" else 0.0
            out[side][interface] = model.JointSignal(
                pdo, entry, factor, offset, lo * factor + offset, hi * factor + offset, bus
            )
    return out


def _scale(j: schema.Joint, interface: str) -> float | None:
    """The joint's SI value per device unit; None when a figure it needs is missing."""
    counts = j.encoder_counts
    if interface == "position" or (interface == "velocity" and j.velocity_unit == "counts/s"):
        return None if counts is None else 2 * math.pi / (counts * j.gear_ratio)
    if interface == "velocity":
        return 2 * math.pi / (60 * j.gear_ratio)
    return None if j.rated_torque is None else j.rated_torque * j.gear_ratio / 1000


_SI = {"position": "rad", "velocity": "rad/s", "effort": "Nm"}  # each interface's SI unit, as SI_UNITS names it


def _unit_factor(r: Resolver, j: schema.Joint, interface: str, s: model.Signal, path: Path) -> float | None:
    """The joint's SI value per unit of a signal that states its unit, 0 (reported) for a unit of another quantity;
    None: the signal states no unit the scaling knows (counts, per mille: _factor)."""
    from netcfg.runtime.actuators import SI_UNITS  # the runtime package only when a spec has joints

    known = SI_UNITS.get(s.unit or "")
    if known is None or known[0] == "1":
        return None
    si, per_unit = known
    if si != _SI[interface]:
        r.err("joint-signal", f"joint '{j.name}': its {interface} is in {_SI[interface]}, and signal '{s.name}' is in "
              f"{s.unit} ({si})", path)
        return 0
    return per_unit * j.gear_ratio if interface == "effort" else per_unit / j.gear_ratio


def _factor(r: Resolver, j: schema.Joint, interface: str, path: Path) -> float | None:
    """The joint's SI value per device unit, or None (reported) when a figure it needs is missing."""
    factor = _scale(j, interface)
    if factor is not None:
        return factor
    if interface == "effort":
        r.err(
            "joint-scale",
            f"joint '{j.name}': its effort is in per mille of the motor's rated torque: give rated_torque (N m)",
            path,
        )
    else:
        r.err(
            "joint-scale",
            f"joint '{j.name}': its {interface} is in encoder counts: give encoder_counts (per motor revolution)",
            path,
        )
    return None


def _signal(r: Resolver, j: schema.Joint, ref: str, side: str, path: Path) -> model.Signal | None:
    name, _, signal = ref.partition(".")
    m = r.model.messages.get(name)
    if m is None and any(spec_m.name == name for spec_m in r.spec.messages):
        return None  # a message the spec has but could not resolve: its own error says why
    if m is None:
        hint = did_you_mean(name, r.model.messages)
        r.err("joint-signal", f"joint '{j.name}': there is no message '{name}'{hint}", path)
        return None
    if side == "command" and j.node not in m.consumers:
        r.err("joint-signal", f"joint '{j.name}': message '{name}' does not go to node '{j.node}'", path)
        return None
    if side == "state" and m.producer != j.node:
        r.err("joint-signal", f"joint '{j.name}': message '{name}' is not sent by node '{j.node}'", path)
        return None
    for s in m.signals:
        if s.name == signal:
            return s
    carried = ", ".join(s.name for s in m.signals) or "none"
    r.err(
        "joint-signal",
        f"joint '{j.name}': node '{j.node}' does not map '{signal}' into message '{name}' (it carries: {carried})",
        path,
    )
    return None


def _device_range(s: model.Signal) -> tuple[float, float]:
    """The device values the signal's bits can carry (its own scale and offset applied)."""
    from netcfg.runtime.codec import int_range  # the runtime package only when a spec has joints

    if s.is_float:
        return -math.inf, math.inf
    lo, hi = int_range(s.bits, s.signed)
    ends = sorted((lo * s.scale + s.offset, hi * s.scale + s.offset))
    return ends[0], ends[1]


def _carrier(c: model.JointSignal) -> str:
    return f"{c.signal} of PDO {c.message}" if c.bus else f"signal {c.message}.{c.signal}"


def _limits(
    r: Resolver, j: schema.Joint, sides: dict[str, dict[str, model.JointSignal]], path: Path
) -> dict[str, tuple[float, float]] | None:
    out: dict[str, tuple[float, float]] = {}
    ok = True
    for interface in INTERFACES:
        given = getattr(j.limits, interface)
        if given is None:
            continue
        lpath: Path = (*path, "limits", interface)
        if isinstance(given, tuple):
            lo, hi = given
            if lo > hi:
                r.err("joint-limits", f"joint '{j.name}': lowest position {lo} is above highest {hi}", lpath)
                ok = False
                continue
        else:
            lo, hi = -given, given
        for side in ("command", "state"):
            carrier = sides[side].get(interface)
            if carrier is None:
                continue
            if lo < carrier.lowest or hi > carrier.highest:
                r.err(
                    "joint-limits",
                    f"joint '{j.name}': {interface} limits {_num(lo)}..{_num(hi)} do not fit "
                    f"{_carrier(carrier)}, which carries {_num(carrier.lowest)}..{_num(carrier.highest)}"
                    f" {_UNITS[interface]} at this scaling",
                    lpath,
                )
                ok = False
                break
        out[interface] = (lo, hi)
    return out if ok else None


_UNITS = {"position": "rad", "velocity": "rad/s", "effort": "N m"}


def _num(value: float) -> str:
    return f"{value:.6g}"
