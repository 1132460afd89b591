"""What the actuator master (netcfg.runtime.actuator_master) reads from runtime.json: which buses carry actuator
nodes, each command it sends at a rate with the reply it waits for and the bounds the analysis used, and how long
an actuator may stay silent before the master reports it lost.

- A command's reply delay range is its reply task's BCET..WCET (netcfg.resolve.actuators made the task from the
  profile's `reply: delay_us`, or from the spec's `reply_delay`): the range the analysis used.
- A reply is late when it comes later after its command's send than the reply's analysed worst-case response
  (runtime.json's `wcrt_ns`) plus the command's own (its `wcrt_ns`). The reply's bound counts from its command's
  earliest end at the latest (netcfg.timing.can_transactions; verify measures from the command's frame so), and the
  master sends a command at or after its release, which is at most the command's worst case before that frame ends:
  the sum is sound from the send, if looser than from the frame by the command's response above its best frame time.
  Without an analysed bound (a file written without one) the bound is the reply delay's upper end alone.
- An actuator is lost when nothing it sends (a reply or a cyclic message) has come for its node's `heartbeat_timeout`,
  or, without one, for 3 periods of the slowest message the master expects from it (3: as Lely's dcfgen's
  heartbeat_multiplier sets a CANopen consumer time from the producer's).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from netcfg.runtime.actuators import ActuatorCodec, ActuatorFrame
from netcfg.runtime.codec import CodecError
from netcfg.runtime.config import Message, Node, RuntimeConfig

LOSS_MULTIPLIER = 3  # periods of silence before an actuator is lost, when its node sets no heartbeat_timeout


@dataclass(frozen=True)
class CommandPlan:
    """One command the master sends at its rate, and the reply it waits for."""

    node: str
    command: str  # the profile's message
    message: Message  # runtime.json's message that carries it
    period_ns: int
    reply: str | None  # the profile's reply message
    reply_message: Message | None
    delay_ns: tuple[int, int] | None  # the reply delay range the analysis used (the reply task's BCET, WCET)
    bound_ns: int | None  # a reply later than this after its command is late
    values: dict[str, float | int | str]  # the command's field values (the profile's units)
    frame: ActuatorFrame  # the command, encoded


@dataclass(frozen=True)
class ActuatorPlan:
    """One actuator: its node, its codec, its commands and how long it may be silent."""

    node: Node
    codec: ActuatorCodec
    commands: tuple[CommandPlan, ...]
    cyclic: tuple[tuple[str, Message], ...]  # (profile message, runtime.json message) it sends on its own
    loss_timeout_ns: int | None  # None: the master expects nothing from it
    enable: Mapping[str, Any] | None  # the profile's enable / safe_stop ({message, values, state}) or None
    safe_stop: Mapping[str, Any] | None

    @property
    def name(self) -> str:
        return self.node.name

    def action_frame(self, which: str) -> ActuatorFrame | None:
        action = self.enable if which == "enable" else self.safe_stop
        if action is None:
            return None
        return self.codec.encode(action["message"], action["values"], units="wire")

    def action_reply(self, which: str) -> str | None:
        action = self.enable if which == "enable" else self.safe_stop
        return None if action is None else self.codec.message(action["message"]).reply


def loss_timeout_ns(heartbeat_timeout_ns: int | None, expected_periods_ns: list[int]) -> int | None:
    """How long an actuator may send nothing before the master reports it lost: its node's heartbeat_timeout, else
    LOSS_MULTIPLIER periods of the slowest message it sends (replies and cyclic ones); None when it sends none."""
    if heartbeat_timeout_ns:
        return heartbeat_timeout_ns
    return LOSS_MULTIPLIER * max(expected_periods_ns) if expected_periods_ns else None


def reply_commands(cfg: RuntimeConfig) -> dict[str, str]:
    """Each actuator reply's runtime.json message -> the command message it answers (netcfg.verify measures the
    reply's response from its command's frame)."""
    return {c.reply_message: c.message for n in cfg.nodes if n.actuator is not None for c in n.actuator.commands
            if c.reply_message is not None}


def actuator_buses(cfg: RuntimeConfig) -> list[str]:
    """The buses that carry actuator profile nodes, in the configuration's order."""
    with_actuators = {b for n in cfg.nodes if n.actuator is not None for b in n.buses}
    return [b.name for b in cfg.buses if b.name in with_actuators]


def actuator_bus(cfg: RuntimeConfig, bus_name: str | None) -> str:
    """The actuator bus named, or the configuration's only one; ValueError otherwise."""
    buses = actuator_buses(cfg)
    if bus_name is not None:
        if bus_name not in buses:
            raise ValueError(f"bus '{bus_name}' has no actuator nodes (actuator buses: {', '.join(buses) or 'none'})")
        return bus_name
    if len(buses) != 1:
        raise ValueError(f"{cfg.system} has {len(buses)} actuator buses ({', '.join(buses) or 'none'}); say which one "
                         "with bus_name")
    return buses[0]


def default_values(codec: ActuatorCodec, command: str) -> dict[str, float | int | str]:
    """A command's values when none are given: each field 0, or its range's bound nearest 0 (MIT: no stiffness,
    no damping, no torque, the actuator limp), in the profile's units."""
    out: dict[str, float | int | str] = {}
    mc = codec.message(command)
    for name in mc.inputs:
        f = mc.by_name[name]
        lo, hi = f.lo, f.hi
        out[name] = 0.0 if lo is None or hi is None else min(max(0.0, lo), hi)
    return out


def plan_actuators(cfg: RuntimeConfig, bus: str, values: Mapping[tuple[str, str], Mapping[str, float | int | str]]
                   | None = None) -> list[ActuatorPlan]:
    """Every actuator on `bus` with its commands encoded; `values` sets command fields by (node, command) in the
    profile's units. CodecError for a value the profile refuses or a name it does not have."""
    given = dict(values or {})
    plans = []
    for node in cfg.nodes:
        if node.actuator is None or bus not in node.buses:
            continue
        codec = node.actuator.codec()
        commands = []
        expected: list[int] = []
        for c in node.actuator.commands:
            msg = cfg.message(c.message)
            assert msg.period_ns is not None
            vals = default_values(codec, c.command)
            extra = dict(given.pop((node.name, c.command), {}))
            unknown = set(extra) - set(vals)
            if unknown:
                raise CodecError(f"{node.name}.{c.command} has no fields {sorted(unknown)}; it has {sorted(vals)}")
            vals.update(extra)
            frame = codec.encode(c.command, vals, units="wire")
            reply_msg = cfg.message(c.reply_message) if c.reply_message else None
            delay = bound = None
            if reply_msg is not None:
                task = next((t for t in node.tasks if t.on_message == msg.name), None)
                if task is not None:
                    delay = (task.bcet_ns, task.wcet_ns)
                if reply_msg.wcrt_ns is not None and msg.wcrt_ns is not None:
                    bound = reply_msg.wcrt_ns + msg.wcrt_ns
                else:
                    bound = delay[1] if delay else None
                expected.append(msg.period_ns)
            commands.append(CommandPlan(node.name, c.command, msg, msg.period_ns, c.reply, reply_msg, delay, bound,
                                        vals, frame))
        cyclic = tuple((pm, cfg.message(m)) for pm, m in node.actuator.cyclic)
        expected += [m.period_ns for _, m in cyclic if m.period_ns]
        timeout = loss_timeout_ns(node.heartbeat_timeout_ns, expected)
        profile = node.actuator.profile
        plans.append(ActuatorPlan(node, codec, tuple(commands), cyclic, timeout, profile.get("enable"),
                                  profile.get("safe_stop")))
    if given:
        names = ", ".join(f"{n}.{c}" for n, c in given)
        raise CodecError(f"no command {names} on bus '{bus}' (the spec's actuator commands)")
    return plans
