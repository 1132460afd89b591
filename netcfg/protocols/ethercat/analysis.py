"""The cycle of an EtherCAT segment: how long the master's frames take on the wire and through the line of
slaves, whether that fits the cycle, whether SYNC0 comes after the frame has passed every slave, and how much of
the cycle is left for mailbox (CoE SDO) traffic.

The model, per cycle:

- The process image is the slaves' outputs and inputs side by side (SOEM's IOmap), read and written by one LRW
  datagram per frame; an image above 1,486 bytes takes several frames, sent back to back.
- A frame's bytes on the wire (IEEE 802.3; ETG.1000.4 for the EtherCAT header and datagrams): preamble and SFD 8,
  Ethernet header 14, EtherCAT header 2, per datagram 10 + data + working counter 2, FCS 4, inter-frame gap 12,
  the Ethernet frame padded to 64 bytes (netcfg.links.ethercat.frame_bytes). A byte is 80 ns at 100 Mbit/s.
- The bus is busy for the frames' wire time (the shortest cycle its bandwidth allows: Beckhoff's "100 servo
  axes every 100 us" is this figure).
- A frame comes back to the master after its wire time, the master's send jitter, each slave's forwarding delay
  and the cables out and back at 0.7 c. A slave's forwarding delay defaults by the physics of its ports
  (netcfg.links.ethercat.default_forwarding_ns): 2 us for an RJ45 slave (Beckhoff EK1101 technical data,
  "propagation delay 1 us typ.", out and back; SOEM's measured 1.40-1.52 us lie under it), 310 ns for an E-bus
  terminal (the largest step of the DC receive times ethercrab keeps of real lines, twice). This latency is what
  the cycle must hold (Beckhoff's "1,000 distributed digital I/O in about 30 us" and "about 12,000 I/O in one
  frame in 300 us" are this figure; they need about 0.12 us an 8-channel terminal, a figure fitted to them: at
  the E-bus default the full frame of 8-channel terminals takes 584 us, of 16-channel ones 353 us).
- The end of the last frame has passed slave k after the jitter, the wire time, and the forwarding delays and
  cables up to k: SYNC0 (each slave's shift after the cycle start) must come later, or the slave latches outputs
  from the frame that is still passing. A slave's SYNC0 may come early by the precision of distributed clocks
  against the reference clock (100 ns: Beckhoff's EtherCAT terminal documentation, "Distributed Clock": the master
  "synchronizes the local clock with the master clock in the EtherCAT bus with a precision of < 100 ns"), so the
  shift must exceed the frame's passing by that much; what is left is the slave's SYNC0 margin.
- What the latency leaves of the cycle is the room for mailbox traffic (CoE SDOs in frames of their own).

Beckhoff's figures: Beckhoff Automation, "Next Generation Ethernet: EtherCAT I/O" (product overview, as published
at globalspec.com, FeaturedProducts/Detail/BeckhoffAutomation/Next_Generation_Ethernet_EtherCAT_IO): "The update
time for 1000 distributed I/Os is only 30 us. Up to 1486 bytes of process data can be exchanged with a single
Ethernet frame - this is equivalent to almost 12,000 digital inputs and outputs. The transfer of this data
quantity only takes 300 us. EtherCAT communication with 100 servo axes only takes 100 us"; Beckhoff's EtherCAT
system description adds that 30 us "is typical for a transfer of 125 byte over 100Mb/s Ethernet".
tests/test_ethercat.py derives each from this model.
"""

from __future__ import annotations

from typing import Any

from netcfg import model
from netcfg.bus_analysis import Analysis, message_head, set_verdict, us
from netcfg.diagnostics import Collector
from netcfg.links import ethercat as link
from netcfg.protocols.ethercat.cycle import CycleTiming, cycle_timing, segment_timing
from netcfg.protocols.ethercat.segment import Segment

__all__ = ["ASSUMES", "DC_PRECISION_NS", "CycleTiming", "analyze_segment", "cycle_timing", "segment_timing"]

DC_PRECISION_NS = 100  # SYNC0 against the reference clock (Beckhoff, "Distributed Clock": "< 100 ns")

ASSUMES = [
    "one LRW datagram per frame carries the process image (outputs then inputs), several frames back to back when "
    f"it exceeds {link.MAX_DATAGRAM_DATA} bytes; the master sends a cycle's first frame at most its master_jitter "
    "late and waits for the last one to come back within the cycle",
    "each slave adds its forwarding delay to the round trip once (default 2 us an RJ45 slave, 310 ns an E-bus one, by "
    "its ESI's Physics); cables at 0.7 c",
    f"every DC slave's SYNC0 within {DC_PRECISION_NS} ns of the reference clock (the master's cycle locked to it)",
    "no frame is lost (a lost frame is a working-counter mismatch the master must detect) and mailbox traffic goes "
    "in the room the cyclic frames leave",
]



def analyze_segment(m: model.Model, bus: model.Bus, diags: Collector, acc: Analysis | None = None) -> dict[str, Any]:
    seg: Segment | None = bus.ethercat
    row: dict[str, Any] = {
        "name": bus.name,
        "protocol": bus.protocol,
        "bitrate": bus.bitrate,
        "utilization": 0.0,
        "messages": [],
    }
    if seg is None:
        return row
    t = segment_timing(bus, seg)
    room = seg.cycle_ns - t.latency_ns
    row["utilization"] = round(t.wire_ns / seg.cycle_ns, 6)
    if room < 0:
        diags.add(
            "cycle-overload",
            f"EtherCAT bus '{bus.name}': the process image ({seg.out_bytes} bytes out, {seg.in_bytes} in, "
            f"{len(t.frames)} frame(s)) is back at the master {t.latency_ns / 1000:.2f} us after the cycle starts "
            f"(wire {t.wire_ns / 1000:.2f}, slaves {t.forwarding_ns / 1000:.2f}, cables {t.propagation_ns / 1000:.2f}, "
            f"jitter {t.jitter_ns / 1000:.2f}), longer than the {seg.cycle_ns / 1000:g} us cycle: lengthen the cycle "
            "or map less",
            m.source.at((*seg.path, "cycle")),
        )
    slaves: list[dict[str, Any]] = []
    early: dict[tuple[str | int, ...], list[tuple[str, int, int]]] = {}  # SYNC0 too early, by the shift's place
    for s, passed in zip(seg.slaves, t.passed_ns):
        shift = s.sync0_shift_ns if s.sync0_shift_ns is not None else seg.sync0_shift_ns
        margin = shift - DC_PRECISION_NS - passed
        ok = margin >= 0 and (s.min_cycle_ns is None or seg.cycle_ns >= s.min_cycle_ns)
        if s.min_cycle_ns is not None and seg.cycle_ns < s.min_cycle_ns:
            diags.add(
                "min-cycle",
                f"slave '{s.node}' ({s.device}) needs a cycle of at least "
                f"{s.min_cycle_ns / 1000:g} us; bus '{bus.name}' runs {seg.cycle_ns / 1000:g} us",
                m.source.at((*s.path, "min_cycle")),
            )
        if s.assign_activate and margin < 0:
            where = (*s.path, "sync0_shift") if s.sync0_shift_ns is not None else (*seg.path, "sync0_shift")
            early.setdefault(where, []).append((s.node, shift, passed))
        slaves.append(
            {
                "node": s.node,
                "position": s.position,
                "device": s.device,
                "out_bytes": s.out_bytes,
                "in_bytes": s.in_bytes,
                "forwarding_us": us(s.forwarding_ns),
                "cable_m": s.cable_m,
                "frame_passed_us": us(passed),
                "sync0_shift_us": us(shift),
                "sync0_margin_us": us(margin) if s.assign_activate else None,
                "assign_activate": f"0x{s.assign_activate:04X}",
                "ok": ok,
            }
        )
    for where, late in early.items():
        names = ", ".join(f"'{n}'" for n, _, _ in late)
        node, shift, passed = late[-1]  # the slave farthest down the line
        diags.add(
            "dc-shift",
            f"SYNC0 comes {shift / 1000:g} us after the cycle starts, but the last frame has passed slave '{node}' "
            f"only {passed / 1000:.2f} us after (slaves {names} latch the outputs of a frame still passing, with "
            f"SYNC0 up to {DC_PRECISION_NS} ns early by distributed clocks' precision): shift SYNC0 to "
            f"{-(-(passed + DC_PRECISION_NS) // 1000)} us or later",
            m.source.at(where),
        )
    row["messages"] = pdo_rows(m, bus, seg, t, diags, acc)  # (before the walrus below rebinds m)
    row["cycle"] = {
        "cycle_us": us(seg.cycle_ns),
        "sync0_cycle_us": us(seg.sync0_cycle_ns),
        "out_bytes": seg.out_bytes,
        "in_bytes": seg.in_bytes,
        "frames": len(t.frames),
        "frame_bytes": list(t.frame_bytes),
        "wire_us": us(t.wire_ns),
        "forwarding_us": us(t.forwarding_ns),
        "propagation_us": us(t.propagation_ns),
        "master_jitter_us": us(t.jitter_ns),
        "latency_us": us(t.latency_ns),
        "mailbox_room_us": us(max(room, 0)),
        "dc_precision_us": us(DC_PRECISION_NS),
        "sync0_margin_us": min((m for x in slaves if (m := x["sync0_margin_us"]) is not None), default=None),
        "ok": room >= 0,
    }
    row["slaves"] = slaves
    return row


def task_starts(seg: Segment) -> dict[str, tuple[int, int]]:
    """When each node's tasks on the cycle (`sync: true`) start, earliest and latest from the cycle's start before
    their offsets: the master's within its send jitter, a DC slave's at its SYNC0, within distributed clocks'
    precision either way."""
    out = {seg.master: (0, seg.master_jitter_ns)} if seg.master is not None else {}
    for s in seg.slaves:
        if s.assign_activate:
            shift = s.sync0_shift_ns if s.sync0_shift_ns is not None else seg.sync0_shift_ns
            out[s.node] = (shift - DC_PRECISION_NS, shift + DC_PRECISION_NS)
    return out


def pdo_rows(
    m: model.Model, bus: model.Bus, seg: Segment, t: CycleTiming, diags: Collector, acc: Analysis | None
) -> list[dict[str, Any]]:
    """Each PDO message's delivery (netcfg.protocols.ethercat.messages) for the flows, and its row: its worst case
    from the cycle's start against its deadline."""
    from netcfg.protocols.ethercat.flow import CycleFlows
    from netcfg.protocols.ethercat.messages import delivery, pdo_messages
    from netcfg.timing.flows import Delivery

    rows = []
    windows = {}
    position = {s.node: k for k, s in enumerate(seg.slaves)}
    cables = [s.cable_m for s in seg.slaves]
    for p in pdo_messages(bus, seg):
        msg = m.messages[p.name]
        windows[msg.name] = timing = delivery(t, p, position[p.slave], cables, bus.bitrate)
        best, worst, read = timing.best_ns, timing.worst_ns, timing.read_ns
        if acc is not None:
            acc.chained[msg.name] = acc.plain[msg.name] = Delivery(best, worst)
        row = message_head(msg, extended=False) | {
            "slave": p.slave,
            "direction": p.direction,
            "pdo": f"0x{p.index:04X}",
            "logical": p.logical,
            # its bytes in the cycle's frame: their bits and their time on the wire, their share of the cycle
            "frame_bits_worst": 8 * p.length,
            "frame_bits_nominal": 8 * p.length,
            "tx_us": us(link.wire_ns(p.length, bus.bitrate)),
            "frame_us_worst": us(link.wire_ns(p.length, bus.bitrate)),
            "utilization": round(link.wire_ns(p.length, bus.bitrate) / seg.cycle_ns, 6),
            "best_us": us(best),
            "read_offset_ns": read,
            "wcrt_us": None,
            "wcrt_ns": None,
            "deadline_us": us(msg.deadline_ns),
            "slack_us": None,
            "schedulable": None,
        }
        set_verdict(row, worst, msg.deadline_ns)
        if row["schedulable"] is False and msg.deadline_ns is not None:
            diags.add(
                "deadline",
                f"message '{msg.name}' (PDO {row['pdo']} of slave '{p.slave}') is delivered up to "
                f"{worst / 1000:.2f} us after the cycle starts, after its deadline of {msg.deadline_ns / 1000:g} us: "
                "shorten what the cycle carries or give a longer deadline",
                m.source.at((*msg.path, "deadline")),
            )
        rows.append(row)
    if acc is not None:
        acc.cycle_flows[bus.name] = CycleFlows(bus.name, seg.cycle_ns, task_starts(seg), windows)
    return rows
