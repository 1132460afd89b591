"""The analysis of a switched Ethernet bus carrying UDP (seed 001): every message's delay along its path through
the switches (the NIC's and each egress port's queue), each link's load against f_max, and the queues' backlogs
against their depths."""

from __future__ import annotations

from typing import Any

from netcfg import links, model
from netcfg.bus_analysis import Analysis, message_row, report_deadlines, set_verdict, us
from netcfg.diagnostics import Collector
from netcfg.timing import ethernet, flows, load

ASSUMES = [
    "full-duplex links; store-and-forward switches with FIFO egress queues, each switch's latency as given; "
    f"every NIC's and egress port's queue as deep as given ({ethernet.QUEUE_FRAMES} frames unless the spec says), "
    "never filled (the check refuses a backlog above it)",
    "each message released at most once per period (or rate) with at most its jitter; upstream queueing "
    "adds to the jitter seen downstream; frames that reach a port over one link come one after another",
    "no frame loss and no other traffic than the spec's",
]


def analyze_ethernet(m: model.Model, bus: model.Bus, diags: Collector, acc: Analysis) -> dict[str, Any]:
    link = links.of(bus)
    timings = {msg.name: link.frame_timing(msg, bus) for msg in bus.messages}
    loads, delays = ethernet.analyse(bus, m.nodes, acc.extra_jitter)
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
    for ll in loads:
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
    report_deadlines(m, bus, rows, diags, clocks_counted=False)
    return {
        "name": bus.name,
        "protocol": bus.protocol,
        "bitrate": bus.bitrate,
        "utilization": round(max((ll.utilization for ll in loads), default=0.0), 6),
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
