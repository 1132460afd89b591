"""The live actuator master: a bus of actuators that speak their own protocols (netcfg.devices.actuator_profile),
driven as runtime.json describes it (netcfg.runtime.actuator_plan reads it).

    plans = plan_actuators(cfg, "leg_can")
    run = ActuatorMaster(plans, period_ns).run(bus, ActuatorRunPlan(cycles=100))

1. Enable: each actuator whose profile has `enable:` gets it; the master waits for its reply where the profile gives
   one (at most the actuator's loss timeout). One that does not answer is lost before the cycle and its `on_loss`
   applies.
2. The cycle: every command goes out at its own period from one start instant (t0 + k * period, never drifting),
   encoded by the profile's codec with its values (the profile's units; default 0, or the range's bound nearest 0).
   Every frame that comes is decoded by the codec of the actuator it belongs to. A reply counts against the last
   command still waiting for it (a device answers in order): `late` when it comes after its bound
   (netcfg.runtime.actuator_plan); a command whose reply has not come within the actuator's loss timeout, or by the
   end of the cycle, counts as `missing` (so replies + missing = commands).
3. Supervision: an actuator that has sent nothing for its loss timeout is `lost`, and its node's `on_loss` applies; a
   decoded frame whose error fields report errors (or whose state field holds one of its error values) is an
   `error`, and its node's `on_emcy` applies (a CANopen node's EMCY and an actuator's error flags are the same
   event to the master). stop_all: every actuator gets its safe stop and the cycle ends; stop_node: this actuator gets
   its safe stop and no more commands; continue: the master reports it and holds, commanding it as before. An
   actuator heard again after it was lost is `back`; errors that go away are `cleared`.
4. The safe stop: when the cycle ends (its cycles, stop(), stop_all, Ctrl-C, an exception), each actuator not yet
   stopped gets its profile's `safe_stop:` command, and the master waits for its reply where the profile gives one.

Reply delays are measured between frame timestamps (the sent command's and the reply's, as the log has them), so
a log of the run shows the same figures. Times in the result are seconds from the cycle's start.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import can

from netcfg.links import pycan_frames
from netcfg.runtime.actuator_plan import LOSS_MULTIPLIER, ActuatorPlan, CommandPlan
from netcfg.runtime.actuators import ActuatorFrame, Decoded
from netcfg.runtime.clock import Clock, SystemClock

RUNNING, LOST, STOPPED = "RUNNING", "LOST", "STOPPED"
SAFE_STOP_WAIT_S = 0.5  # how long the master waits for the safe stop's replies at the end
ENABLE_WAIT_NS = 500_000_000  # the wait for an enable's reply of an actuator with no loss timeout


@dataclass
class ActuatorRunPlan:
    """What to run: `cycles` control periods (None: until stop()); drills (at s, text, action) run once the cycle
    has been going that long; on_cycle is called after each control period."""

    cycles: int | None
    drills: list[tuple[float, str, Callable[[], None]]] = field(default_factory=list)
    on_cycle: Callable[[int, ActuatorRun], None] | None = None


@dataclass
class ActuatorEvent:
    t_s: float
    node: str
    kind: str  # lost | back | error | cleared
    detail: str
    action: str  # stop_all | stop_node | continue | "" (nothing to do)


@dataclass
class ActuatorOutcome:
    name: str
    profile: str
    state: str = "NOT STARTED"  # RUNNING | LOST | STOPPED
    enabled: str | None = None  # "answered", "sent" (no reply to wait for), "no answer", None: no enable command
    commands: int = 0
    replies: int = 0
    missing: int = 0
    late: int = 0
    delay_us: list[float] = field(default_factory=list)  # [least, largest, sum, count]
    bound_us: float | None = None
    loss_timeout_ms: float | None = None
    heard: dict[str, int] = field(default_factory=dict)  # device message -> frames
    last: dict[str, dict[str, Any]] = field(default_factory=dict)  # device message -> its last values (SI)
    states: dict[str, str] = field(default_factory=dict)  # state fields as last reported
    errors: tuple[str, ...] = ()
    lost_at_s: float | None = None
    stopped_at_s: float | None = None
    safe_stop: str | None = None  # what the safe stop got: "answered", "sent", "no answer", None: none sent

    def add_delay(self, us: float) -> None:
        d = self.delay_us
        if not d:
            d.extend([us, us, us, 1.0])
        else:
            d[0], d[1], d[2], d[3] = min(d[0], us), max(d[1], us), d[2] + us, d[3] + 1


@dataclass
class ActuatorRun:
    bus: str
    period_ns: int
    actuators: dict[str, ActuatorOutcome]
    events: list[ActuatorEvent] = field(default_factory=list)
    drills: list[tuple[float, str]] = field(default_factory=list)
    cycles: int = 0
    ended_by: str = "cycles"  # cycles | stop_all:<node> | stop() | signal SIGINT ...
    unknown_frames: int = 0
    # how late after its release each command went out: [largest, sum, count] in us, and the releases sent a whole
    # period or more late (the host missed its cycle: as a missed SYNC is to a CANopen master)
    send_late_us: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    missed_releases: int = 0

    @property
    def ok(self) -> bool:
        """The cycle ran (to its end, or until stopped from outside: stop(), Ctrl-C), no actuator was lost or
        reported an error; late replies are counted, not failures (a host's latency makes them)."""
        return self.cycles > 0 and not self.ended_by.startswith("stop_all") and not any(
            e.kind in ("lost", "error") for e in self.events
        )


@dataclass
class _Pending:
    sent_at: float  # the command frame's timestamp (time.time())
    expires: float  # clock time after which its reply is counted missing


class ActuatorMaster:
    """The cycle over one bus's actuators (the module's docstring). `period_ns` is the control period `cycles`
    counts: the fastest command's period by default."""

    def __init__(self, plans: list[ActuatorPlan], bus_name: str, period_ns: int | None = None,
                 clock: Clock | None = None) -> None:
        self.plans = {p.name: p for p in plans}
        periods = [c.period_ns for p in plans for c in p.commands]
        if period_ns is None and not periods:
            raise ValueError(f"bus '{bus_name}': no actuator has a command at a rate, so there is no cycle to run")
        self.period_ns = period_ns or min(periods)
        self.clock = clock or SystemClock()
        self.result = ActuatorRun(bus_name, self.period_ns, {
            p.name: ActuatorOutcome(p.name, p.codec.profile_name, bound_us=_max_bound_us(p),
                                    loss_timeout_ms=None if p.loss_timeout_ns is None else p.loss_timeout_ns / 1e6)
            for p in plans
        })
        # (node, reply message) -> the commands waiting for it, oldest first: a device answers in order, so a reply
        # that comes after the next command went out still answers the one before
        self._pending: dict[tuple[str, str], list[_Pending]] = {}
        self._reply_of: dict[tuple[str, str], CommandPlan] = {
            (c.node, c.reply): c for p in plans for c in p.commands if c.reply is not None
        }
        self._heard_at: dict[str, float] = {}  # node -> clock time of its last frame
        self._stop_waits: dict[str, str] = {}  # node -> the reply its safe stop waits for
        self._stop_reason: str | None = None
        self._t0 = 0.0
        # called with "stop_all:<node>" when an actuator's on_loss or on_emcy stops this bus: a run of several buses
        # stops the others with it (netcfg.run_actuators), as stop_all means every actuator
        self.on_stop_all: Callable[[str], None] | None = None

    # -- control from outside (a signal handler, a test)
    def stop(self, reason: str = "stop()") -> None:
        if self._stop_reason is None:
            self._stop_reason = reason
            if reason.startswith("stop_all"):  # another bus's actuator stopped the whole run
                self.result.ended_by = reason

    # -- the run
    def run(self, bus: can.BusABC, plan: ActuatorRunPlan) -> ActuatorRun:
        self.bus = bus
        try:
            if self._enable():
                self._cycle(plan)
        finally:
            self._safe_stop_all()
        return self.result

    def _now_s(self) -> float:
        return self.clock.now() - self._t0

    def _send(self, frame: ActuatorFrame) -> float:
        # a remote frame (ODrive's Get_* requests) carries no data; its DLC is the length it asks for
        msg = pycan_frames.message(frame.arbitration_id, frame.is_extended, None if frame.is_remote else frame.data,
                                   fd=frame.fd, brs=frame.brs, remote=frame.is_remote,
                                   dlc=frame.dlc)
        msg.timestamp = time.time()
        self.bus.send(msg)
        return msg.timestamp

    def _enable(self) -> bool:
        waits: dict[str, tuple[str, float]] = {}  # node -> (reply it waits for, clock deadline)
        self._t0 = self.clock.now()
        for p in self.plans.values():
            out = self.result.actuators[p.name]
            frame = p.action_frame("enable")
            out.state = RUNNING
            self._heard_at[p.name] = self.clock.now()
            if frame is None:
                continue
            self._send(frame)
            reply = p.action_reply("enable")
            if reply is None:
                out.enabled = "sent"
            else:
                timeout_s = (p.loss_timeout_ns or ENABLE_WAIT_NS) / 1e9
                waits[p.name] = (reply, self.clock.now() + timeout_s)
        while waits:
            msg = self.bus.recv(timeout=max(0.0, min(d for _, d in waits.values()) - self.clock.now()))
            if msg is not None:
                got = self._decode(msg)
                if got is not None and waits.get(got[0], ("",))[0] == got[1].message:
                    self.result.actuators[got[0]].enabled = "answered"
                    del waits[got[0]]
            now = self.clock.now()
            for name in [n for n, (_, d) in waits.items() if now >= d]:
                self.result.actuators[name].enabled = "no answer"
                del waits[name]
                self._lost(name, "no answer to its enable command")
        return self._stop_reason is None

    def _cycle(self, plan: ActuatorRunPlan) -> None:
        period_s = self.period_ns / 1e9
        commands = [c for p in self.plans.values() for c in p.commands]
        self._t0 = t0 = self.clock.now() + 0.001  # the cycle's start: every command's first release
        for name in self._heard_at:
            self._heard_at[name] = t0
        due = [t0] * len(commands)
        end = None if plan.cycles is None else t0 + plan.cycles * period_s
        drills = sorted(plan.drills, key=lambda d: d[0])
        cycle_mark = t0 + period_s
        while self._stop_reason is None:
            now = self.clock.now()
            if end is not None and now >= end:
                break
            while drills and now - t0 >= drills[0][0]:
                _, text, action = drills.pop(0)
                self.result.drills.append((round(now - t0, 6), text))
                action()
            nxt = min(due)
            if end is not None:
                nxt = min(nxt, end)
            if nxt > now:
                # waits on the bus, never spinning: a spin holds the interpreter lock that simulated devices in the
                # same process need (the sends land the host's wake-up latency late)
                msg = self.bus.recv(timeout=nxt - now)
                if msg is not None:
                    self._receive(msg)
                self._supervise()
                continue
            for i, c in enumerate(commands):
                if due[i] <= now:
                    if self._command(c):
                        self._sent_late(self.clock.now() - due[i], c.period_ns / 1e9)
                    due[i] += c.period_ns / 1e9
            if now >= cycle_mark:
                self.result.cycles += 1
                cycle_mark += period_s
                if plan.on_cycle is not None:
                    plan.on_cycle(self.result.cycles, self.result)
        if self._stop_reason is None:
            self.result.cycles = plan.cycles or self.result.cycles
        elif self.result.ended_by == "cycles":
            self.result.ended_by = self._stop_reason

    def _sent_late(self, late_s: float, period_s: float) -> None:
        r = self.result.send_late_us
        r[0], r[1], r[2] = max(r[0], late_s * 1e6), r[1] + late_s * 1e6, r[2] + 1
        self.result.missed_releases += int(late_s >= period_s)

    def _command(self, c: CommandPlan) -> bool:
        """Send the command (False: its actuator is stopped, nothing sent)."""
        out = self.result.actuators[c.node]
        if out.state == STOPPED:
            return False
        sent = self._send(c.frame)
        out.commands += 1
        if c.reply is not None:
            wait_ns = self.plans[c.node].loss_timeout_ns or LOSS_MULTIPLIER * c.period_ns
            self._pending.setdefault((c.node, c.reply), []).append(_Pending(sent, self.clock.now() + wait_ns / 1e9))
        return True

    def _decode(self, msg: can.Message) -> tuple[str, Decoded] | None:
        if msg.is_error_frame or msg.is_remote_frame:  # a remote frame is a request, sent by a host
            return None
        for p in self.plans.values():
            got = p.codec.decode(msg.arbitration_id, msg.is_extended_id, bytes(msg.data))
            if got is not None:
                return p.name, got
        return None

    def _receive(self, msg: can.Message) -> None:
        got = self._decode(msg)
        if got is None:
            self.result.unknown_frames += 1
            return
        name, d = got
        out = self.result.actuators[name]
        if out.state == STOPPED:
            if self._stop_waits.get(name) == d.message:  # the answer to a safe stop
                out.safe_stop = "answered"
                out.states.update(d.states)
                out.last[d.message] = dict(d.values)
                del self._stop_waits[name]
            return
        self._heard_at[name] = self.clock.now()
        if out.state == LOST:
            out.state = RUNNING
            self._event(name, "back", f"heard again ({d.message})", "")
        out.heard[d.message] = out.heard.get(d.message, 0) + 1
        out.last[d.message] = dict(d.values)
        out.states.update(d.states)
        waiting = self._pending.get((name, d.message))
        if waiting:
            pending = waiting.pop(0)
            c = self._reply_of[(name, d.message)]
            delay_us = (msg.timestamp - pending.sent_at) * 1e6
            out.replies += 1
            out.add_delay(delay_us)
            if c.bound_ns is not None and delay_us * 1000 > c.bound_ns:
                out.late += 1
        if d.errors != out.errors:
            if d.errors:
                self._fault(name, f"{d.message} reports {', '.join(d.errors)}")
            else:
                self._event(name, "cleared", f"{d.message} reports no error", "")
            out.errors = d.errors

    def _supervise(self) -> None:
        now = self.clock.now()
        for (name, _), waiting in self._pending.items():
            while waiting and waiting[0].expires <= now:
                waiting.pop(0)
                self.result.actuators[name].missing += 1
        for name, p in self.plans.items():
            out = self.result.actuators[name]
            if out.state != RUNNING or p.loss_timeout_ns is None:
                continue
            silent = now - self._heard_at[name]
            if silent * 1e9 > p.loss_timeout_ns:
                self._lost(name, f"silent for {silent * 1e3:.1f} ms (loss timeout {p.loss_timeout_ns / 1e6:g} ms)")

    # -- reactions
    def _event(self, name: str, kind: str, detail: str, action: str) -> None:
        self.result.events.append(ActuatorEvent(round(self._now_s(), 6), name, kind, detail, action))

    def _lost(self, name: str, detail: str) -> None:
        out = self.result.actuators[name]
        out.state = LOST
        out.lost_at_s = round(self._now_s(), 6)
        action = self.plans[name].node.on_loss
        self._event(name, "lost", detail, action)
        self._react(name, action)

    def _fault(self, name: str, detail: str) -> None:
        action = self.plans[name].node.on_emcy
        self._event(name, "error", detail, action)
        self._react(name, action)

    def _react(self, name: str, action: str) -> None:
        if action == "stop_all":
            if self._stop_reason is None:
                self._stop_reason = f"stop_all:{name}"
                self.result.ended_by = self._stop_reason
                if self.on_stop_all is not None:
                    self.on_stop_all(self._stop_reason)
        elif action == "stop_node":
            self._safe_stop(name)

    def _safe_stop(self, name: str) -> None:
        """Send the actuator its safe stop, once; the reply it waits for goes to _stop_waits."""
        out, p = self.result.actuators[name], self.plans[name]
        if out.stopped_at_s is not None:
            return
        out.stopped_at_s = round(self._now_s(), 6)
        lost = out.state == LOST
        out.state = STOPPED
        for (node, _), waiting in self._pending.items():
            if node == name:
                out.missing += len(waiting)
                waiting.clear()
        frame = p.action_frame("safe_stop")
        if frame is None:
            return
        try:
            self._send(frame)
        except can.CanError:
            out.safe_stop = "not sent"
            return
        reply = p.action_reply("safe_stop")
        out.safe_stop = "sent" if reply is None or lost else "no answer"
        if reply is not None and not lost:
            self._stop_waits[name] = reply

    def _safe_stop_all(self) -> None:
        for name in self.plans:
            self._safe_stop(name)
        deadline = self.clock.now() + SAFE_STOP_WAIT_S
        while self._stop_waits and self.clock.now() < deadline:
            msg = self.bus.recv(timeout=max(0.0, deadline - self.clock.now()))
            if msg is not None:
                self._receive(msg)


def _max_bound_us(p: ActuatorPlan) -> float | None:
    bounds = [c.bound_ns for c in p.commands if c.bound_ns is not None]
    return max(bounds) / 1000 if bounds else None
