"""ethercat/<bus>/<node>.yaml: each slave's configuration for ICube's ethercat_driver_ros2 (its GenericEcSlave and
EcCiA402Drive plugins read it): vendor_id, product_id, assign_activate, the start-up sdo list, the rpdo/tpdo
channels with their ros2_control command and state interfaces (and, on a joint's channels, the factor and offset
between the device's units and the joint's), and the sync managers, with the field names of the driver's published
configurations (ethercat_driver/examples/configurations/*.yaml)."""

from __future__ import annotations

from typing import Any

from netcfg import model
from netcfg.protocols.ethercat.runtime_section import startup_sdos
from netcfg.protocols.ethercat.segment import AssignedPdo, segments
from netcfg.templating import render

# CiA 402 objects and the ros2_control interfaces EcCiA402Drive gives them (its documentation's names)
COMMANDS = {
    0x6040: "control_word",
    0x607A: "position",
    0x60FF: "velocity",
    0x6071: "effort",
    0x6060: "mode_of_operation",
}
STATES = {0x6041: "status_word", 0x6064: "position", 0x606C: "velocity", 0x6077: "effort", 0x6061: "mode_of_operation"}
# ETG.2000 and CiA 301 type names -> the driver's channel types
TYPES = {
    "BOOL": "bool",
    "BOOLEAN": "bool",
    "SINT": "int8",
    "INTEGER8": "int8",
    "INT": "int16",
    "INTEGER16": "int16",
    "DINT": "int32",
    "INTEGER32": "int32",
    "LINT": "int64",
    "INTEGER64": "int64",
    "USINT": "uint8",
    "UNSIGNED8": "uint8",
    "UINT": "uint16",
    "UNSIGNED16": "uint16",
    "UDINT": "uint32",
    "UNSIGNED32": "uint32",
    "ULINT": "uint64",
    "UNSIGNED64": "uint64",
    "REAL": "float",
    "REAL32": "float",
    "LREAL": "double",
    "REAL64": "double",
}
SDO_TYPES = {8: "uint8", 16: "uint16", 32: "uint32"}


def channel_type(index: int, bits: int, data_type: str) -> str:
    if index == 0:
        return f"bit{bits}"  # a gap in the PDO
    if data_type.upper() in TYPES:
        return TYPES[data_type.upper()]
    return f"uint{bits}" if bits in (8, 16, 32, 64) else f"bit{bits}"


Scaling = dict[tuple[str, str], tuple[float, float]]  # (PDO, entry name) -> (factor, offset)


def scaling(m: model.Model, bus: model.Bus, node: str) -> Scaling:
    """The channel factors of the node's joints, as the driver applies them (ethercat_interface's
    EcPdoChannelManager: a state interface = factor * the entry + offset; the entry written = factor * the command
    interface + offset): the joint's SI units per device unit on the state side, their inverse on the command
    side (netcfg.resolve.joints derives them from the gear ratio, the encoder's counts and the rated torque)."""
    out: Scaling = {}
    for j in m.joints.values():
        if j.node != node:
            continue
        for c in j.state.values():
            if c.bus == bus.name:
                out[(c.message, c.signal)] = (c.from_dev, c.offset)
        for c in j.command.values():
            if c.bus == bus.name:
                out[(c.message, c.signal)] = (1 / c.from_dev, -c.offset / c.from_dev + 0.0)  # + 0.0: no -0.0
    return out


def _pdos(pdos: list[AssignedPdo], interfaces: dict[int, str], key: str, scaled: Scaling) -> list[dict[str, Any]]:
    out = []
    for p in pdos:
        channels = []
        for index, sub, bits, name, data_type in p.entries:
            channel = f"index: 0x{index:04x}, sub_index: {sub}, type: {channel_type(index, bits, data_type)}"
            if index in interfaces:
                channel += f", {key}: {interfaces[index]}"
            if key == "command_interface" and index:
                channel += ", default: 0"
            factor = scaled.get((f"0x{p.index:04X}", name))
            if factor is not None:
                channel += f", factor: {factor[0]!r}" + (f", offset: {factor[1]!r}" if factor[1] else "")
            channels.append(channel)
        out.append({"index": f"0x{p.index:04x}", "channels": channels})
    return out


def emit(m: model.Model, report: dict[str, Any]) -> dict[str, bytes]:
    files = {}
    for bus, seg in segments(m):
        for s in seg.slaves:
            view = {
                "system": m.system,
                "bus": bus.name,
                "slave": s,
                "sdo": [
                    f"index: 0x{x['index']:04x}, sub_index: {x['sub']}, type: {SDO_TYPES[x['bits']]}, "
                    f"value: {x['value']}"
                    for x in startup_sdos(s)
                ],
                "rpdo": _pdos(s.rx, COMMANDS, "command_interface", scaled := scaling(m, bus, s.node)),
                "tpdo": _pdos(s.tx, STATES, "state_interface", scaled),
                "sm": [
                    {
                        "index": sm.number,
                        "type": "output" if sm.kind in ("MBoxOut", "Outputs") else "input",
                        "pdo": {"Outputs": "rpdo", "Inputs": "tpdo"}.get(sm.kind),
                    }
                    for sm in s.sync_managers
                ],
            }
            files[f"ethercat/{bus.name}/{s.node}.yaml"] = render("ethercat_slave.yaml.j2", **view)
    return files
