"""ros2_control/: the robot's ros2_control description from the spec's joints, for systems that have joints.

- ros2_control/<system>.ros2_control.xacro (ros2_control.xacro.j2): one xacro macro, `<system>_ros2_control`,
  with one `<ros2_control type="system">` block per bus whose joints a published hardware plugin drives, and in it
  each joint with its command interfaces (their `min`/`max` from the joint's limits) and state interfaces. A robot's
  URDF includes the file and calls the macro (docs/how-to/ros2-control.md).
- ros2_control/controllers.yaml (ros2_controllers.yaml.j2): the controller manager's parameters: `update_rate`
  from the rate of the master's control task, a `joint_state_broadcaster`, and per bus one
  `forward_command_controller/ForwardCommandController` for each command interface its joints offer.

Names as the consumers publish them:
- CANopen: ros2_canopen's `canopen_ros2_control/RobotSystem` (canopen_ros2_control/src/robot_system.cpp): the
  hardware parameters `bus_config`, `master_config`, `can_interface_name` (required) and `master_bin` (optional;
  `""` for none), and per joint the parameter `device_name`, the slave's name in bus.yml, whose `driver` must be
  `ros2_canopen::Cia402Driver` (the bus.yml emitter writes it for every drive that moves a joint). Its docs
  (user-guide/operation/ros2-control-interface.rst) name the joint parameter `node_id`, which the code does not
  read: both are written, so the block works with either. RobotSystem drives each CiA 402 drive itself (it enables
  the drive on activation and switches its mode with the controllers), so a plain forward-command controller
  feeds it; ros2_canopen's Cia402DeviceController belongs to its other plugin, Cia402System, whose interfaces are
  per device, not per joint.
- ros2_control's hardware description (hardware_interface's component_parser, doc/hardware_interface_types):
  `<ros2_control name type>`, `<hardware><plugin>`, `<param name>`, `<joint name>`, `<command_interface name>`
  with `<param name="min">`/`"max"`, `<state_interface name>`; the interface names `position`, `velocity`,
  `effort` (hardware_interface_type_values.hpp).
- The controllers: ros2_controllers' `joint_state_broadcaster/JointStateBroadcaster` and
  `forward_command_controller/ForwardCommandController` with `joints` and `interface_name`; the controller
  manager's `update_rate` in Hz (an integer).

- EtherCAT: ICube's ethercat_driver_ros2, `ethercat_driver/EthercatDriver` with the hardware parameters `master_id`
  and `control_frequency` (Hz), and in each joint an `<ec_module name>` with the plugin
  `ethercat_generic_plugins/EcCiA402Drive` and the parameters `alias`, `position` (the slave's place on the line),
  `mode_of_operation` (CiA 402: 8 position, 9 velocity, 10 torque) and `slave_config`, the slave's YAML build writes
  (ethercat/<bus>/<node>.yaml), as the driver's example configurations (*.ros2_control.xacro) write them.

- An actuator bus: the vendor's own plugin for each joint's actuator, as the actuator's profile describes it (its
  `ros2_control:` section, netcfg.devices.actuator_ros2): ODrive's `odrive_ros2_control_plugin/ODriveHardwareInterface`
  (odrive_ros2_control 0.0.1) with the hardware parameter `can` (the SocketCAN interface, by default named as the
  bus) and per joint `node_id`. A joint goes in when its interfaces are the messages the plugin itself sends and
  reads, and what it reads comes on its own (a cyclic message: the plugin asks for nothing). An actuator whose
  profile names no plugin has none published (MIT-mode motors, RobStride, MyActuator, moteus): its joints are left
  out, and said so (unsaid(); build prints it), never given a made-up plugin.

Other protocols are an entry in HARDWARE: which buses it drives and a function from the bus to its `<hardware>` block. A
bus without one gets no block: its joints are named in a comment of the xacro file when another bus has one, and a
system with no such bus gets no ros2_control files.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

from netcfg import model
from netcfg.emit.bus_yml import bus_yml_name
from netcfg.emit.joint_scaling import joint_bus
from netcfg.templating import render

XACRO_TEMPLATE = "ros2_control.xacro.j2"
CONTROLLERS_TEMPLATE = "ros2_controllers.yaml.j2"


@dataclass(frozen=True)
class Param:
    name: str
    value: str


@dataclass(frozen=True)
class Interface:
    name: str
    limits: tuple[Param, ...] = ()


@dataclass(frozen=True)
class Module:
    """A device entry inside a joint (ethercat_driver_ros2's `<ec_module>`): its plugin and parameters."""

    name: str
    plugin: str
    params: tuple[Param, ...]


@dataclass(frozen=True)
class JointView:
    name: str
    params: tuple[Param, ...]
    command: tuple[Interface, ...]
    state: tuple[Interface, ...]
    modules: tuple[Module, ...] = ()


@dataclass(frozen=True)
class MacroArg:
    name: str
    default: str | None  # None: the caller must give it


@dataclass(frozen=True)
class Hardware:
    """One bus's `<ros2_control>` block: its plugin, its hardware parameters (as xacro expressions) and the
    macro's arguments they use, and the per-joint parameters."""

    plugin: str
    params: tuple[Param, ...]
    args: tuple[MacroArg, ...]
    joint_params: Callable[[model.Joint], tuple[Param, ...]]
    note: str = ""  # for the file's header: where the parameters' files come from
    joint_modules: Callable[[model.Joint], tuple[Module, ...]] = lambda _j: ()


@dataclass(frozen=True)
class BlockView:
    name: str
    plugin: str
    params: tuple[Param, ...]
    joints: tuple[JointView, ...]


def _canopen(m: model.Model, bus: model.Bus, several: bool) -> Hardware:
    """ros2_canopen's RobotSystem: the bus.yml, the master DCF dcfgen makes from it, the SocketCAN interface."""
    prefix = f"{bus.name}_" if several else ""
    names = ("bus_config", "master_config", "can_interface_name", "master_bin")
    defaults: dict[str, str | None] = {
        "bus_config": None,
        "master_config": None,
        "can_interface_name": bus.name,  # SocketCAN names the interface as the spec names the bus, by default
        "master_bin": "&quot;&quot;",  # RobotSystem reads "" (the two characters) as no master.bin
    }
    args = tuple(MacroArg(prefix + n, defaults[n]) for n in names)
    params = tuple(Param(n, "${" + prefix + n + "}") for n in names)

    def joint_params(j: model.Joint) -> tuple[Param, ...]:
        node = m.nodes[j.node]
        return (Param("device_name", j.node), Param("node_id", str(node.node_id)))

    note = (
        f"bus {bus.name}: bus_config is netcfg's {bus_yml_name(m, bus.name)}; master_config the master.dcf dcfgen "
        "writes from it"
    )
    return Hardware("canopen_ros2_control/RobotSystem", params, args, joint_params, note)


def _ethercat(m: model.Model, bus: model.Bus, several: bool) -> Hardware:
    """ethercat_driver_ros2's EthercatDriver: the master's index and the cycle's rate; each joint's drive an
    `<ec_module>` with the EcCiA402Drive plugin, its place on the line, its mode and the slave file build writes."""
    from netcfg.protocols.ethercat import joints as ec

    prefix = f"{bus.name}_" if several else ""
    args = (MacroArg(prefix + "master_id", "0"), MacroArg(prefix + "slave_config_dir", None))
    rate = max(1, round(1e9 / bus.ethercat.cycle_ns))
    params = (Param("master_id", "${" + prefix + "master_id}"), Param("control_frequency", str(rate)))

    def modules(j: model.Joint) -> tuple[Module, ...]:
        mode = ec.mode_of_operation(list(j.command))
        found = (
            Param("alias", "0"),
            Param("position", str(ec.slave_position(bus, j.node))),
            *((Param("mode_of_operation", str(mode)),) if mode is not None else ()),
            Param("slave_config", "${" + prefix + "slave_config_dir}/" + f"{j.node}.yaml"),
        )
        return (Module(j.node, ec.DRIVE_PLUGIN, found),)

    note = f"bus {bus.name}: slave_config_dir is the folder of netcfg's ethercat/{bus.name}/ (one YAML per slave)"
    return Hardware(ec.DRIVER_PLUGIN, params, args, lambda _j: (), note, modules)


MakeHardware = Callable[[model.Model, model.Bus, bool], Hardware]

# (which buses it drives, by their protocol's section of the bus; its block): EtherCAT and actuator buses add theirs
HARDWARE: tuple[tuple[Callable[[model.Bus], bool], MakeHardware], ...] = (
    (lambda bus: bus.canopen is not None, _canopen),
    (lambda bus: bus.ethercat is not None, _ethercat),
)


def hardware(bus: model.Bus) -> MakeHardware | None:
    return next((make for drives, make in HARDWARE if drives(bus)), None)


def _actuator(m: model.Model, bus: model.Bus, several: bool, plugin: dict[str, Any]) -> Hardware:
    """An actuator vendor's plugin, from the profile's ros2_control section: its hardware parameters (the CAN
    interface a macro argument, named as the bus by default) and each joint's (a parameter of its actuator)."""
    prefix = f"{bus.name}_" if several else ""
    hw = [(name, what) for name, what in plugin["hardware"]]
    args = tuple(MacroArg(prefix + name, bus.name) for name, what in hw if what == "interface")
    params = tuple(Param(name, "${" + prefix + name + "}") for name, _ in hw)

    def joint_params(j: model.Joint) -> tuple[Param, ...]:
        actuator = m.nodes[j.node].actuator or {}
        values = dict(actuator.get("parameters") or ())
        return tuple(Param(name, _number(values[param])) for name, param in plugin["joint"])

    source = plugin["source"]
    interface = ", ".join(name for name, what in hw if what == "interface")
    note = f"bus {bus.name}: {plugin['plugin']}, {source.get('version', '?')}; {interface}: the SocketCAN interface " \
           "the bus is on"
    return Hardware(plugin["plugin"], params, args, joint_params, note)


def _number(value: Any) -> str:
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def _plugin_misfit(m: model.Model, j: model.Joint, plugin: dict[str, Any]) -> str | None:
    """Why the plugin cannot drive the joint as the spec binds it; None: it can."""
    actuator = m.nodes[j.node].actuator or {}
    cyclic = {c["message"] for c in actuator.get("cyclic") or ()}
    for side, carriers in (("command", j.command), ("state", j.state)):
        for interface, c in carriers.items():
            want = plugin[side].get(interface)
            if want is None:
                return f"{plugin['plugin']} has no {side} interface {interface}"
            if (c.message, c.signal) != (f"{j.node}_{want[0]}", want[1]):
                return (f"{plugin['plugin']} {'sends' if side == 'command' else 'reads'} its {interface} as "
                        f"{want[0]}.{want[1]}, the joint names {c.message}.{c.signal}")
            if side == "state" and c.message not in cyclic:
                return (f"{plugin['plugin']} reads its {interface} from {want[0]} and never asks for it: give "
                        f"{c.message} a cyclic rate")
    return None


Group = tuple[model.Bus, MakeHardware, list[model.Joint]]


def _groups(m: model.Model) -> tuple[list[Group], list[str]]:
    """Each block to write (its bus, its hardware, its joints) and what is left out, and why."""
    by_bus: dict[str, list[model.Joint]] = {}
    for j in m.joints.values():
        bus = joint_bus(m, j)
        if bus is not None:
            by_bus.setdefault(bus.name, []).append(j)
    groups: list[Group] = []
    left_out: list[str] = []
    for bus_name, joints in by_bus.items():
        bus = m.buses[bus_name]
        make = hardware(bus)
        if make is not None:
            groups.append((bus, make, joints))
            continue
        plugins: dict[str, tuple[dict[str, Any], list[model.Joint]]] = {}
        none: dict[str, list[str]] = {}  # why there is no plugin -> the joints
        for j in joints:
            node = m.nodes[j.node]
            plugin = node.ros2_control
            if plugin is None:
                why = (f"no official ros2_control plugin for {node.actuator['profile']['name']} (its vendor publishes "
                       "none)" if node.actuator else f"no ros2_control hardware plugin for {bus.protocol} buses here")
                none.setdefault(why, []).append(j.name)
                continue
            misfit = _plugin_misfit(m, j, plugin)
            if misfit is not None:
                left_out.append(f"joint {j.name} on bus {bus_name}: {misfit}")
                continue
            plugins.setdefault(plugin["plugin"], (plugin, []))[1].append(j)
        for why, names in none.items():
            left_out.append(f"joints {', '.join(names)} on bus {bus_name}: {why}")
        for plugin, members in plugins.values():
            groups.append((bus, partial(_actuator, plugin=plugin), members))
    return groups, left_out


def unsaid(m: model.Model) -> list[str]:
    """What of the joints the ros2_control description leaves out, for build to print."""
    return [f"ros2_control: {line}" for line in _groups(m)[1]] if m.joints else []


def emit(m: model.Model, report: dict[str, Any]) -> dict[str, bytes]:
    if not m.joints:
        return {}
    groups, left_out = _groups(m)
    if not groups:
        return {}  # no bus with a plugin: nothing to describe yet
    several = len(groups) > 1
    blocks: list[BlockView] = []
    args: list[MacroArg] = []
    notes: list[str] = []
    names = [bus.name for bus, _, _ in groups]
    for bus, make, joints in groups:
        hw = make(m, bus, several)
        args.extend(hw.args)
        if hw.note:
            notes.append(hw.note)
        suffix = f"_{hw.plugin.split('/')[0]}" if names.count(bus.name) > 1 else ""
        blocks.append(
            BlockView(
                name=f"${{prefix}}{m.system}_{bus.name}{suffix}",
                plugin=hw.plugin,
                params=hw.params,
                joints=tuple(_joint_view(j, hw) for j in joints),
            )
        )
    driven = {bus.name: joints for bus, _, joints in groups}
    return {
        f"ros2_control/{m.system}.ros2_control.xacro": render(
            XACRO_TEMPLATE,
            system=m.system,
            args=[MacroArg("prefix", "''"), *args],
            blocks=blocks,
            notes=notes,
            left_out=left_out,
        ),
        "ros2_control/controllers.yaml": render(
            CONTROLLERS_TEMPLATE,
            system=m.system,
            update_rate=update_rate(m, [m.buses[b] for b in driven], _command_periods(m, driven)),
            controllers=_controllers(m, driven),
        ),
    }


def _command_periods(m: model.Model, driven: dict[str, list[model.Joint]]) -> list[int]:
    """The periods of the commands that move actuator joints: the rate the spec gives the plugin's writes."""
    out = []
    for joints in driven.values():
        for j in joints:
            if m.nodes[j.node].actuator is None:
                continue
            for c in j.command.values():
                period = m.messages[c.message].period_ns
                if period:
                    out.append(period)
    return out


def _joint_view(j: model.Joint, hw: Hardware) -> JointView:
    def limits(interface: str) -> tuple[Param, ...]:
        bounds = j.limits.get(interface)
        if bounds is None:
            return ()
        return (Param("min", repr(bounds[0])), Param("max", repr(bounds[1])))

    return JointView(
        name="${prefix}" + j.name,
        params=hw.joint_params(j),
        command=tuple(Interface(i, limits(i)) for i in j.command),
        state=tuple(Interface(i) for i in j.state),
        modules=hw.joint_modules(j),
    )


@dataclass(frozen=True)
class ControllerView:
    name: str
    joints: tuple[str, ...]
    interface: str


def _controllers(m: model.Model, by_bus: dict[str, list[model.Joint]]) -> list[ControllerView]:
    out = []
    for bus_name, joints in by_bus.items():
        for interface in ("position", "velocity", "effort"):
            moved = tuple(j.name for j in joints if interface in j.command)
            if moved:
                out.append(ControllerView(f"{bus_name}_{interface}_controller", moved, interface))
    return out


def control_period_ns(m: model.Model, bus: model.Bus) -> int | None:
    """The period of the master's control step on the bus: its SYNC task's (each SYNC, on CANopen), else its
    fastest periodic task's; None when the master has no task."""
    masters = [n for n in bus.nodes if m.nodes[n].role == "master"]
    periods = []
    for name in masters:
        for t in m.nodes[name].tasks.values():
            if t.sync_bus == bus.name and bus.canopen is not None:
                periods.append(bus.canopen.sync_period_ns)
            elif t.period_ns is not None:
                periods.append(t.period_ns)
    return min(periods) if periods else None


def update_rate(m: model.Model, buses: list[model.Bus], commands_ns: list[int] | None = None) -> int:
    """The controller manager's rate, Hz: the fastest control step of the buses (their SYNC when the master has no
    task; an actuator joint's command period otherwise), rounded to a whole Hz as ros2_control takes it, at least 1."""
    periods = list(commands_ns or ())
    for bus in buses:
        period = control_period_ns(m, bus)
        if period is None and bus.canopen is not None:
            period = bus.canopen.sync_period_ns
        if period is not None:
            periods.append(period)
    if not periods:
        return 100  # the controller manager's own default
    return max(1, round(1e9 / min(periods)))
