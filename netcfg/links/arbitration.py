"""Priority arbitration on a CAN link (classical or FD): every frame's worst-case response time (Davis et al. 2007)
with FIFO transmit queues (can_fifo), release offsets (can_offsets) and the bit-error model, the queues' backlogs,
and what these bounds assume. The protocols over CAN call `analyze_arbitrated` with themselves as its hooks."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from netcfg import links, model
from netcfg.bus_analysis import (
    Analysis,
    BusFrames,
    error_model,
    errors_section,
    frame_times,
    message_row,
    report_deadlines,
    set_verdict,
    us,
)
from netcfg.diagnostics import Collector
from netcfg.spec.units import format_ns
from netcfg.timing import can_errors, can_fifo, can_offsets, can_rta, can_transactions, flows, load
from netcfg.timing.frames import arbitration_key, bits_to_ns


class ArbitrationHooks(Protocol):
    """What the arbitration analysis asks of the protocol over the link (netcfg.protocols.base.Protocol has each,
    a protocol overriding what it adds): named here, in the link layer, so that it does not depend on the layer
    above it."""

    def overhead(self, bus: model.Bus) -> tuple[int, int] | None: ...

    def offsets_unused(self, bus: model.Bus) -> str | None: ...

    def answers(self, m: model.Model, bus: model.Bus) -> dict[str, tuple[str, int]]: ...

    def bound_messages(
        self, m: model.Model, bus: model.Bus, frames: BusFrames, diags: Collector, acc: Analysis
    ) -> dict[str, Any] | None: ...

    def check_tx_queues(self, m: model.Model, bus: model.Bus, rows: list[dict[str, Any]], diags: Collector) -> None: ...

    def extend(
        self, m: model.Model, bus: model.Bus, timings: dict[str, load.FrameTiming], diags: Collector, acc: Analysis
    ) -> dict[str, Any]: ...

    def check_overload(
        self, m: model.Model, bus: model.Bus, timings: dict[str, load.FrameTiming], worst: float, diags: Collector
    ) -> None: ...


def assumptions(bus: model.Bus, fifo_nodes: tuple[str, ...] = ()) -> list[str]:
    """What the bounds of a CAN bus rest on, in the user's terms (the README explains each)."""
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
    return out


def frame_priority(can_id: int, extended: bool, remote: bool) -> int:
    """Sort key of arbitration, lower wins, with the RTR bit: after the identifier (a standard frame's 11 bits,
    an extended frame's 29), the RTR bit is dominant in a data frame and recessive in a remote frame, so a data
    frame wins over a remote frame of its identifier (ISO 11898-1, 10.4.2.2 and 10.8.2). A standard remote frame
    still wins over an extended frame of its base identifier: its IDE bit, dominant, comes before theirs."""
    return arbitration_key(can_id, extended) << 1 | remote


@dataclass(frozen=True)
class ArbitratedFrame(can_rta.CanFrame):
    """A frame as the analyses see it, its priority with the RTR bit (frame_priority)."""

    remote: bool = False

    @property
    def priority_key(self) -> int:
        return frame_priority(self.id, self.extended, self.remote)


def rta_frames(
    msgs: list[model.Message], timings: dict[str, load.FrameTiming], acc: Analysis | None = None
) -> list[can_rta.CanFrame]:
    """The messages as the response-time analysis sees them (worst-case frame times from the load)."""
    return [
        ArbitratedFrame(
            msg.name,
            msg.id,
            msg.extended,
            timings[msg.name].tx_ns,
            msg.interval_ns,
            acc.jitter(msg) if acc else msg.jitter_ns,
            msg.deadline_ns,
            msg.remote,
        )
        for msg in msgs
    ]


def offset_releases(m: model.Model, bus: model.Bus) -> dict[str, tuple[str, int]]:
    """Messages released at a fixed offset of their sender's clock -> (sender, offset): periodic at one period,
    with an offset, and not sent by a task as it finishes (then the task's end, not the offset, releases it). Only
    where the bus's protocol uses offsets (netcfg.protocols.release_offsets asks it)."""
    return {
        msg.name: (msg.producer, msg.offset_ns)
        for msg in bus.messages
        if msg.kind == "periodic"
        and msg.offset_ns is not None
        and msg.period_ns is not None
        and msg.period_ns == msg.interval_ns
        and not flows.sending_tasks(m, msg)
    }


def fifo_senders(m: model.Model, bus: model.Bus) -> dict[str, str]:
    """Message -> its node, for every message sent through a FIFO transmit queue on this bus."""
    return {msg.name: msg.producer for msg in bus.messages if m.nodes[msg.producer].tx_queue.fifo}


def fifo_inputs(
    m: model.Model, bus: model.Bus, released: dict[str, tuple[str, int]]
) -> tuple[dict[str, int], dict[str, int]]:
    """What the FIFO analysis takes of the spec besides the frames: the offsets of the FIFO members released at a
    fixed offset of their node's clock (of `released`, the bus's release offsets), and the depth of each FIFO that
    drops a frame queued into it when full."""
    fifo_of = fifo_senders(m, bus)
    offsets = {name: o for name, (_, o) in released.items() if name in fifo_of}
    drops = {
        node: m.nodes[node].tx_queue.depth for node in set(fifo_of.values()) if m.nodes[node].tx_queue.on_full == "drop"
    }
    return offsets, drops


def bus_responses(
    m: model.Model, bus: model.Bus, frames: list[can_rta.CanFrame], tau: int, released: dict[str, tuple[str, int]]
) -> can_fifo.FifoAnalysis:
    """Every message's response on a CAN bus: FIFO queues (can_fifo, with their members' offsets) around the
    priority-queued analysis, with release offsets (can_offsets) for the priority-queued senders that keep them
    (`released`: the bus's release offsets)."""
    fifo_of = fifo_senders(m, bus)
    offsets = {name: o for name, o in released.items() if name not in fifo_of}
    ppm, errors = bus.clock_tolerance_ppm, error_model(bus)
    fifo_offsets, drops = fifo_inputs(m, bus, released)
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


def command_anchors(
    m: model.Model, bus: model.Bus, released: dict[str, tuple[str, int]], commands: set[str]
) -> dict[str, tuple[str, int]]:
    """The clock each periodic command is released on and its offset there: its sender's, at its offset
    (`released`); a task's end, when the one task that sends it runs at its period (its other messages go with it);
    else its own."""
    out: dict[str, tuple[str, int]] = {}
    for name in sorted(commands):
        msg = m.messages[name]
        if msg.kind != "periodic" or msg.period_ns is None or msg.period_ns != msg.interval_ns:
            continue
        senders = flows.sending_tasks(m, msg)
        if name in released:
            out[name] = released[name]
        elif len(senders) == 1 and m.task(senders[0]).period_ns == msg.period_ns:
            out[name] = (f"task {senders[0]}", 0)
        else:
            out[name] = (f"message {name}", 0)
    return out


def transaction_responses(
    m: model.Model,
    bus: model.Bus,
    proto: ArbitrationHooks,
    frames: list[can_rta.CanFrame],
    timings: dict[str, load.FrameTiming],
    tau: int,
    released: dict[str, tuple[str, int]],
    base: dict[str, can_rta.Response],
) -> dict[str, can_rta.Response]:
    """The bounds with each reply the protocol names held with its command as one transaction (can_transactions),
    where every sender queues by priority; `base` where there is none (or a FIFO queue on the bus)."""
    pairs = proto.answers(m, bus)
    if not pairs or fifo_senders(m, bus) or proto.offsets_unused(bus) is not None:
        return base
    answers = {
        reply: can_transactions.Answer(command, lead, timings[command].nominal_ns)
        for reply, (command, lead) in pairs.items()
    }
    anchors = command_anchors(m, bus, released, {a.command for a in answers.values()})
    return can_transactions.analyse(
        frames, tau, released, anchors, answers, base, bus.clock_tolerance_ppm, error_model(bus)
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


def analyze_arbitrated(
    m: model.Model, bus: model.Bus, diags: Collector, acc: Analysis, proto: ArbitrationHooks
) -> dict[str, Any]:
    """A bus whose frames arbitrate by identifier: every message's bound under priority arbitration (with FIFO
    queues, release offsets and the error model), the protocol adding its own frames, bounds and sections."""
    timings, worst, nominal = load.can_bus_load(bus)
    frame_ns = frame_times(timings)
    rows = [message_row(msg, timings[msg.name]) for msg in bus.messages]
    for row, msg in zip(rows, bus.messages):  # the release jitter analysed: the spec's and its sender's spread
        row["jitter_us"], row["jitter_ns"] = us(acc.jitter(msg)), acc.jitter(msg)
    tau = bits_to_ns(1, bus.bitrate)
    errors = error_model(bus)
    overhead = proto.overhead(bus)
    if errors is not None:
        largest = max([t.tx_ns for t in timings.values()] + ([overhead[0]] if overhead else []), default=0)
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
    released = {} if proto.offsets_unused(bus) is not None else offset_releases(m, bus)
    frames = rta_frames(bus.messages, timings, acc)
    fifo = bus_responses(m, bus, frames, tau, released)
    plain = fifo.responses
    for msg in bus.messages:
        acc.plain[msg.name] = flows.Delivery(frame_ns[msg.name][0], acc.from_release(msg, plain[msg.name].wcrt_ns))
    # the rows' bounds: replies held with their commands; flows and the holistic jitter keep the offset-free ones
    # (a reply's transaction bound counts from its command, not from its own release as a flow's delivery does)
    bounded = plain if acc.jitter_only or worst > 1 else transaction_responses(
        m, bus, proto, frames, timings, tau, released, plain
    )
    out: dict[str, Any] = {
        "name": bus.name,
        "protocol": bus.protocol,
        "bitrate": bus.bitrate,
        **({"data_bitrate": bus.data_bitrate} if bus.data_bitrate is not None else {}),
        "utilization": round(worst, 6),
        "utilization_nominal": round(nominal, 6),
        "errors": errors_section(
            bus, worst + (overhead[0] / overhead[1] if overhead else 0.0), links.of(bus).bits_per_second(bus, timings)
        ),
        "messages": rows,
    }
    section = proto.bound_messages(m, bus, BusFrames(rows, timings, worst), diags, acc)
    if section is not None:
        out.update(section)
    else:
        for row, msg in zip(rows, bus.messages):
            r = bounded[msg.name]
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
        proto.check_tx_queues(m, bus, queues, diags)
        for row in rows:
            if row["name"] in fifo.effective_jitter_ns:
                row["tx_queue"] = "fifo"
    out.update(proto.extend(m, bus, timings, diags, acc))
    proto.check_overload(m, bus, timings, worst, diags)
    report_deadlines(m, bus, rows, diags)
    return out


def check_overload(
    m: model.Model, bus: model.Bus, timings: dict[str, load.FrameTiming], worst: float, diags: Collector
) -> None:
    if load.can_bus_overloaded(bus, timings, worst):
        diags.add(
            "overload",
            f"bus '{bus.name}' is loaded at {worst:.1%} in the worst case, "
            f"{worst - 1:.1%} over its capacity: slow some messages down or raise the bit rate",
            m.source.at(bus.path),
        )
