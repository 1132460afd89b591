"""Model -> Report: bus load and timing analysis for every bus and flow.

The report is plain JSON-ready data in the shape DESIGN.md fixes; timing problems are added to the
diagnostics at the source position of the message, bus or flow they concern.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from netcfg import model
from netcfg.diagnostics import Collector
from netcfg.spec.units import format_ns
from netcfg.timing import can_errors, can_fifo, can_offsets, can_rta, flows, load
from netcfg.timing.frames import bits_to_ns, frame_bits

# The analyses of FTT-CAN, CANopen's SYNC cycle, Ethernet and node CPUs are imported by the functions that run them:
# a spec that has none of these loads none of them.
if TYPE_CHECKING:
    from netcfg.timing import canopen_sync, ethernet, ftt


def us(ns: float | int | None) -> float | None:
    return None if ns is None else round(ns / 1000, 3)


class _Analysis:
    """Per-bus results that flows need: how each message delivers data, and the FTT-CAN schedules."""

    def __init__(self) -> None:
        self.chained: dict[str, flows.Delivery] = {}  # as analysed on its own bus (FTT windows, RTA, links)
        self.plain: dict[str, flows.Delivery] = {}  # the same bus as plain, unsynchronised CAN
        self.ftt: dict[str, flows.FttTimes] = {}
        self.canopen: dict[str, flows.SyncTimes] = {}
        self.task_ns: dict[str, int | None] = {}  # node.task -> worst-case response time on its processor
        self.task_wcrt: dict[str, int | None] = {}  # the same from the task's nominal release (jitter included)
        self.extra_jitter: dict[str, int] = {}  # message -> release jitter its sending task's response adds

    def jitter(self, msg: model.Message) -> int:
        """A message's release jitter: the spec's, plus its sending task's response-time variation."""
        return msg.jitter_ns + self.extra_jitter.get(msg.name, 0)

    def from_release(self, msg: model.Message, wcrt: int | None) -> int | None:
        """A response time from the message's actual queueing (flows count the sending task's variation)."""
        return None if wcrt is None else wcrt - self.extra_jitter.get(msg.name, 0)


MAX_HOLISTIC_ROUNDS = 50  # rounds of the sender-jitter iteration between processors and buses


def analyze(m: model.Model, diags: Collector) -> dict[str, Any]:
    """Buses, processors and flows. A message that a task sends as it finishes is released with that task's
    response-time variation as jitter, which in turn may delay tasks started by messages: the two are iterated
    from zero jitter until nothing grows (holistic analysis, Tindell and Clark 1994); the last round reports."""
    acc = _Analysis()
    acc.extra_jitter = holistic_jitter(m)
    return _analyze_once(m, diags, acc)


def holistic_jitter(m: model.Model) -> dict[str, int]:
    """Each task-sent message's release jitter beyond the spec's, at the fixed point of the holistic iteration
    (analyze's; --explain and tune read the same figures)."""
    extra: dict[str, int] = {}
    if any(_sent_by_task(m, msg) for msg in m.messages.values()):
        for _ in range(MAX_HOLISTIC_ROUNDS):
            acc = _Analysis()
            acc.extra_jitter = extra
            _analyze_once(m, Collector(), acc)
            grown = sender_jitter(m, acc)
            if grown == extra:
                break
            extra = grown
    return extra


def analysis_jitter(m: model.Model) -> _Analysis:
    """An analysis context that carries only the holistic release jitter, for rta_frames outside analyze."""
    acc = _Analysis()
    acc.extra_jitter = holistic_jitter(m)
    return acc


def _sent_by_task(m: model.Model, msg: model.Message) -> bool:
    """Queued by a task as it finishes (not by an FTT-CAN schedule or a CANopen SYNC)."""
    if msg.window == "sync" or msg.implicit or (msg.pdo is not None and 1 <= msg.pdo.transmission <= 240):
        return False
    return bool(flows.sending_tasks(m, msg))


def sender_jitter(m: model.Model, acc: _Analysis) -> dict[str, int]:
    """Each task-sent message's extra release jitter: its slowest sender's response minus its BCET."""
    out = {}
    for msg in m.messages.values():
        if not _sent_by_task(m, msg):
            continue
        spread = 0
        for ref in flows.sending_tasks(m, msg):
            r = acc.task_wcrt.get(ref)
            if r is not None:
                spread = max(spread, r - m.task(ref).bcet_ns)
        if spread:
            out[msg.name] = spread
    return out


def _analyze_once(m: model.Model, diags: Collector, acc: _Analysis) -> dict[str, Any]:
    buses = []
    for bus in m.buses.values():
        if bus.protocol == "ethernet-udp":
            buses.append(analyze_ethernet(m, bus, diags, acc))
        else:
            buses.append(analyze_can(m, bus, diags, acc))
    for row, bus in zip(buses, m.buses.values()):
        row["assumes"] = assumptions(bus, tuple(q["node"] for q in row.get("tx_queues", ())))
        check_offsets(m, bus, diags)
        warn_if_nothing_analysed(m, bus, diags)
    nodes = [analyze_node(m, node, acc, diags) for node in m.nodes.values() if node.tasks]
    return {"buses": buses, "nodes": nodes, "flows": [analyze_flow(m, f, acc, diags) for f in m.flows.values()]}


def warn_if_nothing_analysed(m: model.Model, bus: model.Bus, diags: Collector) -> None:
    """A bus whose every message is on-demand carries no analysed load: its 0.0 % and the verdict say nothing of
    its timing (a DBC without cycle times imports that way), which a user must not read as a pass."""
    if not bus.messages or any(msg.kind != "on-demand" for msg in bus.messages):
        return
    if any(d.code == "dbc-not-analysed" for d in diags.items):  # check F.dbc: each message has said so already
        return
    diags.add(
        "not-analysed",
        f"bus '{bus.name}': all {len(bus.messages)} of its messages are on-demand, so nothing on it is analysed and "
        "its 0.0 % load says nothing of its timing; give its messages a period (or min_interarrival for sporadic "
        "ones), or for a DBC assume one with --default-period T (check, import dbc, init --from dbc)",
        m.source.at(bus.path),
        "warning",
    )


def assumptions(bus: model.Bus, fifo_nodes: tuple[str, ...] = ()) -> list[str]:
    """What the bounds of this bus rest on, in the user's terms (the README explains each)."""
    if bus.protocol == "ethernet-udp":
        from netcfg.timing.ethernet import QUEUE_FRAMES

        return [
            "full-duplex links; store-and-forward switches with FIFO egress queues, each switch's latency as given; "
            f"every NIC's and egress port's queue as deep as given ({QUEUE_FRAMES} frames unless the spec says), "
            "never filled (the check refuses a backlog above it)",
            "each message released at most once per period (or rate) with at most its jitter; upstream queueing "
            "adds to the jitter seen downstream; frames that reach a port over one link come one after another",
            "no frame loss and no other traffic than the spec's",
        ]
    queues = (
        "every node queues its frames by priority (no FIFO transmit buffer, no priority inversion in the controller)"
    )
    if fifo_nodes:
        queues = (
            f"{', '.join(fifo_nodes)} queue{'s' if len(fifo_nodes) == 1 else ''} frames in FIFO order (at most one "
            "frame of each message in the queue at a time), every other node by priority"
        )
    out = [
        f"{queues}; worst-case bit stuffing",
        "periodic messages released at most once per (fastest) period, sporadic ones at most once per minimum "
        "inter-arrival time, each at most its jitter late",
        f"every sender's clock within +-{bus.clock_tolerance_ppm} ppm of nominal (clock_tolerance): periods are "
        "counted at the fastest clocks"
        if bus.clock_tolerance_ppm
        else "every sender's clock exact (clock_tolerance 0): periods are counted as nominal",
        "no bus errors, hence no retransmissions (the bus states no error model)"
        if bus.errors is None
        else "bit errors: "
        + can_errors.describe(bus.errors.burst, format_ns(bus.errors.interval_ns))
        + f", each an error frame of up to {can_errors.ERROR_FRAME_BITS} bits and a retransmission",
    ]
    if bus.ftt is not None:
        out += [
            "the master keeps an exact EC grid; triggered tasks start when the trigger message ends; synchronous "
            "messages are queued at their window's start and go out in identifier order",
            "inside a period_range the master may use any period, keeping the message's init EC",
            "an asynchronous frame starts only if it ends before the next window (inserted idle time), a resend "
            "after a bit error too",
        ]
    return out


def activation(m: model.Model, task: model.Task, acc: _Analysis) -> tuple[int | None, int | None]:
    """(shortest interval, jitter) of a task's activations; jitter None when its message has no bound."""
    if task.on_message is not None:
        d = acc.chained.get(task.on_message)
        if d is None or d.worst_ns is None:
            return m.messages[task.on_message].interval_ns, None
        # the message's response jitter from its nominal release: its delivery's spread, and the release jitter its
        # sending task's response adds (Tindell and Clark 1994: an activated task inherits its message's jitter)
        inherited = d.worst_ns - d.best_ns + acc.extra_jitter.get(task.on_message, 0)
        return m.messages[task.on_message].interval_ns, inherited
    if task.trigger is not None:
        return m.triggers[task.trigger].interval_ns, 0
    if task.sync_bus is not None and task.sync_bus in acc.canopen:
        loop = acc.canopen[task.sync_bus].master
        if loop is not None and task.node == loop.node:  # the SYNC producer's loop keeps k T + offset (MasterLoop)
            return task.period_ns, loop.jitter_ns
        sync = acc.canopen[task.sync_bus].sync  # the SYNC frame may be held up by arbitration (or a FIFO queue)
        return task.period_ns, None if sync.worst_ns is None else sync.worst_ns - sync.best_ns
    return task.period_ns, 0


def analyze_node(m: model.Model, node: model.Node, acc: _Analysis, diags: Collector) -> dict[str, Any]:
    """Response time of each task on the node's processor; a node above 100 % is an error."""
    from netcfg.timing import cpu

    tasks = []
    unbounded_input = set()
    for task in node.tasks.values():
        interval, jitter = activation(m, task, acc)
        if jitter is None:
            unbounded_input.add(task.name)
        tasks.append(cpu.CpuTask(task.name, task.wcet_ns, interval, jitter or 0, task.priority))
    load_ = cpu.utilisation(tasks)
    overloaded = cpu.overloaded(tasks)
    if overloaded:
        diags.add(
            "cpu-overload",
            f"node '{node.name}' needs {load_:.1%} of its processor for its tasks ({load_ - 1:.1%} too much): "
            "shorten their execution times or lengthen their periods",
            m.source.at(node.path),
        )
    response = cpu.analyse(tasks, node.scheduling)
    for t in tasks:
        if response[t.name] is None and not overloaded and t.name not in unbounded_input:
            diags.add(
                "task-unbounded",
                f"task '{node.name}.{t.name}' has no bounded response time: the tasks at its priority and above "
                "fill the processor (exactly 100 % with jitter or blocking); shorten a WCET or lower a rate",
                m.source.at(node.tasks[t.name].path),
            )
    rows = []
    for rank, t in enumerate(cpu.priority_order(tasks)):
        r = None if t.name in unbounded_input else response[t.name]
        # flows time a task from its actual activation, whose lateness they already count: R - J
        acc.task_ns[f"{node.name}.{t.name}"] = None if r is None else r - t.j_ns
        acc.task_wcrt[f"{node.name}.{t.name}"] = r
        rows.append(
            {
                "name": t.name,
                "priority": rank,
                "wcet_us": us(t.c_ns),
                "interval_us": us(t.t_ns),
                "jitter_us": us(t.j_ns),
                "wcrt_us": us(r),
            }
        )
    return {"name": node.name, "scheduling": node.scheduling, "utilization": round(load_, 6), "tasks": rows}


def message_row(msg: model.Message, t: load.FrameTiming) -> dict[str, Any]:
    row = {
        "name": msg.name,
        "id": msg.id,
        "extended": msg.extended,
        "size": msg.size,
        "kind": msg.kind,
        "producer": msg.producer,
        "consumers": list(msg.consumers),
        "period_us": us(msg.period_ns),
        "interval_us": us(msg.interval_ns),
        "offset_us": us(msg.offset_ns),
        "frame_bits_worst": t.bits_worst,
        "frame_bits_nominal": t.bits_nominal,
        "tx_us": us(t.tx_ns),
        "frame_us_worst": us(t.tx_ns),
        "utilization": round(t.utilization, 6),
        "wcrt_us": None,
        "wcrt_ns": None,  # exact, for runtime.json
        "deadline_us": us(msg.deadline_ns),
        "slack_us": None,
        "schedulable": None,
    }
    if t.fd_worst is not None:  # CAN FD: the padded length, and how many of the worst-case bits are at the data rate
        row.update(fd=True, brs=msg.brs, frame_size=msg.frame_size, frame_bits_worst_data_phase=t.fd_worst.data)
    return row


def set_verdict(row: dict[str, Any], wcrt_ns: int | None, deadline_ns: int | None) -> None:
    row["wcrt_us"] = us(wcrt_ns)
    row["wcrt_ns"] = wcrt_ns
    if deadline_ns is None:
        return
    row["schedulable"] = wcrt_ns is not None and wcrt_ns <= deadline_ns
    row["slack_us"] = None if wcrt_ns is None else us(deadline_ns - wcrt_ns)


def report_deadlines(m: model.Model, bus: model.Bus, rows: list[dict[str, Any]], diags: Collector) -> None:
    by_name = {msg.name: msg for msg in bus.messages}
    for row in rows:
        if row["schedulable"] is False and row.get("unbounded") != "dropped":  # check_tx_queues names those
            msg = by_name[row["name"]]
            if row["wcrt_us"] is None and row.get("unbounded") == "iterations":
                text = (
                    f"message '{msg.name}' has no worst-case response time within {can_rta.MAX_ITERATIONS:,} "
                    "steps of the analysis: the traffic at its priority is so close to 100% of the capacity that "
                    "its busy period is too long to follow"
                )
            elif row["wcrt_us"] is None and row.get("unbounded") == "fifo" and row.get("tx_queue") == "fifo":
                text = (
                    f"message '{msg.name}' has no bounded worst-case response time: its sender's FIFO transmit "
                    "queue has no bound (one of its messages, or of a FIFO above it, waits longer than its period, so "
                    "two of its frames can be queued at once)"
                )
            elif row["wcrt_us"] is None and row.get("unbounded") == "fifo":
                text = (
                    f"message '{msg.name}' has no bounded worst-case response time: another node's FIFO transmit "
                    "queue with a message above it has no bound (a member waits longer than its period), so its "
                    "frames reach arbitration at no bounded time; see that queue in the bus's tx_queues"
                )
            elif row["wcrt_us"] is None:
                text = (
                    f"message '{msg.name}' has no bounded worst-case response time: the traffic at its "
                    "priority or on its path reaches 100% of the capacity"
                    + (
                        f" when the senders' clocks run {bus.clock_tolerance_ppm} ppm fast (the bus's clock_tolerance)"
                        if bus.clock_tolerance_ppm and bus.protocol != "ethernet-udp"
                        else ""
                    )
                )
            else:
                text = (
                    f"message '{msg.name}' can take {row['wcrt_us']:g} us, {-row['slack_us']:g} us past its "
                    f"deadline of {row['deadline_us']:g} us"
                )
            diags.add(
                "deadline", text + "; lower the load, raise its priority or relax the deadline", m.source.at(msg.path)
            )


def rta_frames(
    msgs: list[model.Message], timings: dict[str, load.FrameTiming], acc: _Analysis | None = None
) -> list[can_rta.CanFrame]:
    """The messages as the response-time analysis sees them (worst-case frame times from the load)."""
    return [
        can_rta.CanFrame(
            msg.name,
            msg.id,
            msg.extended,
            timings[msg.name].tx_ns,
            msg.interval_ns,
            acc.jitter(msg) if acc else msg.jitter_ns,
            msg.deadline_ns,
        )
        for msg in msgs
    ]


def release_offsets(m: model.Model, bus: model.Bus) -> dict[str, tuple[str, int]]:
    """Messages released at a fixed offset of their sender's clock -> (sender, offset): periodic at one period,
    with an offset, and not sent by a task as it finishes (then the task's end, not the offset, releases it).
    CANopen and Ethernet buses have none (model.Bus.offsets_unused says why)."""
    if bus.offsets_unused is not None:
        return {}
    return {
        msg.name: (msg.producer, msg.offset_ns)
        for msg in bus.messages
        if msg.kind == "periodic"
        and msg.offset_ns is not None
        and msg.period_ns is not None
        and msg.period_ns == msg.interval_ns
        and not flows.sending_tasks(m, msg)
    }


def offset_ignored(m: model.Model, bus: model.Bus, msg: model.Message) -> tuple[str, str] | None:
    """(why, what to do) when the analysis that bounds `msg` cannot use the offset the spec gave it; None when it
    has none or it is used (release_offsets takes it, or FTT-CAN's schedule takes it as the first EC)."""
    if msg.offset_ns is None or msg.offset_auto or msg.implicit:  # SYNC and heartbeats: netcfg's own
        return None
    if (why := bus.offsets_unused) is not None:
        return why, "its bounds hold for any offset; drop it"
    if msg.window == "sync":
        return None
    if senders := flows.sending_tasks(m, msg):
        return (
            f"task '{senders[0]}' sends it as it finishes (a step before it in a flow), so the task's end releases it",
            f"drop the offset, or give the task '{senders[0]}' the offset instead",
        )
    if msg.window == "async":
        return (
            "FTT-CAN's asynchronous window is analysed with every release at any phase",
            "drop the offset, or make it synchronous (window: sync), where the offset is its first EC",
        )
    return None


def check_offsets(m: model.Model, bus: model.Bus, diags: Collector) -> None:
    """A warning for each offset the analysis of this bus cannot use, and for each sender whose offsets unroll
    into more releases than the offset analysis follows (it then takes them at any phase)."""
    for msg in bus.messages:
        if (ignored := offset_ignored(m, bus, msg)) is not None:
            why, fix = ignored
            diags.add(
                "offset-unused",
                f"the analysis does not use the offset {format_ns(msg.offset_ns or 0)} of '{msg.name}': {why}; "
                f"{fix}",
                m.source.at((*msg.path, "offset")),
                "warning",
            )
    offsets = release_offsets(m, bus)
    # where can_offsets or a FIFO queue (within the same limit) gives the bound: not in FTT-CAN's windows (the
    # master's schedule uses synchronous offsets)
    periods = {msg.name: msg.period_ns for msg in bus.messages if msg.name in offsets and msg.window is None}
    for node, names in can_offsets.too_long({n: (offsets[n][0], t) for n, t in periods.items() if t}).items():
        first = m.messages[names[0]]
        diags.add(
            "offset-unused",
            f"the analysis does not use the offsets of node '{node}' ({', '.join(repr(n) for n in names)}): their "
            f"periods' hyperperiod unrolls into more than {can_offsets.MAX_JOBS} releases, so they are taken at any "
            "phase; choose periods that divide each other (harmonic), or drop the offsets",
            m.source.at((*first.path, "offset")),
            "warning",
        )


def error_model(bus: model.Bus) -> can_errors.ErrorModel | None:
    """The bus's bit-error model as the timing core takes it; None: an error-free bus."""
    if bus.errors is None:
        return None
    return can_errors.ErrorModel.for_bus(bus.errors.burst, bus.errors.interval_ns, bus.bitrate)


DEFAULT_BER = 1e-6  # the schema's default `ber`: what a bus without an error model is rated against


def errors_section(
    bus: model.Bus, utilization: float, timings: dict[str, load.FrameTiming] | None = None
) -> dict[str, Any]:
    """The bus's error assumption and how likely its environment is to break it in an hour. A bit error can hit
    any bit on the wire: on CAN FD the data phase sends more bits per second than the nominal rate, so there they
    are counted frame by frame."""
    em = error_model(bus)
    ber = bus.errors.ber if bus.errors is not None else DEFAULT_BER
    rate = can_errors.errors_per_second(ber, bus.bitrate, utilization)
    if bus.protocol == "can-fd" and timings is not None:
        bits_per_s = sum(
            timings[msg.name].bits_worst * 1e9 / msg.interval_ns
            for msg in bus.messages
            if msg.interval_ns and msg.kind != "on-demand"
        )
        rate = max(rate, ber * bits_per_s)
    p = can_errors.exceed_probability(rate, em.burst if em else None, em.interval_ns if em else 1)
    out: dict[str, Any] = {
        "model": None
        if em is None
        else {
            "burst": em.burst,
            "interval_us": us(em.interval_ns),
            "error_frame_bits": can_errors.ERROR_FRAME_BITS,
            "error_frame_us": us(em.error_frame_ns),
        },
        "assumption": (
            "error-free bus: no bound allows for a bit error (set the bus's errors: to allow for them)"
            if em is None
            else can_errors.describe(em.burst, format_ns(em.interval_ns))
        ),
        "ber": ber,
        "errors_per_hour": round(rate * 3600, 3),
        "exceed_probability_per_hour": float(f"{p:.3g}"),
    }
    return out


def fifo_senders(m: model.Model, bus: model.Bus) -> dict[str, str]:
    """Message -> its node, for every message sent through a FIFO transmit queue on this bus."""
    return {msg.name: msg.producer for msg in bus.messages if m.nodes[msg.producer].tx_queue.fifo}


def fifo_inputs(m: model.Model, bus: model.Bus) -> tuple[dict[str, int], dict[str, int]]:
    """What the FIFO analysis takes of the spec besides the frames: the offsets of the FIFO members released at a
    fixed offset of their node's clock, and the depth of each FIFO that drops a frame queued into it when full."""
    fifo_of = fifo_senders(m, bus)
    offsets = {name: o for name, (_, o) in release_offsets(m, bus).items() if name in fifo_of}
    drops = {
        node: m.nodes[node].tx_queue.depth for node in set(fifo_of.values()) if m.nodes[node].tx_queue.on_full == "drop"
    }
    return offsets, drops


def bus_responses(
    m: model.Model, bus: model.Bus, frames: list[can_rta.CanFrame], tau: int
) -> can_fifo.FifoAnalysis:
    """Every message's response on a CAN bus: FIFO queues (can_fifo, with their members' offsets) around the
    priority-queued analysis, with release offsets (can_offsets) for the priority-queued senders that keep them."""
    fifo_of = fifo_senders(m, bus)
    offsets = {name: o for name, o in release_offsets(m, bus).items() if name not in fifo_of}
    ppm, errors = bus.clock_tolerance_ppm, error_model(bus)
    fifo_offsets, drops = fifo_inputs(m, bus)
    return can_fifo.analyse(
        frames,
        tau,
        fifo_of,
        lambda fs: can_offsets.analyse(fs, tau, offsets, ppm, errors),
        ppm,
        errors,
        fifo_offsets,
        drops,
    )


def tx_queue_rows(m: model.Model, bus: model.Bus, fifo: can_fifo.FifoAnalysis) -> list[dict[str, Any]]:
    """Each FIFO transmit queue on the bus: its largest bound and its backlog. Under the analysis's premise (each
    member sent within its period) at most one instance of each member is queued at a time, and with offsets only
    the members that can be queued together (can_fifo): the backlog is the most of them."""
    rows = []
    for node, q in fifo.queues.items():
        spec = m.nodes[node].tx_queue
        rows.append(
            {
                "node": node,
                "policy": spec.policy,
                "depth": spec.depth,
                "on_full": spec.on_full,
                "messages": list(q.members),
                "backlog_max": None if q.queue_ns is None else q.backlog,
                "together": list(q.together),
                "by_offsets": q.narrowed,
                "lowest": q.lowest,
                "blocking_us": us(q.blocking_ns),
                "queued_us": us(q.queued_ns),
                "interference_us": us(q.interference_ns),
                "error_us": us(q.error_ns),
                "queue_us": us(q.queue_ns),
                "dropped": [name for name in q.members if name in fifo.dropped],
                **({"unbounded": q.limit} if q.limit else {}),
            }
        )
    return rows


def check_tx_queues(m: model.Model, bus: model.Bus, rows: list[dict[str, Any]], diags: Collector) -> None:
    """A FIFO that can hold more frames than its depth: with drop, the messages whose frames can find it full are
    lost then and have no bound (an error, unless each may be lost); with block, the sending task waits for a
    slot, which no task bound here includes (an error)."""
    for row in rows:
        node = m.nodes[row["node"]]
        backlog = row["backlog_max"]
        if backlog is not None and backlog <= row["depth"]:
            continue
        held = "an unbounded number of" if backlog is None else f"up to {backlog}"
        at = m.source.at((*node.path, "tx_queue"))
        if row["on_full"] == "drop" and backlog is None:  # its members have no bound already: one error each
            diags.add(
                "tx-queue",
                f"node '{node.name}' can have {held} frames in its FIFO transmit queue on bus '{bus.name}', more "
                f"than its depth of {row['depth']}: frames will be dropped; raise the depth or send fewer messages",
                at,
                "warning",
            )
        elif row["on_full"] == "drop":
            on_bus = {msg.name: msg for msg in bus.messages}  # the protocol's own frames (a SYNC) too
            lost = [name for name in row["dropped"] if not on_bus[name].may_be_lost]
            if lost:
                names = ", ".join(f"'{name}'" for name in lost)
                diags.add(
                    "tx-queue",
                    f"node '{node.name}' can have {held} frames in its FIFO transmit queue on bus '{bus.name}', "
                    f"more than its depth of {row['depth']}, and drops a frame queued into it when full: "
                    f"{names} can find it full and be lost, so {'it has' if len(lost) == 1 else 'they have'} no "
                    "response time; raise the depth, keep the messages apart with offsets, or mark each message "
                    "the system can lose with may_be_lost: true",
                    at,
                )
        else:
            diags.add(
                "tx-queue",
                f"node '{node.name}' can have {held} frames in its FIFO transmit queue on bus '{bus.name}', more "
                f"than its depth of {row['depth']}: its sending task blocks, which its response time does not "
                "include; raise the depth, send fewer messages or use on_full: drop",
                at,
            )
    if bus.ftt is None:
        return
    # FTT-CAN's analyses order a node's frames by identifier: the asynchronous window's (priority queues) and the
    # synchronous window's (several synchronous frames of one node in one EC); a FIFO with one synchronous message
    # changes neither
    for row in rows:
        node = m.nodes[row["node"]]
        sent = [msg for msg in bus.messages if msg.producer == node.name]
        if any(msg.window == "async" for msg in sent) or len(sent) > 1:
            diags.add(
                "tx-queue",
                f"node '{node.name}' sends {', '.join(repr(msg.name) for msg in sent)} through a FIFO transmit "
                f"queue on FTT-CAN bus '{bus.name}', whose window analyses assume frames leave in identifier "
                "order: give it tx_queue: priority",
                m.source.at((*node.path, "tx_queue")),
            )


def analyze_can(m: model.Model, bus: model.Bus, diags: Collector, acc: _Analysis) -> dict[str, Any]:
    timings, worst, nominal = load.can_bus_load(bus)
    # (nominal, worst-case) frame time of each message: without and with stuff bits
    frame_ns = {name: (t.nominal_ns, t.tx_ns) for name, t in timings.items()}
    rows = [message_row(msg, timings[msg.name]) for msg in bus.messages]
    for row, msg in zip(rows, bus.messages):  # the release jitter analysed: the spec's and its sender's spread
        row["jitter_us"], row["jitter_ns"] = us(acc.jitter(msg)), acc.jitter(msg)
    tau = bits_to_ns(1, bus.bitrate)
    errors = error_model(bus)
    if errors is not None:
        largest = max([t.tx_ns for t in timings.values()] + ([bus_tm_and_ec(bus)[0]] if bus.ftt else []), default=0)
        recovery = errors.error_frame_ns + largest
        if recovery >= errors.interval_ns:
            diags.add(
                "error-model",
                f"bus '{bus.name}': one bit error costs up to {format_ns(recovery)} (a "
                f"{format_ns(errors.error_frame_ns)} error frame and its longest frame sent again), not less than "
                "the error model's interval of "
                f"{format_ns(errors.interval_ns)}: errors at that rate could keep the bus busy for ever and no bound "
                "holds; lengthen errors.interval",
                m.source.at((*bus.path, "errors", "interval")),
            )
    fifo = bus_responses(m, bus, rta_frames(bus.messages, timings, acc), tau)
    plain = fifo.responses
    for msg in bus.messages:
        acc.plain[msg.name] = flows.Delivery(frame_ns[msg.name][0], acc.from_release(msg, plain[msg.name].wcrt_ns))
    out: dict[str, Any] = {
        "name": bus.name,
        "protocol": bus.protocol,
        "bitrate": bus.bitrate,
        **({"data_bitrate": bus.data_bitrate} if bus.data_bitrate is not None else {}),
        "utilization": round(worst, 6),
        "utilization_nominal": round(nominal, 6),
        "errors": errors_section(bus, worst + (_tm_load(bus) if bus.ftt is not None else 0.0), timings),
        "messages": rows,
    }
    if bus.ftt is not None:
        out["ftt"] = analyze_ftt(m, bus, rows, frame_ns, diags, acc)
        out["utilization_with_tm"] = round(worst + out["ftt"]["tm_overhead"], 6)
        tm_ns, ec_ns = bus_tm_and_ec(bus)
        if load.can_bus_overloaded(bus, timings, worst + tm_ns / ec_ns, extra=(tm_ns, ec_ns)):
            diags.add(
                "overload",
                f"bus '{bus.name}' is loaded at {worst + tm_ns / ec_ns:.1%} in the worst case with its trigger "
                "message, over its capacity: slow some messages down, lengthen the EC or raise the bit rate",
                m.source.at(bus.path),
            )
    else:
        for row, msg in zip(rows, bus.messages):
            r = plain[msg.name]
            # a message the spec allows to lose, that its queue can drop, is promised nothing
            set_verdict(row, r.wcrt_ns, None if r.limit == "dropped" and msg.may_be_lost else msg.deadline_ns)
            row["blocking_us"] = us(r.blocking_ns)
            row["busy_period_us"] = us(r.busy_period_ns)
            row["instances"] = r.instances
            if errors is not None:
                row["error_us"] = us(r.error_ns)
            if r.limit:
                row["unbounded"] = r.limit
            acc.chained[msg.name] = acc.plain[msg.name]
    queues = tx_queue_rows(m, bus, fifo)
    if queues:
        out["tx_queues"] = queues
        check_tx_queues(m, bus, queues, diags)
        for row in rows:
            if row["name"] in fifo.effective_jitter_ns:
                row["tx_queue"] = "fifo"
    if bus.canopen is not None:
        out["sync"] = analyze_sync(m, bus, frame_ns, diags, acc)
    if bus.ftt is None and load.can_bus_overloaded(bus, timings, worst):
        diags.add(
            "overload",
            f"bus '{bus.name}' is loaded at {worst:.1%} in the worst case, "
            f"{worst - 1:.1%} over its capacity: slow some messages down or raise the bit rate",
            m.source.at(bus.path),
        )
    report_deadlines(m, bus, rows, diags)
    return out


def _tm_load(bus: model.Bus) -> float:
    """FTT-CAN: the share of the bus the trigger message takes (its bits can be hit too)."""
    tm_ns, ec_ns = bus_tm_and_ec(bus)
    return tm_ns / ec_ns


def bus_tm_and_ec(bus: model.Bus) -> tuple[int, int]:
    """FTT-CAN: the trigger message's worst-case time and the EC, in ns."""
    from netcfg.timing import ftt

    assert bus.ftt is not None
    return ftt.tm_time_ns(bus.ftt.tm_size, bus.id_bits == 29, bus.bitrate), bus.ftt.ec_ns


def analyze_sync(
    m: model.Model, bus: model.Bus, frame_ns: dict[str, tuple[int, int]], diags: Collector, acc: _Analysis
) -> dict[str, Any]:
    from netcfg.timing import canopen_sync

    co = bus.canopen
    assert co is not None
    # one release model: each message's jitter as the response-time analysis takes it (rta_frames), each TPDO's
    # queueing delay after SYNC as the flows take it
    delays = {msg.name: m.nodes[msg.producer].tx_delay_ns for msg in bus.messages}
    cycles = canopen_sync.analyse(
        bus,
        {name: worst for name, (_, worst) in frame_ns.items()},
        {msg.name: acc.jitter(msg) for msg in bus.messages},
        delays,
        error_model(bus),
    )
    sync_msg = next(msg for msg in bus.messages if msg.implicit == "SYNC")
    bus_msgs = {msg.name: msg for msg in bus.messages}
    loop = canopen_sync.master_loop(m, bus)
    acc.canopen[bus.name] = flows.SyncTimes(
        period_ns=co.sync_period_ns,
        sync=acc.chained[sync_msg.name],
        every=canopen_sync.sync_transmissions(bus),
        frame_ns={name: nominal for name, (nominal, _) in frame_ns.items()},
        completion_ns=[c.completion_ns for c in cycles],
        master=loop,
        release_delay_ns=delays,
        ahead_of_sync=frozenset(
            msg.name
            for msg in bus.messages
            if msg.producer == co.sync_producer and msg is not sync_msg and m.nodes[msg.producer].tx_queue.fifo
        ),
        every_nth_write=frozenset(
            msg.name
            for msg in bus.messages
            if msg.pdo is not None
            and msg.pdo.kind == "rpdo"
            and msg.producer == co.sync_producer
            and msg.kind == "periodic"
            and (msg.period_ns or 0) > co.sync_period_ns
        ),
    )
    check_master_loop(m, bus, loop, diags)
    check_event_timer_periods(m, bus, acc, diags)
    rows = []
    for c in cycles:
        rows.append(
            {
                "cycle": c.index,
                "tpdos": len(c.tpdos),
                "completion_us": us(c.completion_ns),
                "limit_us": us(c.limit_ns),
                "slack_us": None if c.completion_ns is None else us(c.limit_ns - c.completion_ns),
                "fits": c.completion_ns is not None and c.completion_ns <= c.limit_ns,
                "blocking_us": us(c.blocking_ns),
                **({"error_us": us(c.error_ns)} if bus.errors is not None else {}),
                "sync_us": us(c.sync_ns),
                "tpdos_us": us(c.tpdos_ns),
                **({"tx_delay_us": us(c.delay_ns)} if c.delay_ns else {}),
            }
        )
    for c in cycles:
        if c.completion_ns is None or c.completion_ns > c.limit_ns:
            how = (
                "never: the other traffic alone fills the bus"
                if c.completion_ns is None
                else f"{c.completion_ns / 1000:g} us after SYNC, {(c.completion_ns - c.limit_ns) / 1000:g} us too late"
            )
            # a drive's tx_delay that alone takes more than the overshoot is what to change
            late_by = None if c.completion_ns is None else c.completion_ns - c.limit_ns
            slow = [n for n in c.tpdos if late_by is not None and delays[n] == c.delay_ns >= late_by]
            waits = (
                f" ({bus_msgs[slow[0]].producer} queues {slow[0]} its tx_delay of "
                f"{format_ns(c.delay_ns)} after SYNC's reception)"
                if slow
                else ""
            )
            diags.add(
                "sync-cycle",
                f"SYNC cycle {c.index} of bus '{bus.name}': the last of its {len(c.tpdos)} "
                f"synchronous TPDOs completes {how} for {c.limit_name} ({c.limit_ns / 1000:g} us){waits}; lengthen "
                "the cycle, move TPDOs to other cycles (transmission type n > 1)"
                + (", shorten that tx_delay" if slow else "")
                + " or raise the bit rate",
                m.source.at((*bus.path, "canopen")),
            )
            break
    finished = [c.completion_ns for c in cycles if c.completion_ns is not None]
    worst = max(finished) if len(finished) == len(cycles) and finished else None
    # the worst cycle held against each limit the bus has (canopen_sync takes the tightest of them per cycle)
    limits = [
        {
            "name": name,
            "limit_us": us(limit),
            "fits": worst is not None and worst <= limit,
            "margin_us": None if worst is None else us(abs(limit - worst)),
        }
        for name, limit in (
            ("synchronous window (0x1007)", co.sync_window_ns),
            ("master's read window", co.read_window_ns),
            ("communication cycle (0x1006)", co.sync_period_ns),
        )
        if limit is not None
    ]
    master: dict[str, Any] = {
        "node": loop.node,
        "tasks": list(loop.tasks),
        "offset_us": us(loop.offset_ns),
        "bcet_us": us(loop.bcet_ns),
        "wcet_us": us(loop.wcet_ns),
        "jitter_us": us(loop.jitter_ns),
        # the latest its RxPDOs are queued after SYNC (None: right before the next SYNC, the paper's loop)
        "writes_done_us": None if loop.offset_ns is None else us(loop.offset_ns + loop.jitter_ns + loop.wcet_ns),
    }
    return {
        "master": master,
        "period_us": us(co.sync_period_ns),
        "window_us": us(co.sync_window_ns),
        "read_window_us": us(co.read_window_ns),
        "producer": co.sync_producer,
        "cycles_analysed": len(cycles),
        "worst_completion_us": us(worst),
        "limits": limits,
        "max_tpdos_per_cycle": max((len(c.tpdos) for c in cycles), default=0),
        "cycles": rows[:64],
    }


def check_event_timer_periods(m: model.Model, bus: model.Bus, acc: _Analysis, diags: Collector) -> None:
    """An event-driven TPDO taken as periodic (cia301.tpdo_timing: application events every period, which keeps its
    event timer from running out) holds only while a late event still comes before the timer: period + release
    jitter below it. Resolve knew the spec's jitter; the sending task's spread is known here."""
    for msg in bus.messages:
        p = msg.pdo
        if p is None or p.kind != "tpdo" or p.transmission < 254 or not p.event_timer_ms or msg.kind != "periodic":
            continue
        timer, period, jitter = p.event_timer_ms * 1_000_000, msg.period_ns or 0, acc.jitter(msg)
        if period >= timer or period + jitter < timer:
            continue  # the timer alone (on-demand), or the timer is never reached
        diags.add(
            "event-timer",
            f"TPDO '{msg.name}' is written every {format_ns(period)} with up to {format_ns(jitter)} release jitter "
            f"(its sending task's response-time spread), so its {format_ns(timer)} event timer can run out before a "
            "late write, and the two sends come an inhibit time apart: lengthen the event timer beyond "
            f"{format_ns(period + jitter)}, or take the period out and let the inhibit time bound it",
            m.source.at((*msg.path, "pdo", "event_timer")),
        )


def check_master_loop(m: model.Model, bus: model.Bus, loop: canopen_sync.MasterLoop, diags: Collector) -> None:
    """The master's computation must start on complete samples and end before its next SYNC is due."""
    co = bus.canopen
    assert co is not None
    if loop.offset_ns is None:
        return
    where = m.source.at(m.task(loop.tasks[0]).path)
    names = ", ".join(f"'{t}'" for t in loop.tasks)
    if len(loop.tasks) > 1:
        diags.add(
            "master-cycle",
            f"the master has {len(loop.tasks)} SYNC tasks on bus '{bus.name}' ({names}); its loop computes once per "
            "cycle and then writes its RxPDOs: give it one SYNC task per CANopen bus",
            m.source.at(m.task(loop.tasks[1]).path),
        )
        return
    # the master collects for its read window, else the synchronous window, else the whole period (as it runs)
    window = co.read_window_ns or co.sync_window_ns or co.sync_period_ns
    if loop.offset_ns < window:
        diags.add(
            "master-cycle",
            f"the master's SYNC task {names} starts {format_ns(loop.offset_ns)} after SYNC, before the "
            f"{format_ns(window)} read window of bus '{bus.name}' ends: the master computes on the samples it "
            "collected; give it an offset of at least the read window, or a shorter read_window",
            where,
        )
    end = loop.offset_ns + loop.jitter_ns + loop.wcet_ns
    if end > co.sync_period_ns:
        diags.add(
            "master-cycle",
            f"the master's SYNC task {names} on bus '{bus.name}' ends up to {format_ns(end)} after SYNC (offset "
            f"{format_ns(loop.offset_ns)} + master_jitter {format_ns(loop.jitter_ns)} + WCET "
            f"{format_ns(loop.wcet_ns)}), after the next SYNC is due ({format_ns(co.sync_period_ns)}): the master "
            "cannot keep its period; shorten its offset or WCET, or lengthen the SYNC period",
            where,
        )


def analyze_ftt(
    m: model.Model,
    bus: model.Bus,
    rows: list[dict[str, Any]],
    frame_ns: dict[str, tuple[int, int]],
    diags: Collector,
    acc: _Analysis,
) -> dict[str, Any]:
    from netcfg.timing import ftt

    assert bus.ftt is not None
    triggers = [t for t in m.triggers.values() if t.bus == bus.name]
    entries = ftt.srt(bus, triggers)
    try:
        errors = error_model(bus)
        sched = ftt.build_schedule(bus, entries, errors=errors)
        fastest = ftt.build_schedule(bus, entries, fastest=True, errors=errors)
        envelope = ftt.envelope_schedule(bus, entries, errors)
    except ftt.MacroCycleTooLong as exc:
        periods = sorted({e.period_ec for e in entries} | {e.fastest_period_ec for e in entries})
        diags.add(
            "macro-cycle",
            f"the periods of bus '{bus.name}' ({', '.join(map(str, periods))} ECs) make a macro-cycle of "
            f"{exc.ecs:,} ECs; netcfg builds tables of up to {ftt.MAX_MACRO_CYCLE:,}: choose harmonic periods "
            "(multiples of each other)",
            m.source.at((*bus.path, "ftt")),
        )
        tm_ns = ftt.tm_time_ns(bus.ftt.tm_size, bus.id_bits == 29, bus.bitrate)
        return {
            "ec_us": us(bus.ftt.ec_ns),
            "tm_us": us(tm_ns),
            "tm_overhead": round(tm_ns / bus.ftt.ec_ns, 6),
            "lsw_us": us(bus.ftt.lsw_ns),
            "macro_cycle_ec": exc.ecs,
            "srt": [srt_row(e) for e in entries],
        }
    bus.ftt_schedule = sched
    acc.ftt[bus.name] = flows.FttTimes(sched, frame_ns, {e.name: (e.period_ec, e.init_ec) for e in entries})
    for label, s in (("", sched), (" at some periods inside period_range", envelope)):
        for slot in s.slots:
            need = slot.sync_ns + slot.allowance_ns
            if need > s.lsw_ns:
                allowance = f" with {slot.allowance_ns / 1000:g} us for bit errors" if slot.allowance_ns else ""
                diags.add(
                    "lsw",
                    f"EC {slot.index}{label} of bus '{bus.name}': the synchronous messages "
                    f"{', '.join(slot.messages)} need {need / 1000:g} us{allowance}, "
                    f"{(need - s.lsw_ns) / 1000:g} us more than the LSW of {s.lsw_ns / 1000:g} us; "
                    "move an offset or lengthen the LSW",
                    m.source.at((*bus.path, "ftt")),
                )
                break
    # synchronous messages: their frame ends within the window of each EC they are due in
    sync_worst: dict[str, int] = {}
    for slot in sched.slots:
        for name in slot.messages:
            end = sched.completion(name, slot.index, frame_ns)[1] + slot.allowance_ns  # retransmissions within
            sync_worst[name] = max(sync_worst.get(name, 0), end)
    async_msgs = [msg for msg in bus.messages if msg.window == "async"]
    async_frames = [
        ftt.AsyncFrame(msg.name, msg.id, frame_ns[msg.name][1], msg.interval_ns, acc.jitter(msg), msg.extended)
        for msg in async_msgs
    ]
    limited: set[str] = set()
    async_worst = ftt.async_response_times(envelope, async_frames, limited, bus.clock_tolerance_ppm, errors)
    for row, msg in zip(rows, bus.messages):
        if msg.window == "sync":
            wcrt = sync_worst.get(msg.name)
            row["window"] = "sync"
            row["ftt_id"] = msg.ftt_id
        else:
            wcrt = async_worst.get(msg.name)
            row["window"] = "async"
            if msg.name in limited:
                row["unbounded"] = "iterations"
        set_verdict(row, wcrt, msg.deadline_ns)
        row["wcrt_plain_can_us"] = us(acc.plain[msg.name].worst_ns)
        row["wcrt_plain_can_ns"] = acc.plain[msg.name].worst_ns  # exact, for runtime.json
        acc.chained[msg.name] = flows.Delivery(frame_ns[msg.name][0], acc.from_release(msg, wcrt))
    worst = max(sched.slots, key=lambda s: (s.sync_ns + s.allowance_ns, -s.index))
    worst_fast = max(fastest.slots, key=lambda s: (s.sync_ns + s.allowance_ns, -s.index))
    tm_ns = sched.tm_ns
    return {
        "ec_us": us(bus.ftt.ec_ns),
        "tm_bits": frame_bits(bus.ftt.tm_size, bus.id_bits == 29).total,
        "tm_us": us(tm_ns),
        "tm_overhead": round(tm_ns / bus.ftt.ec_ns, 6),
        "lsw_us": us(sched.lsw_ns),
        "master": bus.ftt.master,
        "windows": "sync-first" if sched.sync_first else "async-first",
        **({"tm_error_delay_us": us(sched.tm_delay_ns)} if errors is not None else {}),
        "macro_cycle_ec": sched.macro_cycle,
        "srt": [srt_row(e) for e in entries],
        "worst_ec": {
            "index": worst.index,
            "sync_us": us(worst.sync_ns),
            "messages": list(worst.messages),
            "fits": worst.sync_ns + worst.allowance_ns <= sched.lsw_ns,
            **({"error_allowance_us": us(worst.allowance_ns)} if errors is not None else {}),
        },
        "worst_ec_fastest": {
            "index": worst_fast.index,
            "sync_us": us(worst_fast.sync_ns),
            "messages": list(worst_fast.messages),
            "fits": worst_fast.sync_ns + worst_fast.allowance_ns <= fastest.lsw_ns,
        },
        "ecs": [
            {
                "index": s.index,
                "ids": list(s.ids),
                "ec_schedule": ftt.ec_schedule_mask(s),
                "messages": list(s.messages),
                "triggers": list(s.triggers),
                "sync_us": us(s.sync_ns),
                "async_us": us(s.async_ns),
                **({"error_allowance_us": us(s.allowance_ns)} if errors is not None else {}),
            }
            for s in sched.slots
        ],
    }


def srt_row(e: ftt.SrtEntry) -> dict[str, Any]:
    return {
        "id": e.ftt_id,
        "name": e.name,
        "type": e.kind,
        "producer": e.producer,
        "targets": list(e.targets),
        "size": e.size,
        "can_id": e.can_id,
        "c_bits": e.c_bits,
        "c_us": us(e.c_ns),
        "period_ec": e.period_ec,
        "fastest_period_ec": e.fastest_period_ec,
        "init_ec": e.init_ec,
        "deadline_us": us(e.deadline_ns),
    }


def analyze_ethernet(m: model.Model, bus: model.Bus, diags: Collector, acc: _Analysis) -> dict[str, Any]:
    from netcfg.timing import ethernet

    timings = {msg.name: load.udp_timing(msg, bus.bitrate) for msg in bus.messages}
    links, delays = ethernet.analyse(bus, m.nodes, acc.extra_jitter)
    f_max = ethernet.max_min_frame_rate(bus.bitrate)
    worst: dict[str, ethernet.PathDelay] = {}
    for d in delays:
        if d.message not in worst or _later(d, worst[d.message]):
            worst[d.message] = d
    rows = []
    for msg in bus.messages:
        row = message_row(msg, timings[msg.name])
        row["frame_bytes"] = timings[msg.name].bits_worst // 8
        row["rate_hz"] = round(load.rate_hz(msg), 6)
        d = worst[msg.name]
        row["delay_us"] = {
            "pre": us(d.tpre_ns),
            "wait": us(d.twait_ns),
            "frame": us(d.tframe_ns),
            "prop": us(d.tprop_ns),
            "switch": us(d.tswitch_ns),
            "post": us(d.tpost_ns),
            "consumer": d.consumer,
            "hops": len(d.hops),
        }
        set_verdict(row, d.total_ns, msg.deadline_ns)
        best = min(x.tframe_ns + x.tprop_ns for x in delays if x.message == msg.name)
        acc.chained[msg.name] = acc.plain[msg.name] = flows.Delivery(best, d.total_ns)
        rows.append(row)
    link_rows = []
    by_name = {msg.name: msg for msg in bus.messages}
    depths = ethernet.queue_depths(bus, m.nodes)
    for ll in links:
        n = len(ll.senders)
        # f_transm of a sender on this link: the rate of all its messages there (seed 001: f_transm < f_max / n)
        per_sender: dict[str, float] = {}
        for name in ll.messages:
            msg = by_name[name]
            per_sender[msg.producer] = per_sender.get(msg.producer, 0.0) + load.rate_hz(msg)
        f_transm = max(per_sender.values(), default=0.0)
        link_rows.append(
            {
                "from": ll.src,
                "to": ll.dst,
                "messages": ll.messages,
                "senders": n,
                "f_transm_hz": round(f_transm, 3),
                "frames_per_s": round(ll.frames_per_s, 3),
                "utilization": round(ll.utilization, 6),
                "f_max_hz": round(f_max, 3),
                "f_max_per_sender_hz": round(f_max / n, 3),
                "busy_period_us": us(ll.busy_period_ns),
                "backlog_frames": None if ll.queue is None else ll.queue.backlog,
                "queue_frames": depths[(ll.src, ll.dst)].depth,
                "ok": ll.utilization < 1 and _queue_holds(m, bus, ll, depths[(ll.src, ll.dst)], diags),
            }
        )
        if ll.utilization >= 1:
            diags.add(
                "link-overload",
                f"link {ll.src} -> {ll.dst} on bus '{bus.name}' must carry "
                f"{ll.frames_per_s / 1000:.2f} kHz of frames, {ll.utilization:.1%} of its capacity "
                f"({ll.utilization - 1:.1%} too much): with {n} senders, f_transm must stay below "
                f"f_max/n = {f_max / n / 1000:.2f} kHz but one sends at {f_transm / 1000:.2f} kHz",
                m.source.at(bus.path),
            )
    report_deadlines(m, bus, rows, diags)
    return {
        "name": bus.name,
        "protocol": bus.protocol,
        "bitrate": bus.bitrate,
        "utilization": round(max((ll.utilization for ll in links), default=0.0), 6),
        "messages": rows,
        "min_frame_us": us(ethernet.min_frame_ns(bus.bitrate)),
        "f_max_hz": round(f_max, 3),
        "links": link_rows,
    }


def _queue_holds(m: model.Model, bus: model.Bus, ll: ethernet.LinkLoad, at: ethernet.QueueAt, diags: Collector) -> bool:
    """A transmit queue that can fill is refused: the frame that finds it full is dropped, which no bound covers."""
    if ll.queue is None or ll.queue.backlog <= at.depth:
        return True
    held = ll.queue.backlog
    if at.switch is None:
        where = (
            f"node '{ll.src}' can have {held} frames at once in its NIC's transmit queue (link {ll.src} -> {ll.dst})"
        )
        fix = f"give the node 'nic_queue: {held}' or more"
        pos = m.source.at((*m.nodes[ll.src].path, "nic_queue"))
    elif at.port is None:
        where = f"switch '{ll.src}' (its port to {ll.dst}) can have {held} frames at once in its egress queue"
        fix = f"give the switch 'queue: {held}' or more"
        pos = m.source.at((*at.switch.path, "queue"))
    else:
        where = f"switch '{ll.src}' port {at.port} (to {ll.dst}) can have {held} frames at once in its egress queue"
        fix = f"give the port 'queue: {held}' or more"
        pos = m.source.at(at.switch.queue_paths[at.port])
    diags.add(
        "queue-overflow",
        f"{where} on bus '{bus.name}', but the queue holds {at.depth}: {held - at.depth} would be dropped; {fix}, "
        "or spread the messages' releases with offsets",
        pos,
    )
    return False


def _later(a: ethernet.PathDelay, b: ethernet.PathDelay) -> bool:
    if a.total_ns is None:
        return b.total_ns is not None
    return b.total_ns is not None and a.total_ns > b.total_ns


def analyze_flow(m: model.Model, flow: model.Flow, acc: _Analysis, diags: Collector) -> dict[str, Any]:
    unsync, delivery = flows.unsynchronised(m, flow, acc.plain, acc.task_ns)
    sync = None
    ftt_bus = next(
        (m.messages[r].bus for s in flow.steps if s.kind == "message" for r in s.refs if m.messages[r].bus in acc.ftt),
        None,
    )
    if ftt_bus is not None:
        sync = flows.synchronised(m, flow, acc.ftt[ftt_bus], acc.chained, acc.task_ns)
    else:
        co_bus = next(
            (
                t.sync_bus
                for s in flow.steps
                if s.kind == "task"
                for r in s.refs
                if (t := m.task(r)).sync_bus in acc.canopen
            ),
            None,
        )
        co_bus = co_bus or next(
            (
                m.messages[r].bus
                for s in flow.steps
                if s.kind == "message"
                for r in s.refs
                if m.messages[r].bus in acc.canopen
            ),
            None,
        )
        if co_bus is not None:
            sync = flows.synchronised_canopen(m, flow, co_bus, acc.canopen[co_bus], acc.chained, acc.task_ns)
    lo: int
    hi: int | None
    if sync:
        lo, hi = sync[0]
    elif ftt_bus is not None:  # free-running steps around FTT-CAN windows: the windows' own delivery times
        lo, hi = flows.unsynchronised(m, flow, acc.chained, acc.task_ns, acc.ftt[ftt_bus])[0]
    else:
        lo, hi = unsync
    out: dict[str, Any] = {
        "name": flow.name,
        "mode": "synchronised" if sync else "unsynchronised",
        "latency_min_us": us(lo),
        "latency_max_us": us(hi),
        "latency_ns": [lo, hi],  # exact, for runtime.json
        "jitter_us": None if hi is None else us(hi - lo),
        "deadline_us": us(flow.deadline_ns),
        "meets_deadline": None if flow.deadline_ns is None else hi is not None and hi <= flow.deadline_ns,
        "unsynchronised": {
            "latency_min_us": us(unsync[0]),
            "latency_max_us": us(unsync[1]),
            "latency_ns": list(unsync),
        },
        "steps": [list(s.refs) if len(s.refs) > 1 else s.refs[0] for s in flow.steps],
    }
    if sync:
        out["synchronised"] = {"latency_min_us": us(sync[0][0]), "latency_max_us": us(sync[0][1])}
        if sync[1]:
            out["synchronised"]["delivery_min_us"] = us(sync[1][0])
            out["synchronised"]["delivery_max_us"] = us(sync[1][1])
    if delivery:
        out["unsynchronised"]["delivery_min_us"] = us(delivery[0])
        out["unsynchronised"]["delivery_max_us"] = us(delivery[1])
    if flow.deadline_ns is not None and (hi is None or hi > flow.deadline_ns):
        how = "is unbounded" if hi is None else f"reaches {hi / 1000:g} us, {(hi - flow.deadline_ns) / 1000:g} us late"
        diags.add(
            "flow-deadline",
            f"flow '{flow.name}' {how} for its deadline of {flow.deadline_ns / 1000:g} us",
            m.source.at(flow.path),
        )
    return out
