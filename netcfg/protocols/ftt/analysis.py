"""The analysis of an FTT-CAN bus (Almeida, Pedreiras and Fonseca; seed 002): the SRT and the EC-schedules of one
macro-cycle, the synchronous window's fit in the LSW, the asynchronous window's response times, and what the windows
require of the nodes' transmit queues. The arbitration analysis of the same bus (netcfg.links.arbitration) gives
each message's bound as plain CAN beside them."""

from __future__ import annotations

from typing import Any

from netcfg import model
from netcfg.bus_analysis import Analysis, BusFrames, error_model, frame_times, set_verdict, us
from netcfg.diagnostics import Collector
from netcfg.timing import flows, ftt, load


def bound_messages(
    m: model.Model, bus: model.Bus, frames: BusFrames, diags: Collector, acc: Analysis
) -> dict[str, Any]:
    """The windows' bounds of every message (written into `frames.rows`), and the bus's load with its trigger
    message."""
    section = analyze_ftt(m, bus, frames.rows, frame_times(frames.timings), diags, acc)
    return {"ftt": section, "utilization_with_tm": round(frames.worst + section["tm_overhead"], 6)}


def check_overload(
    m: model.Model, bus: model.Bus, timings: dict[str, load.FrameTiming], worst: float, diags: Collector
) -> None:
    tm_ns, ec_ns = bus_tm_and_ec(bus)
    if load.can_bus_overloaded(bus, timings, worst + tm_ns / ec_ns, extra=(tm_ns, ec_ns)):
        diags.add(
            "overload",
            f"bus '{bus.name}' is loaded at {worst + tm_ns / ec_ns:.1%} in the worst case with its trigger "
            "message, over its capacity: slow some messages down, lengthen the EC or raise the bit rate",
            m.source.at(bus.path),
        )


def bus_tm_and_ec(bus: model.Bus) -> tuple[int, int]:
    """FTT-CAN: the trigger message's worst-case time and the EC, in ns."""
    assert bus.ftt is not None
    f = bus.ftt
    return ftt.tm_time_ns(f.tm_size, f.tm_extended, bus.bitrate, f.tm_fd, bus.data_bitrate), f.ec_ns


def analyze_ftt(
    m: model.Model,
    bus: model.Bus,
    rows: list[dict[str, Any]],
    frame_ns: dict[str, tuple[int, int]],
    diags: Collector,
    acc: Analysis,
) -> dict[str, Any]:
    assert bus.ftt is not None
    triggers = [t for t in m.triggers.values() if t.bus == bus.name]
    entries = ftt.srt(bus, bus.ftt, triggers)
    try:
        errors = error_model(bus)
        sched = ftt.build_schedule(bus, bus.ftt, entries, errors=errors)
        fastest = ftt.build_schedule(bus, bus.ftt, entries, fastest=True, errors=errors)
        envelope = ftt.envelope_schedule(bus, bus.ftt, entries, errors)
    except ftt.MacroCycleTooLong as exc:
        periods = sorted({e.period_ec for e in entries} | {e.fastest_period_ec for e in entries})
        diags.add(
            "macro-cycle",
            f"the periods of bus '{bus.name}' ({', '.join(map(str, periods))} ECs) make a macro-cycle of "
            f"{exc.ecs:,} ECs; netcfg builds tables of up to {ftt.MAX_MACRO_CYCLE:,}: choose harmonic periods "
            "(multiples of each other)",
            m.source.at((*bus.path, "ftt")),
        )
        tm_ns = bus_tm_and_ec(bus)[0]
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
        "tm_bits": ftt.tm_bits(bus.ftt.tm_size, bus.ftt.tm_extended, bus.ftt.tm_fd).total,
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


def check_tx_queues(m: model.Model, bus: model.Bus, rows: list[dict[str, Any]], diags: Collector) -> None:
    """FIFO transmit queues the windows' analyses cannot take."""
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


ASSUMES = [
    "the master keeps an exact EC grid; triggered tasks start when the trigger message ends; synchronous "
    "messages are queued at their window's start and go out in identifier order",
    "inside a period_range the master may use any period, keeping the message's init EC",
    "an asynchronous frame starts only if it ends before the next window (inserted idle time), a resend "
    "after a bit error too",
]
