"""Actuator nodes: a node whose `device:` is an actuator profile (netcfg.devices.actuator_profile) becomes ordinary
messages and tasks, so that every later stage (load, response times, flows, emitters, the simulator) reads them as
it reads any other.

- each command the spec lists is a periodic message from the commanding node at its rate;
- each reply the profile gives a command is a periodic message at the command's rate, sent by a task of the
  actuator that the command starts (on_message), whose BCET/WCET are the profile's reply delay range: the holistic
  analysis then gives the reply its command's response jitter plus that range, and a flow through
  command -> actuator task -> reply is bounded like any other (the task sends the reply as it ends: `sent_by`);
- each cyclic message of the profile whose rate parameter is not 0 is a periodic message at that rate.

Signals come from the profile's payload fields. A span field (MIT packing over [lo, hi]) is a linear map as a DBC
factor is: scale (hi - lo) / (2^bits - 1), offset lo; the one difference is that the device and the runtime codec
truncate a value to its count where codec.Field rounds to the nearest.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from netcfg import model
from netcfg.devices import builtin_profile_names
from netcfg.devices.actuator_profile import (
    ActuatorProfile,
    builtin_actuator_names,
    builtin_actuator_profile,
    load_actuator_profile,
)
from netcfg.diagnostics import SpecError
from netcfg.inputs import check_input_path
from netcfg.links import LINKS
from netcfg.protocols import PROTOCOLS
from netcfg.runtime.actuators import ActuatorCodec, MessageCodec
from netcfg.runtime.codec import CodecError
from netcfg.spec import schema
from netcfg.spec.names import is_name
from netcfg.spec.source import Path
from netcfg.spec.suggest import did_you_mean
from netcfg.spec.units import format_ns

if TYPE_CHECKING:
    from netcfg.resolve.core import Resolver

MS = 1_000_000


def is_actuator_device(device: object) -> bool:
    """The `device:` forms that name an actuator profile (the others are CANopen's)."""
    if isinstance(device, str):  # a name with '-' is no spec Name: only a profile's (moteus is both)
        return "-" in device or device in builtin_actuator_names()
    return isinstance(device, schema.ActuatorDevice)


def load_profile(r: Resolver, n: schema.Node, path: Path) -> ActuatorProfile | None:
    dpath = (*path, "device")
    if isinstance(n.device, str):
        try:
            return builtin_actuator_profile(n.device)
        except KeyError:
            known = [*builtin_actuator_names(), *builtin_profile_names()]
            r.err(
                "unknown-device",
                f"no built-in device profile '{n.device}'{did_you_mean(n.device, known)}; actuator profiles: "
                f"{', '.join(builtin_actuator_names())}, or give a profile file as 'device: {{actuator: x.yaml}}'",
                dpath,
            )
            return None
    assert isinstance(n.device, schema.ActuatorDevice)
    try:
        file = check_input_path(r.spec_dir, n.device.actuator, "actuator profile")
    except ValueError as exc:
        r.err("actuator-missing", str(exc), (*dpath, "actuator"))
        return None
    try:
        return load_actuator_profile(file)
    except SpecError as exc:  # each at the profile's own line, as a vendor EDS's errors are
        r.d.items.extend(exc.diagnostics)
        return None


def resolve_actuators(r: Resolver) -> None:
    for i, n in enumerate(r.spec.nodes):
        path: Path = ("nodes", i)
        if n.device is None or not is_actuator_device(n.device):
            if n.actuator is not None:
                r.err("wrong-section", f"'actuator:' sets up an actuator profile's node; give '{n.name}' a "
                      "'device:' that names one (e.g. damiao-dm-j4310)", (*path, "actuator"))
            continue
        if any(b not in r.spec_buses for b in n.buses):
            continue  # reported on the node
        profile = load_profile(r, n, path)
        if profile is not None:
            _Actuator(r, n, path, profile).resolve()


def add_reply_senders(r: Resolver) -> None:
    """Each reply is sent by the actuator task its command starts (after resolve_flows, which sets the rest)."""
    for msg in r.model.messages.values():
        if msg.name in r.actuator_replies:
            r.model.sent_by[msg.name] = (r.actuator_replies[msg.name],)


class _Actuator:
    def __init__(self, r: Resolver, n: schema.Node, path: Path, profile: ActuatorProfile) -> None:
        self.r, self.n, self.path, self.profile = r, n, path, profile
        self.apath: Path = (*path, "actuator")
        self.setup = n.actuator or schema.Actuator.model_validate({})
        self.plain: dict[str, Any] = profile.plain

    def resolve(self) -> None:
        r, n = self.r, self.n
        sbus = r.spec_buses[n.buses[0]]
        if len(n.buses) != 1:
            r.err("actuator-bus", f"actuator '{n.name}' speaks its profile's protocol on one bus; it lists "
                  f"{len(n.buses)}", (*self.path, "buses"))
            return
        protocol = r.bus_protocol(sbus)
        needs = LINKS[self.plain["link"]]
        if not protocol.carries_actuators or (needs.data_phase and not protocol.link.data_phase):
            fit = [name for name, p in PROTOCOLS.items() if p.carries_actuators
                   and (p.link.data_phase or not needs.data_phase)]
            r.err("actuator-link", f"'{self.profile.name}' speaks its own protocol over {needs.name} frames; bus "
                  f"'{sbus.name}' is {protocol.name}: put the actuator on a bus of protocol {' or '.join(fit)}",
                  (*self.path, "device"))
            return
        bus = r.model.buses[sbus.name]
        commander = self.commander(sbus)
        codec = self.codec()
        if commander is None or codec is None:
            return
        node = r.model.nodes[n.name]
        replies: dict[str, int] = {}  # reply message -> the command's index
        self.commands: list[dict[str, Any]] = []
        self.cyclics: list[dict[str, Any]] = []
        for j, c in enumerate(self.setup.commands):
            self.command(j, c, codec, commander, bus, node, replies)
        self.cyclic(codec, commander, bus)
        node.actuator = {  # what a master needs to run its codec (runtime.json's node `actuator`)
            "profile": self.plain,
            "parameters": [[k, v] for k, v in sorted(codec.parameters.items()) if v is not None],
            "commanded_by": commander,
            "commands": self.commands,
            "cyclic": self.cyclics,
        }
        node.ros2_control = self.profile.ros2_control

    # -- who, and with which parameters
    def commander(self, sbus: schema.Bus) -> str | None:
        given = self.setup.commanded_by
        if given is not None:
            where = (*self.apath, "commanded_by")
            if given not in self.r.spec_nodes:
                self.r.err("unknown-node", f"'{given}' is not a node{did_you_mean(given, self.r.spec_nodes)}", where)
                return None
            if sbus.name not in self.r.spec_nodes[given].buses or given == self.n.name:
                self.r.err("not-on-bus", f"'{given}' cannot command '{self.n.name}': it is not another node of bus "
                           f"'{sbus.name}'", where)
                return None
            return given
        masters = [m for m in self.r.masters(sbus.name) if m != self.n.name]
        if len(masters) != 1:
            self.r.err("actuator-commander", f"actuator '{self.n.name}': bus '{sbus.name}' has "
                       f"{'no master' if not masters else 'several masters'}; say which node commands it with "
                       "'commanded_by: <node>' under 'actuator:'", self.path)
            return None
        return masters[0]

    def codec(self) -> ActuatorCodec | None:
        declared = self.plain["parameters"]
        values: dict[str, int | float] = {}
        ok = True
        for name, value in self.setup.parameters.items():
            where = (*self.apath, "parameters", name)
            if name == "node_id":
                self.r.err("actuator-parameter", "the node id is the node's 'node_id'; drop it here", where)
                ok = False
            elif name not in declared:
                self.r.err("actuator-parameter", f"'{self.profile.name}' has no parameter '{name}'"
                           f"{did_you_mean(name, declared)}; it has {', '.join(sorted(declared))}", where)
                ok = False
            else:
                values[name] = int(value) if float(value).is_integer() else value
        if "node_id" in declared:
            if self.n.node_id is None:
                self.r.err("node-id", f"actuator '{self.n.name}' needs a node_id (its profile's identifiers use it)",
                           self.path)
                return None
            values["node_id"] = self.n.node_id
        for name, value in values.items():
            low, high = declared[name].get("min"), declared[name].get("max")
            if (low is not None and value < low) or (high is not None and value > high):
                where = (*self.path, "node_id") if name == "node_id" else (*self.apath, "parameters", name)
                self.r.err("actuator-parameter", f"{self.profile.name}'s {name} is {low}..{high}; {value} is outside",
                           where)
                ok = False
        for c in self.setup.cyclic:  # a cyclic rate is the value of its parameter (ms)
            got = self.cyclic_period(c)
            if got is not None:
                values[got[0]] = got[1] // MS
        missing = [p for p, d in declared.items() if d.get("default") is None and p not in values]
        if missing:
            self.r.err("actuator-parameter", f"actuator '{self.n.name}': '{self.profile.name}' needs "
                       f"{', '.join(missing)}; give them under 'actuator: parameters:'", self.path)
            return None
        if not ok:
            return None
        try:
            return ActuatorCodec(self.plain, **values)
        except CodecError as exc:
            self.r.err("actuator-parameter", f"actuator '{self.n.name}': {exc}", self.apath)
            return None

    def period(self, item: schema.ActuatorCommand | schema.ActuatorCyclic, path: Path) -> int | None:
        if (item.period is None) == (item.rate is None):
            self.r.err("period", f"say how often '{item.message}' is sent: 'period' or 'rate', one of them", path)
            return None
        ns = round(1_000_000_000 / item.rate) if item.rate is not None else self.r.ns(item.period, (*path, "period"),
                                                                                      None)
        if ns is None or ns <= 0:
            self.r.err("period", f"'{item.message}': a period must be above zero", path)
            return None
        return ns

    def profile_message(self, name: str, sender: str, path: Path) -> dict[str, Any] | None:
        mine = {m["name"]: m for m in self.plain["messages"] if m["from"] == sender}
        if name in mine:
            return mine[name]
        other = "the host's" if sender == "device" else "the device's own"
        also = f" ('{name}' is one of {other})" if name in self.profile.message_names() else ""
        self.r.err("actuator-message", f"'{self.profile.name}' has no message '{name}' from the {sender}{also}"
                   f"{did_you_mean(name, mine)}; it has {', '.join(mine) or 'none'}", (*path, "message"))
        return None

    # -- messages
    def command(self, j: int, c: schema.ActuatorCommand, codec: ActuatorCodec, commander: str, bus: model.Bus,
                node: model.Node, replies: dict[str, int]) -> None:
        cpath: Path = (*self.apath, "commands", j)
        pm = self.profile_message(c.message, "host", cpath)
        period = self.period(c, cpath)
        if pm is None or period is None:
            return
        mc = codec.message(c.message)
        cmd = self.message(mc, pm, f"{self.n.name}_{c.message}", commander, self.n.name, period, bus, cpath,
                           c.description)
        if cmd is None:
            return
        record: dict[str, Any] = {"command": c.message, "message": cmd.name, "reply": None, "reply_message": None}
        self.commands.append(record)
        if mc.reply is None or mc.reply_delay_us is None:
            return
        lo, hi = (round(d * 1000) for d in mc.reply_delay_us)
        basis = mc.delay_basis
        if c.reply_delay is not None:
            given = [self.r.ns(d, (*cpath, "reply_delay", k), None) for k, d in enumerate(c.reply_delay)]
            if given[0] is None or given[1] is None or not 0 <= given[0] <= given[1]:
                self.r.err("actuator-delay", "reply_delay is [shortest, longest], 0 <= shortest <= longest",
                           (*cpath, "reply_delay"))
                return
            lo, hi = given[0], given[1]
            basis = "measured: the spec's reply_delay"
        if hi >= period:
            self.r.err("actuator-rate", f"'{self.profile.name}' answers {c.message} within {format_ns(hi)} "
                       f"({basis.split(':')[0]}); a period of {format_ns(period)} sends the next command "
                       "before the answer may come: command it less often", (*cpath, "rate" if c.rate else "period"))
            return
        if mc.reply in replies:
            self.r.err("actuator-reply", f"'{c.message}' and '{self.setup.commands[replies[mc.reply]].message}' are "
                       f"both answered by '{mc.reply}': command one of them at a rate, the other on demand (netcfg "
                       "cannot tell their answers apart)", cpath)
            return
        replies[mc.reply] = j
        task = model.Task(
            node=self.n.name, name=c.message, period_ns=None, offset_ns=0, wcet_ns=max(hi, 1), bcet_ns=lo,
            trigger=None, on_message=cmd.name, path=cpath,
            description=f"{self.profile.name} answers {c.message} with {mc.reply} ({basis})",
        )
        if c.message in node.tasks:
            self.r.err("duplicate-name", f"'{c.message}' is listed twice", cpath)
            return
        node.tasks[c.message] = task
        rm = codec.message(mc.reply)
        reply_plain = next(m for m in self.plain["messages"] if m["name"] == mc.reply)
        reply = self.message(rm, reply_plain, f"{self.n.name}_{mc.reply}", self.n.name, commander, period, bus,
                             cpath, None)
        if reply is not None:
            self.r.actuator_replies[reply.name] = task.ref
            record["reply"], record["reply_message"] = mc.reply, reply.name

    def cyclic_period(self, c: schema.ActuatorCyclic) -> tuple[str, int] | None:
        j = self.setup.cyclic.index(c)
        cpath: Path = (*self.apath, "cyclic", j)
        pm = self.profile_message(c.message, "device", cpath)
        period = self.period(c, cpath)
        if pm is None or period is None:
            return None
        param = pm.get("cyclic")
        if param is None:
            self.r.err("actuator-cyclic", f"'{self.profile.name}' sends {c.message} only when asked, not at a rate of "
                       "its own", (*cpath, "message"))
            return None
        p = self.plain["parameters"][param]
        low, high = max(p.get("min", 1), 1), p.get("max")
        where = (*cpath, "rate" if c.rate else "period")
        if period % MS or period // MS < low or (high is not None and period // MS > high):
            self.r.err("actuator-rate", f"'{self.profile.name}' sends {c.message} every {param} ms, a whole number "
                       f"{low}..{high}; {format_ns(period)} is not one", where)
            return None
        return param, period

    def cyclic(self, codec: ActuatorCodec, commander: str, bus: model.Bus) -> None:
        listed = {c.message: j for j, c in enumerate(self.setup.cyclic)}
        for pm in self.plain["messages"]:
            param = pm.get("cyclic")
            if param is None:
                continue
            value = codec.parameters.get(param) or 0
            if not value:
                continue  # off (0): the device does not send it
            path = (*self.apath, "cyclic", listed[pm["name"]]) if pm["name"] in listed else self.path
            if f"{self.n.name}_{pm['name']}" in self.r.actuator_replies:
                self.r.err("actuator-reply", f"'{pm['name']}' answers a command of '{self.n.name}' and is sent every "
                           f"{param} ms too; set 'parameters: {{{param}: 0}}' (off) to command it at a rate", path)
                continue
            got = self.message(codec.message(pm["name"]), pm, f"{self.n.name}_{pm['name']}", self.n.name, commander,
                               int(value * MS), bus, path, None)
            if got is not None:
                self.cyclics.append({"profile_message": pm["name"], "message": got.name})

    def message(self, mc: MessageCodec, pm: dict[str, Any], name: str, producer: str, consumer: str, period: int,
                bus: model.Bus, path: Path, description: str | None) -> model.Message | None:
        if not is_name(name):
            self.r.err("actuator-name", f"the message name '{name}' (node and profile message) is not a valid name: "
                       "shorten the node's name", self.path)
            return None
        if mc._id_fields:
            self.r.err("actuator-message", f"'{pm['name']}' carries fields in its identifier, so its priority changes "
                       "from frame to frame; netcfg does not analyse such a message at a rate", path)
            return None
        self.r.claim_implicit_name(name, f"actuator '{self.n.name}'")
        if name in self.r.model.messages:
            self.r.err("duplicate-name", f"message '{name}' is already defined", path)
            return None
        fd = mc.fd
        fields = {f["name"]: f for f in pm.get("fields") or ()}
        description = description or _limits(self.profile.name, mc)
        # a remote request (RTR) has no data field: 0 bytes on the wire, whatever length its DLC asks for
        msg = model.Message(
            name=name, bus=bus.name, producer=producer, consumers=(consumer,), id=mc.base_id,
            extended=mc._frame_extended(mc.base_id), size=0 if mc.is_remote else mc.size, kind="periodic",
            period_ns=period,
            interval_ns=period, offset_ns=None, offset_auto=False, deadline_ns=period, jitter_ns=0, path=path,
            signals=tuple(_signal(f, fields[f.name]) for f in mc.payload if f.const is None), description=description,
            fd=fd, brs=fd, fixed_by=f"actuator profile {self.profile.name}", remote=mc.is_remote,
            base_payload=mc.base if any(mc.base) else None,
        )
        self.r.model.messages[name] = msg
        bus.messages.append(msg)
        return msg


def _limits(profile: str, mc: MessageCodec) -> str:
    """What a DBC or a C header's signals cannot say of a profile message, for their comments."""
    words = [f"{profile} {mc.name}"]
    span = [f.name for f in mc.payload if f.encoding == "span"]
    const = [f.name for f in mc.payload if f.const is not None]
    if span:
        words.append(f"{', '.join(span)} MIT-packed: the device, netcfg.runtime.actuators and the C header's setters "
                     "truncate to the count below, a DBC signal's factor rounds to the nearest (at most one count "
                     "apart)")
    if const:
        words.append(f"constant {', '.join(const)} written by the codec and a C header's pack, not signals")
    if mc.fixed is not None:
        words.append(f"fixed payload {mc.fixed.hex(' ').upper()}")
    return "; ".join(words)


def _signal(f: Any, plain: dict[str, Any]) -> model.Signal:
    """A payload field as a signal, in the wire's unit: linear as it is; span as the linear map it is (scale
    (hi - lo) / (2^bits - 1), offset lo)."""
    v = f.value
    if f.encoding == "span":
        scale, offset = (f.hi - f.lo) / ((1 << f.bits) - 1), f.lo
    else:
        scale, offset = v.scale, v.offset
    unit = plain.get("unit") or "1"
    return model.Signal(
        name=f.name, start_bit=f.layout.start_bit, bits=f.bits, signed=v.signed, is_float=v.is_float, scale=scale,
        offset=offset, minimum=f.lo, maximum=f.hi, unit=None if unit == "1" else unit,
        big_endian=f.layout.big_endian, choices=tuple(sorted(f.choices.items())),
        span=(f.lo, f.hi) if f.encoding == "span" else None,
    )
