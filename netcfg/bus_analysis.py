"""What every bus's analysis shares: the state flows and processors read from the buses' analyses, a message's row
of the report and its verdict, the deadline errors, and the bit-error model's terms. The protocols' analyses
(netcfg.protocols) and the CAN arbitration analysis (netcfg.links.arbitration) build their rows with these."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from netcfg import model
from netcfg.diagnostics import Collector
from netcfg.spec.units import format_ns
from netcfg.timing import can_errors, can_rta, flows, load

FlowBounds = tuple[tuple[int, int], tuple[int, int] | None]  # a flow's (latency, last delivery) range, in ns


def us(ns: float | int | None) -> float | None:
    return None if ns is None else round(ns / 1000, 3)


@dataclass(frozen=True)
class BusFrames:
    """What the arbitration analysis of a CAN bus hands a protocol that bounds the bus's messages itself
    (netcfg.protocols.base.Protocol.bound_messages): the report's rows, one a message in the bus's order, each
    message's frame timing, and the bus's worst-case utilisation."""

    rows: list[dict[str, Any]]
    timings: dict[str, load.FrameTiming]
    worst: float


class Analysis:
    """Per-bus results that flows and processors need: how each message delivers data, the FTT-CAN schedules and
    the CANopen SYNC cycles, the tasks' response times and the release jitter each sending task adds."""

    def __init__(self) -> None:
        self.chained: dict[str, flows.Delivery] = {}  # as analysed on its own bus (FTT windows, RTA, links)
        self.plain: dict[str, flows.Delivery] = {}  # the same bus as plain, unsynchronised CAN
        self.ftt: dict[str, flows.FttTimes] = {}
        self.canopen: dict[str, flows.SyncTimes] = {}
        # a bus whose own cycle flows may keep step with (an EtherCAT master's): its flow model, which gives a flow's
        # (latency, last delivery) in step with that cycle, or None for a flow not in step with it
        self.cycle_flows: dict[str, Callable[[model.Model, model.Flow, Analysis], FlowBounds | None]] = {}
        self.task_ns: dict[str, int | None] = {}  # node.task -> worst-case response time on its processor
        self.task_wcrt: dict[str, int | None] = {}  # the same from the task's nominal release (jitter included)
        self.extra_jitter: dict[str, int] = {}  # message -> release jitter its sending task's response adds
        # a round of the holistic iteration: only what the next round reads (deliveries, task responses) is needed,
        # not the report's bounds that nothing else reads (a reply's transaction bound)
        self.jitter_only = False

    def jitter(self, msg: model.Message) -> int:
        """A message's release jitter: the spec's, plus its sending task's response-time variation."""
        return msg.jitter_ns + self.extra_jitter.get(msg.name, 0)

    def from_release(self, msg: model.Message, wcrt: int | None) -> int | None:
        """A response time from the message's actual queueing (flows count the sending task's variation)."""
        return None if wcrt is None else wcrt - self.extra_jitter.get(msg.name, 0)


def frame_times(timings: dict[str, load.FrameTiming]) -> dict[str, tuple[int, int]]:
    """(nominal, worst-case) frame time of each message: without and with stuff bits."""
    return {name: (t.nominal_ns, t.tx_ns) for name, t in timings.items()}


def message_head(msg: model.Message, *, extended: bool = True) -> dict[str, Any]:
    """The columns that open every bus's message row: who the message is, who sends and reads it, how often."""
    row: dict[str, Any] = {"name": msg.name, "id": msg.id}
    if extended:  # an identifier's format: frames that arbitrate have one
        row["extended"] = msg.extended
    row.update(size=msg.size, kind=msg.kind, producer=msg.producer, consumers=list(msg.consumers),
               period_us=us(msg.period_ns), interval_us=us(msg.interval_ns))
    return row


def message_row(msg: model.Message, t: load.FrameTiming) -> dict[str, Any]:
    row = message_head(msg) | {
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
    if msg.remote:  # a remote frame (RTR): no data field, below the data frame of its identifier
        row["remote"] = True
    return row


def set_verdict(row: dict[str, Any], wcrt_ns: int | None, deadline_ns: int | None) -> None:
    row["wcrt_us"] = us(wcrt_ns)
    row["wcrt_ns"] = wcrt_ns
    if deadline_ns is None:
        return
    row["schedulable"] = wcrt_ns is not None and wcrt_ns <= deadline_ns
    row["slack_us"] = None if wcrt_ns is None else us(deadline_ns - wcrt_ns)


def report_deadlines(
    m: model.Model, bus: model.Bus, rows: list[dict[str, Any]], diags: Collector, clocks_counted: bool = True
) -> None:
    """A deadline error for each message whose bound misses it (`clocks_counted`: the senders' clock tolerance
    shortens the periods the bound counts, as on CAN)."""
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
                        if bus.clock_tolerance_ppm and clocks_counted
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


def error_model(bus: model.Bus) -> can_errors.ErrorModel | None:
    """The bus's bit-error model as the timing core takes it; None: an error-free bus."""
    if bus.errors is None:
        return None
    return can_errors.ErrorModel.for_bus(bus.errors.burst, bus.errors.interval_ns, bus.bitrate)


DEFAULT_BER = 1e-6  # the schema's default `ber`: what a bus without an error model is rated against


def errors_section(bus: model.Bus, utilization: float, bits_per_s: float | None = None) -> dict[str, Any]:
    """The bus's error assumption and how likely its environment is to break it in an hour. A bit error can hit
    any bit on the wire: where a data phase sends more bits per second than the nominal rate, `bits_per_s` (the
    link's count, frame by frame) is the rate they come at."""
    em = error_model(bus)
    ber = bus.errors.ber if bus.errors is not None else DEFAULT_BER
    rate = can_errors.errors_per_second(ber, bus.bitrate, utilization)
    if bits_per_s is not None:
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
