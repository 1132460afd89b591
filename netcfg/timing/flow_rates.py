"""How often a model's tasks start and its messages are renewed (Rates), as the flow models wait for them: a
task's activations, a message's deliveries and renewal, the spacing of the sends of a sporadic message that its
tasks send as they end, and which messages surely go out ahead of others.
"""

from __future__ import annotations

from dataclasses import dataclass

from netcfg import model
from netcfg.timing import clocks
from netcfg.timing.flow_steps import (
    Delivery,
    TaskTimes,
    clock_tolerance,
    message_period,
    sending_tasks,
    task_period,
    task_response,
)
from netcfg.timing.frames import arbitration_key


@dataclass(frozen=True)
class Runs:
    """How a task's starts (or a message's deliveries) follow one another: n of them apart, between
    n * fastest - spread and n * slowest + spread (nominal spacings, the spread in real time)."""

    fastest: int
    slowest: int
    spread: int


@dataclass(frozen=True)
class Rates:
    """How often a model's tasks start and its messages are renewed, from each message's delivery and each task's
    response; `scheduled`: the messages an FTT-CAN schedule sends in their windows (their senders' ends do not
    move them, and `chained` holds their windows' delivery)."""

    m: model.Model
    chained: dict[str, Delivery]
    task_ns: TaskTimes | None = None
    scheduled: frozenset[str] = frozenset()

    def activations(self, task: model.Task, seen: frozenset[str] = frozenset()) -> Runs | None:
        """A task's starts: on its own clock or trigger at its period, or at its message's deliveries; None when
        no rate bounds them."""
        if task.on_message is not None:
            return self.arrivals(self.m.messages[task.on_message], seen)
        slowest = task_period(self.m, task)
        if not slowest:
            return None
        fastest = self.m.triggers[task.trigger].interval_ns if task.trigger is not None else slowest
        return Runs(fastest, slowest, 0)

    def arrivals(self, msg: model.Message, seen: frozenset[str] = frozenset()) -> Runs | None:
        """A message's deliveries: its releases, moved by its release jitter (the spec's and its senders'
        response variation, unless a schedule sends it) and by its delivery's variation."""
        every, d = self.renewal(msg, seen), self.chained.get(msg.name)
        variation = 0 if msg.name in self.scheduled else self.send_variation(msg)
        if every is None or not msg.interval_ns or d is None or d.worst_ns is None or variation is None:
            return None
        jitter = 0 if msg.name in self.scheduled else msg.jitter_ns
        return Runs(msg.interval_ns, every, jitter + variation + d.worst_ns - d.best_ns)

    def start_spacing(self, msg: model.Message) -> int | None:
        """How far apart the starts of a task this message starts may be; None when no rate bounds them."""
        runs = self.arrivals(msg)
        return None if runs is None else runs.slowest + runs.spread

    def send_variation(self, msg: model.Message) -> int | None:
        """How much later than its fastest a task that sends the message as it ends may end: its response less
        its BCET (the slowest sender's); None when one's response is unbounded."""
        out = 0
        for ref in sending_tasks(self.m, msg):
            task = self.m.task(ref)
            busy = task_response(task, self.task_ns)
            if busy is None:
                return None
            out = max(out, busy - task.bcet_ns)
        return out

    def renewal(self, msg: model.Message, seen: frozenset[str] = frozenset()) -> int | None:
        """The longest nominal time between two of a message's releases; None when no rate bounds it. A sporadic
        message that tasks send as they end goes at most once per minimum inter-arrival time, so a run may send
        nothing and the next release comes with the next run that does (send_spacing; the senders' response
        variation and the spec's jitter come on top, as for any task-sent message); one sent on its own is taken
        at its minimum inter-arrival time (all that is known, as netcfg.sim releases it)."""
        if msg.kind != "sporadic":
            return message_period(msg)
        senders = sending_tasks(self.m, msg)
        if not senders:
            return msg.interval_ns
        if len(senders) == 1:
            return self.send_spacing(msg, self.m.task(senders[0]), seen)
        # several: after any send, each sender's first run to end the minimum inter-arrival time later sends
        # (unless another did in between); it starts up to one of its spacings (and spread) after that time less
        # its BCET, and ends up to its response later (the senders' starts are not one sequence: counted whole)
        if msg.name in seen or msg.interval_ns is None:
            return None
        gaps = []
        for ref in senders:
            task = self.m.task(ref)
            runs, busy = self.activations(task, seen | {msg.name}), task_response(task, self.task_ns)
            if runs is not None and busy is not None:
                gaps.append(msg.interval_ns + runs.slowest + runs.spread + busy - task.bcet_ns)
        return min(gaps, default=None)

    def send_spacing(self, msg: model.Message, sender: model.Task, seen: frozenset[str] = frozenset()) -> int | None:
        """The longest nominal time between the starts of two runs of `sender` in a row that send `msg` as they
        end. A sporadic message goes at most once per minimum inter-arrival time I: a run that ends sooner than I
        after the last send sends nothing (netcfg.sim skips it), and the data it read waits for the next run that
        does. After a send by run a, run a + n starts no sooner than n * fastest - spread after a's start and ends
        no sooner than its BCET after that, while run a ended up to its response R after its start: run a + n
        surely sends once n * fastest - spread + BCET >= R + I. A task started by a message has no period of its
        own: its runs follow that message's deliveries. With several senders another's sends may hold this one's
        off for ever: None, as when no rate bounds the runs."""
        if msg.name in seen:  # a loop of messages starting the tasks that send each other: no rate is known
            return None
        runs = self.activations(sender, seen | {msg.name})
        if runs is None:
            return None
        if msg.kind == "sporadic" and msg.interval_ns and len(sending_tasks(self.m, msg)) > 1:
            return None
        n = self._runs_to_send(msg, sender, runs)
        return None if n is None else n * runs.slowest + runs.spread

    def shared(self, msg: model.Message) -> bool:
        """Several tasks send a sporadic message: a run's data may leave with another's send (the message carries
        the freshest output of the step before), or wait for one when another sent too recently."""
        return msg.kind == "sporadic" and bool(msg.interval_ns) and len(sending_tasks(self.m, msg)) > 1

    def skips_sends(self, msg: model.Message, sender: model.Task) -> bool:
        """Some run of `sender` may send nothing of the sporadic message it sends as it ends (send_spacing)."""
        if msg.kind != "sporadic" or not msg.interval_ns:
            return False
        runs = self.activations(sender)
        return runs is None or len(sending_tasks(self.m, msg)) > 1 or self._runs_to_send(msg, sender, runs) != 1

    def _runs_to_send(self, msg: model.Message, sender: model.Task, runs: Runs) -> int | None:
        """How many runs after one that sends a sporadic message the sender surely sends it again (1: every
        run); None when that is not bounded (its response unbounded, or its runs not spaced at all)."""
        if msg.kind != "sporadic" or not msg.interval_ns:
            return 1
        busy = task_response(sender, self.task_ns)
        fastest = clocks.shortest_real(runs.fastest, clock_tolerance(self.m))
        if busy is None or fastest <= 0:
            return None
        need = msg.interval_ns + busy - sender.bcet_ns + runs.spread
        return max(1, -(-need // fastest))

    def drops(self, name: str) -> bool:
        """A message some of whose data never goes out: a sporadic one a run of its sender may skip."""
        msg = self.m.messages.get(name)
        return msg is not None and any(self.skips_sends(msg, self.m.task(t)) for t in sending_tasks(self.m, msg))

    def queued_ahead(self, first: str, then: str) -> bool:
        """A message is delivered before another whenever both carry the same data: the same tasks queue both on
        one CAN bus as they end, every run (no send skipped), in a transmit queue by priority, and it wins
        arbitration (resent after an error, it still goes first)."""
        a, b = self.m.messages[first], self.m.messages[then]
        senders = sending_tasks(self.m, a)
        if not senders or senders != sending_tasks(self.m, b) or a.bus != b.bus or not self.m.buses[a.bus].is_can:
            return False
        if {first, then} & self.scheduled or self.m.nodes[a.producer].tx_queue.fifo:
            return False
        if any(self.skips_sends(msg, self.m.task(t)) for msg in (a, b) for t in senders):
            return False
        return arbitration_key(a.id, a.extended) < arbitration_key(b.id, b.extended)

    def sending_runs(self, task: model.Task, nxt: model.FlowStep, period: int | None) -> int | None:
        """How often a task that reads data it did not start with takes it on to the next step: every `period`,
        but a sporadic message it sends leaves only with the runs that send it (send_spacing), and the data a
        run that sent nothing read waits for the next that does (None: no rate bounds them)."""
        if nxt.kind != "message":
            return period
        for name in nxt.refs:
            msg = self.m.messages[name]
            if msg.kind == "sporadic" and task.ref in sending_tasks(self.m, msg) and not self.shared(msg):
                gap = self.send_spacing(msg, task)
                period = None if gap is None or period is None else max(period, gap)
        return period
