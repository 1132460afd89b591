"""An actuator profile's `ros2_control:` section: the vendor's own ros2_control hardware plugin for the actuator, as
its package documents it, so that netcfg writes that plugin's description for the joints the actuator moves
(netcfg.emit.ros2_control). A profile without one has no official plugin, and netcfg says so instead of naming one.

    ros2_control:
      plugin: odrive_ros2_control_plugin/ODriveHardwareInterface   # the pluginlib class name
      source: {document: ..., version: ...}                       # the package, its version and files read
      hardware: {can: interface}        # hardware parameter -> what it holds: interface (the CAN interface's name)
      joint: {node_id: node_id}         # joint parameter -> the profile parameter it holds
      applies_gear_ratio: false         # the plugin converts units only: the device reports the joint's side
      command: {velocity: set_input_vel.input_vel, ...}   # interface -> the profile message.field the plugin sends
      state: {position: get_encoder_estimates.pos_estimate, ...}   # ... and the one it reads

The plugin sends and reads those messages itself; what it reads must come on its own (a cyclic message), as a
plugin that never asks for it would otherwise wait forever.
"""

from __future__ import annotations

from typing import Any

from netcfg.spec.suggest import did_you_mean

KEYS = ("plugin", "source", "hardware", "joint", "applies_gear_ratio", "command", "state", "doc")
HARDWARE_VALUES = ("interface",)  # what a hardware parameter may hold
INTERFACES = ("position", "velocity", "effort")  # hardware_interface_type_values.hpp's HW_IF_*


def check_ros2_control(c: Any, data: Any, params: dict[str, Any], messages: list[dict[str, Any]]) -> dict[str, Any]:
    """The section, checked by the profile's checker `c` (actuator_profile._Checker): every name it uses is the
    profile's, every interface one of ros2_control's."""
    body = c.mapping(data, ("ros2_control",), "ros2_control") or {}
    c.keys(body, KEYS, ("ros2_control",), "ros2_control")
    out: dict[str, Any] = {"plugin": c.text(body.get("plugin"), ("ros2_control", "plugin"), "ros2_control plugin")}
    source = c.mapping(body.get("source", {}), ("ros2_control", "source"), "ros2_control source") or {}
    for k in ("document", "version"):
        if k not in source:
            c.err("profile-source", f"ros2_control source has no '{k}': name the plugin's package and its version",
                  ("ros2_control", "source") if "source" in body else ("ros2_control",))
    out["source"] = dict(source)
    hardware = c.mapping(body.get("hardware", {}), ("ros2_control", "hardware"), "ros2_control hardware") or {}
    for name, value in hardware.items():
        c.choice(value, HARDWARE_VALUES, ("ros2_control", "hardware", name), f"hardware parameter {name}")
    out["hardware"] = [[str(k), v] for k, v in hardware.items()]
    joint = c.mapping(body.get("joint", {}), ("ros2_control", "joint"), "ros2_control joint") or {}
    for name, value in joint.items():
        if value not in params:
            c.err("profile-ros2", f"joint parameter {name}: {value!r} is not a parameter of the profile"
                  f"{did_you_mean(str(value), params)}", ("ros2_control", "joint", name))
    out["joint"] = [[str(k), v] for k, v in joint.items()]
    gear = body.get("applies_gear_ratio", True)
    out["applies_gear_ratio"] = c.choice(gear, (True, False), ("ros2_control", "applies_gear_ratio"),
                                         "applies_gear_ratio")
    fields = {(m["name"], f["name"]): m["from"] for m in messages for f in m.get("fields") or ()}
    for side, sender in (("command", "host"), ("state", "device")):
        table = c.mapping(body.get(side, {}), ("ros2_control", side), f"ros2_control {side}") or {}
        out[side] = {}
        for interface, ref in table.items():
            where = ("ros2_control", side, interface)
            if interface not in INTERFACES:
                c.err("profile-ros2", f"{side} interface {interface!r} is none of {', '.join(INTERFACES)}", where,
                      key=True)
                continue
            message, _, field = str(ref).partition(".")
            if fields.get((message, field)) != sender:
                c.err("profile-ros2", f"{side} {interface}: {ref!r} is no field of a message the "
                      f"{'host' if sender == 'host' else 'device'} sends (message.field)", where)
                continue
            out[side][interface] = [message, field]
    return out
