"""Build a simulation from a runtime configuration, run it, and hand the raw records to netcfg.sim.results.

Only netcfg.runtime is read here: whatever the simulator needs, runtime.json must carry, which keeps it complete
for a real master too. What runs:

* every node has its own clock (random phase, drift drawn within +-drift_ppm), so free-running activities slide;
* CAN buses arbitrate frame by frame (netcfg.sim.can_bus); free-running messages (periodic at their period,
  sporadic at their minimum inter-arrival time, the worst case the analysis assumes) come as release streams;
* FTT-CAN buses get their master (netcfg.protocols.ftt.sim), CANopen buses their master cycle and drives
  (netcfg.sim.canopen), Ethernet buses their switches (netcfg.sim.ethernet), EtherCAT segments their cyclic
  frames through the slaves (netcfg.sim.ethercat); with mode "unsync" every CAN bus
  runs as plain, unsynchronised CAN instead, from the same configuration;
* tasks that flows mention run when they are activated (period, trigger, SYNC or message), for a time drawn
  between BCET and WCET, and the flows are measured as data age (netcfg.sim.flows).

Random draws: node clocks, each task's execution times and the Ethernet networks' jitter and receive processing
each come from a generator of their own, seeded from the run's seed and the source's name (Simulator.random); the
CAN buses' draws (jitter, payloads, bit errors, the drives' delays) share the run's generator, Scenario.rng.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from netcfg import protocols
from netcfg.runtime import Bus, Flow, Message, RuntimeConfig, Task
from netcfg.sim import whole_run
from netcfg.sim.can_bus import CanBus
from netcfg.sim.engine import NEVER, TASKS, NodeClock, Simulator
from netcfg.sim.faults import Fault
from netcfg.sim.flows import FlowTracker
from netcfg.sim.run import MasterTiming
from netcfg.sim.streams import PeriodicStreams

if TYPE_CHECKING:
    from netcfg.sim.ethernet import EthernetNetwork

# a task's execution-time draws are taken from its generator this many at a time (_uniforms)
DRAW_BLOCK = 256


@dataclass(frozen=True)
class SimOptions:
    duration_ns: int = 1_000_000_000
    seed: int = 0
    stuffing: str = "worst"  # "exact" | "worst" | "none"
    drift_ppm: float = 50.0
    random_phase: bool = True  # False: every node's clock starts at 0 (offsets as written)
    mode: str = "auto"  # "auto": each bus's own protocol; "unsync": CAN buses run as free-running CAN
    # "pdo": the live master cycle (netcfg.runtime.canopen_master) with the spec's timing; "sdo": concurrent SDO
    # polling loops; "external": only the drives, which answer
    # the SYNCs a program sends through netcfg.sim.pybus (a live master run in virtual time)
    canopen: str = "pdo"
    faults: tuple[Fault, ...] = ()
    trace: bool = False
    master: MasterTiming = field(default_factory=MasterTiming)
    drive_delay_ns: int | None = None  # drives' SYNC -> TPDO queueing delay; None: the node's tx_delay
    # Ethernet: every transmit queue's depth in frames, NICs and switch ports alike (None: each its own from the
    # runtime configuration), and per receiving node the (BCET, WCET) of consuming one frame (None: the node's
    # on_message task for that message, if any)
    eth_queue_frames: int | None = None
    eth_processing_ns: Mapping[str, tuple[int, int]] | None = None
    # compute the run's streams at once where netcfg.sim.whole_run (Ethernet) or a protocol's own (FTT-CAN's,
    # netcfg.protocols.ftt.sim_whole_run) covers it (the same results as event by event);
    # a run that meets a tie only the order of events decides starts again event by event, at worst twice the work
    whole_run: bool = True


@dataclass(frozen=True)
class _TaskPlan:
    ref: str
    node: str
    bcet: int
    wcet: int
    tx_delay: int
    sends: tuple[tuple[str, int], ...]  # (message, its minimum inter-arrival time if sporadic, else 0)
    runs: list[tuple[int, int]]  # Scenario.task_runs of the task
    trackers: tuple[FlowTracker, ...]
    draws: Iterator[float]  # the uniform draws of the task's own generator (Scenario.exec_uniforms)


class Scenario:
    def __init__(self, cfg: RuntimeConfig, opts: SimOptions) -> None:
        self.cfg = cfg
        self.opts = opts
        self._build()

    def _build(self) -> None:
        cfg, opts = self.cfg, self.opts
        self.sim = Simulator(opts.seed)
        rng = self.sim.rng
        self.rng = rng
        self.can: dict[str, CanBus] = {}
        self.msg_source: dict[str, tuple[CanBus, int]] = {}
        self.eth_owner: dict[str, EthernetNetwork] = {}  # Ethernet message -> its network
        # a crash, and a reset drill (its node's boot-up message aside: netcfg.sim.canopen_drills)
        self.crash_at: dict[str, int] = {f.silences: f.at_ns for f in opts.faults if f.silences}
        self.lost: dict[str, int] = {}  # message -> instances that never made it (scripted loss, crash)
        self.protocols: dict[str, object] = {}  # bus -> its protocol driver (FTT master, CANopen master, network)
        self._task_runs: dict[str, list[tuple[int, int]]] = {}  # task -> (start, end) of each run, event by event
        self.task_arrays: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # the same computed whole (whole_run)
        self.sends: dict[str, list[str]] = {}  # task -> messages it sends as it finishes
        self._last_send: dict[str, int] = {}  # sporadic message -> when its task last sent it
        self._plans: dict[int, _TaskPlan] = {}  # id(task) -> what its activations do (run_task)
        self._exec_draws: dict[str, np.random.Generator] = {}  # task -> the generator of its execution times
        self._exec_uniforms: dict[str, Iterator[float]] = {}  # task -> its draws one by one (exec_uniforms)
        self._on_trigger: dict[str, list[Task]] = {}  # trigger -> the tasks it activates that a flow follows
        self._on_sync: dict[str, list[Task]] = {}  # bus -> the same for its SYNC
        # node clocks: a random phase within the node's shortest period (within a longer one, a node with an hourly
        # message would stay silent for most runs), a drift within +-drift_ppm
        self.clock: dict[str, NodeClock] = {}
        # time is the masters' time: an FTT-CAN master or a CANopen SYNC producer starts at 0 and does not drift
        masters = {who for b in cfg.buses if (who := protocols.of(b).sim_master(b)) is not None}
        for node in cfg.nodes:
            periods = [m.interval_ns or 0 for m in cfg.messages if m.producer == node.name]
            periods += [t.period_ns or 0 for t in node.tasks]
            span = min((p for p in periods if p > 0), default=0)
            draw = self.random(f"clock {node.name}")
            phase = int(draw.integers(0, span)) if span > 0 and opts.random_phase else 0
            drift = int(draw.uniform(-opts.drift_ppm, opts.drift_ppm) * 1000)
            if node.name in masters and opts.mode != "unsync":
                phase, drift = 0, 0  # the master's first cycle starts the run
            self.clock[node.name] = NodeClock(phase, drift)
        self.flows = [FlowTracker(cfg, f, self._warm_up(f)) for f in cfg.flows]
        self._flow_refs: dict[str, list[FlowTracker]] = {}
        for tr in self.flows:
            for ref in tr.refs():
                self._flow_refs.setdefault(ref, []).append(tr)
        # tasks that send a message as they end run even where no flow follows them (an actuator's reply task)
        self._senders = {ref for m in cfg.messages for ref in m.sent_by or ()}
        self._message_tasks: dict[str, list[Task]] = {}
        for node in cfg.nodes:
            for task in node.tasks:
                if task.on_message is not None and self._wanted(task):
                    self._message_tasks.setdefault(task.on_message, []).append(task)
        for bus in cfg.buses:
            if bus.is_can:
                self._build_can(bus)
            elif bus.is_udp:
                from netcfg.sim.ethernet import EthernetNetwork

                # chained messages are sent by their flow task (submit), not free-running: known before the build
                for m in cfg.messages_on(bus.name):
                    for ref in m.sent_by or ():
                        self.sends.setdefault(ref, []).append(m.name)
                net = EthernetNetwork(self, bus)
                self.protocols[bus.name] = net
                self.eth_owner.update(dict.fromkeys(net.owned, net))
            elif bus.ethercat is not None:  # an EtherCAT segment: runtime.json's section of it
                from netcfg.sim.ethercat import EthercatSegment

                self.protocols[bus.name] = EthercatSegment(self, bus)
        self._start_free_running_tasks()
        for f in opts.faults:
            f.install(self)
        for can in self.can.values():  # a crashed node stops babbling too
            if can.babble is not None:
                src, start, stop = can.babble
                can.babble = (src, start, min(stop, self.crash_at.get(can.sources[src].producer, NEVER)))

    @property
    def task_runs(self) -> dict[str, list[tuple[int, int]]]:
        """Task -> (start, end) of each of its runs, in activation order (of the tasks a flow follows)."""
        for ref, (start, end) in self.task_arrays.items():  # lists only when asked: 15 kHz tasks make millions
            self._task_runs.setdefault(ref, []).extend(zip(start.tolist(), end.tolist()))
        self.task_arrays.clear()
        return self._task_runs

    def _warm_up(self, flow: Flow) -> int:
        """Flows are measured once every node they involve has started (its clock's phase): data that met a
        consumer not yet running would show a start-up delay no steady state has."""
        nodes = set()
        for step in flow.steps:
            for ref in step.refs:
                if step.kind == "task":
                    nodes.add(ref.split(".", 1)[0])
                else:
                    m = self.cfg.message(ref)
                    nodes.update((m.producer, *m.consumers))
        return max((self.clock[n].phase_ns for n in nodes if n in self.clock), default=0)

    # -- what the protocol drivers call -------------------------------------------------------------------
    @property
    def synchronised(self) -> bool:
        """FTT-CAN and CANopen buses run their protocol (mode "auto"), not as free-running CAN ("unsync")."""
        return self.opts.mode != "unsync"

    def _wanted(self, task: Task) -> bool:
        return task.ref in self._flow_refs or task.ref in self._senders

    def random(self, source: str) -> np.random.Generator:
        return self.sim.random(source)

    def exec_draws(self, ref: str) -> np.random.Generator:
        """The generator of a task's execution times: its k-th activation runs for BCET + floor(u * (WCET - BCET
        + 1)), u its k-th uniform draw (no draw for a fixed time; run_task, exec_ns and whole_run alike)."""
        draws = self._exec_draws.get(ref)
        if draws is None:
            draws = self._exec_draws[ref] = self.random(f"task {ref}")
        return draws

    def exec_uniforms(self, ref: str) -> Iterator[float]:
        """The uniform draws of exec_draws(ref), one by one, for the event path (whole_run takes arrays from the
        generator itself; a run uses one or the other, never both)."""
        draws = self._exec_uniforms.get(ref)
        if draws is None:
            draws = self._exec_uniforms[ref] = _uniforms(self.exec_draws(ref))
        return draws

    def exec_ns(self, task: Task) -> int:
        if task.wcet_ns <= task.bcet_ns:
            return task.wcet_ns
        lo, hi = task.bcet_ns, task.wcet_ns
        return lo + int(next(self.exec_uniforms(task.ref)) * (hi - lo + 1))

    def _plan(self, task: Task) -> _TaskPlan:
        """What every activation of the task does, looked up once (the run's sends and flows are complete by its
        first activation): tasks of fast loops run tens of thousands of times a simulated second."""
        ref = task.ref
        tx = self.cfg.node(task.node).tx_delay_ns
        sends = [(name, self.cfg.message(name).min_gap_ns) for name in self.sends.get(ref, ())]
        plan = _TaskPlan(
            ref, task.node, task.bcet_ns, task.wcet_ns, tx, tuple(sends),
            self._task_runs.setdefault(ref, []), tuple(self._flow_refs.get(ref, ())), self.exec_uniforms(ref),
        )
        self._plans[id(task)] = plan
        return plan

    def run_task(self, task: Task, start: int | None = None) -> None:
        """Activate a task now (or at `start`): it runs for a time between BCET and WCET."""
        sim = self.sim
        t = sim.now
        if start is not None and start > t:
            sim.at(start, self._run_later, task)
            return
        plan = self._plans.get(id(task)) or self._plan(task)
        if t >= self.crash_at.get(plan.node, NEVER):
            for name, _ in plan.sends:
                self.drop(name)  # what the task would have sent is lost with it
            return
        lo, hi = plan.bcet, plan.wcet
        end = t + (hi if hi <= lo else lo + int(next(plan.draws) * (hi - lo + 1)))  # exec_ns, inline
        plan.runs.append((t, end))
        for tr in plan.trackers:
            tr.task_started(plan.ref, t, end)
        if plan.sends:
            send = end + plan.tx_delay
            for name, sporadic in plan.sends:
                if sporadic:
                    if send < self._last_send.get(name, -NEVER) + sporadic:
                        continue  # too soon after the last one: this run raises no event
                    self._last_send[name] = send
                sim.at(send, self._send_chained, name)

    def _run_later(self, task: Task) -> None:
        self.run_task(task)

    def task_ran(self, task: Task, start: int, end: int) -> None:
        """A task that code outside the simulator ran (the live CANopen master's computation), for its flows."""
        plan = self._plans.get(id(task))
        if plan is None:
            if not self._wanted(task):
                return
            plan = self._plan(task)  # its runs and flows, looked up once: the live master reports every cycle
        plan.runs.append((start, end))
        for tr in plan.trackers:
            tr.task_started(plan.ref, start, end)

    def tasks_on_trigger(self, trigger: str) -> list[Task]:
        known = self._on_trigger.get(trigger)
        if known is None:  # asked at every trigger message: found once
            tasks = (self.cfg.task(ref) for ref in self.cfg.trigger(trigger).tasks)
            known = self._on_trigger[trigger] = [t for t in tasks if self._wanted(t)]
        return known

    def tasks_on_sync(self, bus: str) -> list[Task]:
        known = self._on_sync.get(bus)
        if known is None:  # asked at every SYNC: found once
            known = [t for n in self.cfg.nodes for t in n.tasks if t.sync_bus == bus and self._wanted(t)]
            self._on_sync[bus] = known
        return known

    def tasks_on_message(self, message: str) -> list[Task]:
        return self._message_tasks.get(message, [])

    def trackers_of(self, ref: str) -> list[FlowTracker]:
        return self._flow_refs.get(ref, [])

    def alive(self, node: str) -> bool:
        return self.sim.now < self.crash_at.get(node, NEVER)

    def submit(self, message: str, data: bytes | None = None) -> None:
        """A reactive sender queues a frame now (unless it crashed or the frame is scripted to be lost)."""
        if message not in self.msg_source:  # an Ethernet message: its producer's NIC queue
            self.eth_owner[message].submit(message)
            return
        bus, src = self.msg_source[message]
        if not self.alive(bus.sources[src].producer):
            bus.drop(src)
            return
        bus.submit(src, data)

    def _send_chained(self, name: str) -> None:
        self.submit(name)

    def drop(self, message: str) -> None:
        if message in self.msg_source:
            bus, src = self.msg_source[message]
            bus.drop(src)
        else:
            self.lost[message] = self.lost.get(message, 0) + 1

    def listen(self, message: str, fn: Callable[[int, int, int, bytes | None], None]) -> None:
        bus, src = self.msg_source[message]
        bus.listen(src, fn)

    # -- CAN --------------------------------------------------------------------------------------------
    def _build_can(self, bus: Bus) -> None:
        can = CanBus(self.sim, bus.name, bus.bitrate, self.opts.stuffing, self.opts.trace, bus.data_bitrate)
        self.can[bus.name] = can
        # the bus's protocol drives it in a synchronised run (FTT-CAN's master, CANopen's master cycle); unsynchronised,
        # every CAN bus runs free
        proto = protocols.of(bus) if self.synchronised else None
        for m in self.cfg.messages_on(bus.name):
            gated = proto is not None and proto.sim_gated(m)
            src = can.add_source(m.name, m.id, m.extended, m.size, m.producer, gated, m.fd, m.brs, m.fields,
                                 m.remote)
            self.msg_source[m.name] = (can, src)
        for node in self.cfg.nodes:
            if node.tx_queue.fifo and bus.name in node.buses:
                can.fifo_queue(node.name, node.tx_queue.depth, node.tx_queue.on_full == "drop")
        driver = None if proto is None else proto.sim_driver(self, bus, can)
        if driver is not None:
            self.protocols[bus.name] = driver
        owned: set[str] = getattr(driver, "owned", set())
        for m in self.cfg.messages_on(bus.name):
            if m.name not in owned:
                for task in m.sent_by or ():
                    self.sends.setdefault(task, []).append(m.name)
        chained = {name for names in self.sends.values() for name in names}
        free = [
            m for m in self.cfg.messages_on(bus.name)
            if m.name not in owned and m.name not in chained and self._free_running(m)
        ]
        self._add_streams(can, free)
        for m in self.cfg.messages_on(bus.name):
            trackers = self._flow_refs.get(m.name, [])
            tasks = self._message_tasks.get(m.name, [])
            if trackers or tasks:
                can.listen(self.msg_source[m.name][1], self._on_delivery(m, trackers, tasks))

    @staticmethod
    def _free_running(m: Message) -> bool:
        return m.kind in ("periodic", "sporadic") and bool(m.interval_ns)

    def _add_streams(self, can: CanBus, msgs: list[Message]) -> None:
        if not msgs:
            return
        clocks = [self.clock[m.producer] for m in msgs]
        can.add_stream(
            PeriodicStreams(
                sources=[self.msg_source[m.name][1] for m in msgs],
                periods=[m.interval_ns or 0 for m in msgs],
                offsets=[m.offset_ns or 0 for m in msgs],
                phases=[c.phase_ns for c in clocks],
                drifts_ppb=[c.drift_ppb for c in clocks],
                jitters=[m.jitter_ns for m in msgs],
                until=[self.crash_at.get(m.producer, NEVER) for m in msgs],
                rng=self.rng,
                cut=can.dropped,
            )
        )

    def capture_lag(self, m: Message) -> int:
        """How long before its release on a CAN bus a frame took its data: a frame a task sends carries the run that
        ended its producer's tx_delay earlier (the frame is queued then), a free-running one its release's."""
        chained = any(m.name in names for names in self.sends.values())  # queued by its task's end, tx_delay on
        return self.cfg.node(m.producer).tx_delay_ns if chained else 0

    def _on_delivery(
        self, m: Message, trackers: list[FlowTracker], tasks: list[Task]
    ) -> Callable[[int, int, int, bytes | None], None]:
        name = m.name
        started = [(task, self.cfg.node(task.node).rx_delay_ns) for task in tasks]  # and after how long
        lag = self.capture_lag(m)

        def deliver(end: int, _src: int, release: int, _data: bytes | None) -> None:
            for tr in trackers:
                tr.message_delivered(name, release - lag, end)
            for task, rx_delay in started:
                self.run_task(task, end + rx_delay)

        return deliver

    # -- tasks ------------------------------------------------------------------------------------------
    def free_running_tasks(self) -> list[tuple[Task, NodeClock, int]]:
        """(task, its node's clock, period) of the tasks that run on their node's clock: periodic ones; in
        unsynchronised mode, triggered and SYNC tasks too, at their trigger's or SYNC's period (the alternative
        the analysis also reports)."""
        out = []
        for node in self.cfg.nodes:
            clock = self.clock[node.name]
            for task in node.tasks:
                if not self._wanted(task) or task.on_message is not None:
                    continue
                period = task.period_ns
                if (task.trigger is not None or task.sync_bus is not None) and self.synchronised:
                    continue  # its trigger message or its SYNC starts it
                if task.trigger is not None:
                    period = self.cfg.trigger(task.trigger).interval_ns
                elif task.sync_bus is not None:
                    bus = self.cfg.bus(task.sync_bus)
                    period = bus.canopen.sync_period_ns if bus.canopen else period
                if period:
                    out.append((task, clock, period))
        return out

    def _start_free_running_tasks(self) -> None:
        for task, clock, period in self.free_running_tasks():
            self._periodic_task(task, clock, period)

    def _periodic_task(self, task: Task, clock: NodeClock, period: int) -> None:
        k = 0

        def fire(_: object) -> None:
            nonlocal k
            self.run_task(task)
            k += 1
            self.sim.at(clock.to_global(task.offset_ns + k * period), fire, None, TASKS)

        self.sim.at(clock.to_global(task.offset_ns), fire, None, TASKS)

    # -- run --------------------------------------------------------------------------------------------
    def start(self) -> None:
        """Put the first events in place; then run_until() (or a co-simulated program's clock) advances time."""
        for can in self.can.values():
            can.start()
        for driver in self.protocols.values():
            start = getattr(driver, "start", None)
            if start is not None:
                start()

    def run(self) -> None:
        if self.opts.whole_run:
            try:
                order = whole_run.plan(self)
                if order is not None:
                    whole_run.run(self, order)
                    return
                for bus in self.cfg.buses:  # a protocol's own whole run (FTT-CAN's: one bus run as FTT-CAN)
                    whole = protocols.of(bus).sim_whole_run(self)
                    if whole is not None:
                        whole()
                        return
            except whole_run.Undecided:  # rare: a tie only the order of events decides; the event path from 0
                self._build()
        self.start()
        live: list[Any] = [d for d in self.protocols.values() if getattr(d, "live", False)]
        if len(live) == 1:  # the master's loop advances the whole simulation as it waits
            live[0].drive(self.opts.duration_ns)
        elif live:  # several: each in a thread of its own, one at a time (netcfg.sim.pybus)
            from netcfg.sim.pybus import run_programs

            until = self.opts.duration_ns
            run_programs(self, [(d.start_ns, partial(d.drive, until)) for d in live], until)
        self.sim.run_until(self.opts.duration_ns)


def _uniforms(gen: np.random.Generator) -> Iterator[float]:
    """gen.random(), call after call, drawn a block at a time: the same numbers (one next_double of the bit
    generator each, whether one or an array is asked for), without numpy's cost per call (about 1.8 us)."""
    while True:
        yield from gen.random(DRAW_BLOCK).tolist()


def simulate(cfg: RuntimeConfig, opts: SimOptions) -> Scenario:
    sc = Scenario(cfg, opts)
    sc.run()
    return sc


__all__ = ["MasterTiming", "Scenario", "SimOptions", "simulate"]
