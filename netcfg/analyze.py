"""Model -> Report: bus load and timing analysis for every bus and flow.

The report is plain JSON-ready data in the shape DESIGN.md fixes; timing problems are added to the
diagnostics at the source position of the message, bus or flow they concern.
"""

from __future__ import annotations

from typing import Any

from netcfg import model
from netcfg.diagnostics import Collector
from netcfg.timing import ethernet, load
from netcfg.timing.frames import bits_to_ns, can_frame_bits


def us(ns: float | int | None) -> float | None:
    return None if ns is None else round(ns / 1000, 3)


def analyze(m: model.Model, diags: Collector) -> dict[str, Any]:
    buses = [analyze_bus(m, bus, diags) for bus in m.buses.values()]
    return {"buses": buses, "flows": []}


def analyze_bus(m: model.Model, bus: model.Bus, diags: Collector) -> dict[str, Any]:
    if bus.protocol == "ethernet-udp":
        return analyze_ethernet(m, bus, diags)
    timings, worst, nominal = load.can_bus_load(bus)
    out: dict[str, Any] = {
        "name": bus.name,
        "protocol": bus.protocol,
        "bitrate": bus.bitrate,
        "utilization": round(worst, 6),
        "utilization_nominal": round(nominal, 6),
        "messages": [message_row(msg, timings[msg.name]) for msg in bus.messages],
    }
    if bus.ftt is not None:
        tm_bits = can_frame_bits(bus.ftt.tm_size, bus.id_bits == 29)
        tm_ns = bits_to_ns(tm_bits, bus.bitrate)
        out["ftt"] = {
            "ec_us": us(bus.ftt.ec_ns),
            "tm_bits": tm_bits,
            "tm_us": us(tm_ns),
            "tm_overhead": round(tm_ns / bus.ftt.ec_ns, 6),
            "lsw_us": us(bus.ftt.lsw_ns),
        }
        out["utilization_with_tm"] = round(worst + tm_ns / bus.ftt.ec_ns, 6)
    if worst > 1:
        diags.add("overload", f"bus '{bus.name}' is loaded at {worst:.1%} in the worst case; it cannot carry its "
                  "messages: slow some down or raise the bit rate", m.source.at(bus.path))
    return out


def message_row(msg: model.Message, t: load.FrameTiming) -> dict[str, Any]:
    return {
        "name": msg.name,
        "id": msg.id,
        "extended": msg.extended,
        "size": msg.size,
        "kind": msg.kind,
        "producer": msg.producer,
        "period_us": us(msg.period_ns),
        "interval_us": us(msg.interval_ns),
        "min_interarrival_us": us(msg.interval_ns) if msg.kind == "sporadic" else None,
        "frame_bits_worst": t.bits_worst,
        "frame_bits_nominal": t.bits_nominal,
        "tx_us": us(t.tx_ns),
        "utilization": round(t.utilization, 6),
        "wcrt_us": None,
        "deadline_us": us(msg.deadline_ns),
        "slack_us": None,
        "schedulable": None,
    }


def analyze_ethernet(m: model.Model, bus: model.Bus, diags: Collector) -> dict[str, Any]:
    timings = {msg.name: load.udp_timing(msg, bus.bitrate) for msg in bus.messages}
    links, delays = ethernet.analyse(bus, m.nodes)
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
        d = worst.get(msg.name)
        if d is not None:
            row["wcrt_us"] = us(d.total_ns)
            row["delay_us"] = {"pre": us(d.tpre_ns), "wait": us(d.twait_ns), "frame": us(d.tframe_ns),
                               "prop": us(d.tprop_ns), "switch": us(d.tswitch_ns), "post": us(d.tpost_ns),
                               "consumer": d.consumer, "hops": len(d.hops)}
            set_verdict(row, d.total_ns, msg.deadline_ns)
        rows.append(row)
    link_rows = []
    for ll in links:
        n = len(ll.senders)
        link_rows.append({
            "from": ll.src, "to": ll.dst, "messages": ll.messages, "senders": n,
            "frames_per_s": round(ll.frames_per_s, 3), "utilization": round(ll.utilization, 6),
            "f_max_hz": round(f_max, 3), "f_max_per_sender_hz": round(f_max / n, 3),
            "busy_period_us": us(ll.busy_period_ns), "ok": ll.utilization < 1,
        })
        if ll.utilization >= 1:
            sender_rate = max(load.rate_hz(msg) for msg in bus.messages if msg.name in ll.messages)
            diags.add("link-overload", f"link {ll.src} -> {ll.dst} on bus '{bus.name}' must carry "
                      f"{ll.frames_per_s / 1000:.2f} kHz of frames ({ll.utilization:.1%} of its capacity, "
                      f"{ll.utilization - 1:.1%} too much): with {n} senders f_transm must stay below f_max/n = "
                      f"{f_max / n / 1000:.2f} kHz, but one sends at {sender_rate / 1000:.2f} kHz",
                      m.source.at(bus.path))
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


def _later(a: ethernet.PathDelay, b: ethernet.PathDelay) -> bool:
    if a.total_ns is None:
        return b.total_ns is not None
    return b.total_ns is not None and a.total_ns > b.total_ns


def set_verdict(row: dict[str, Any], wcrt_ns: int | None, deadline_ns: int | None) -> None:
    row["wcrt_us"] = us(wcrt_ns)
    if deadline_ns is None:
        return
    row["schedulable"] = wcrt_ns is not None and wcrt_ns <= deadline_ns
    row["slack_us"] = None if wcrt_ns is None else us(deadline_ns - wcrt_ns)


def report_deadlines(m: model.Model, bus: model.Bus, rows: list[dict[str, Any]], diags: Collector) -> None:
    by_name = {msg.name: msg for msg in bus.messages}
    for row in rows:
        if row["schedulable"] is False:
            msg = by_name[row["name"]]
            if row["wcrt_us"] is None:
                text = (f"message '{msg.name}' has no bounded worst-case response time: the traffic at its "
                        "priority or on its path reaches 100% of the capacity")
            else:
                text = (f"message '{msg.name}' can take {row['wcrt_us']:g} us, {-row['slack_us']:g} us past its "
                        f"deadline of {row['deadline_us']:g} us")
            diags.add("deadline", text + "; lower the load, raise its priority or relax the deadline",
                      m.source.at(msg.path))
