"""The report rows of an EtherCAT segment, in check's text and in report.md: the cycle's budget (the frames on the
wire, the slaves' delays, the cables, the master's jitter, the room left for mailbox traffic, SYNC0's margin) and
each slave's place in it."""

from __future__ import annotations

from typing import Any


def render_cycle(bus: dict[str, Any], table: Any, num: Any) -> list[str]:
    c = bus["cycle"]
    out = [
        f"  cycle {num(c['cycle_us'])} us (SYNC0 every {num(c['sync0_cycle_us'])} us): {c['out_bytes']} bytes out, "
        f"{c['in_bytes']} in, {c['frames']} frame(s) of {', '.join(map(str, c['frame_bytes']))} bytes on the wire",
        f"  back at the master after {num(c['latency_us'])} us = jitter {num(c['master_jitter_us'])} + wire "
        f"{num(c['wire_us'])} + slaves {num(c['forwarding_us'])} + cables {num(c['propagation_us'])}; "
        f"{num(c['mailbox_room_us'])} us left for mailbox traffic"
        + ("" if c["ok"] else " (NO: the cycle is too short)"),
    ]
    if c.get("sync0_margin_us") is not None:
        out.append(
            f"  SYNC0 after the frame has passed with {num(c['sync0_margin_us'])} us to spare at the tightest slave "
            f"(distributed clocks' precision {num(c['dc_precision_us'])} us taken off)"
        )
    rows = [
        [
            *_slave(s),
            num(s["frame_passed_us"]),
            num(s["sync0_shift_us"]),
            "-" if s.get("sync0_margin_us") is None else num(s["sync0_margin_us"]),
            s["assign_activate"],
            num(s["ok"], false="NO"),
        ]
        for s in bus["slaves"]
    ]
    head = ["pos", "slave", "device", "out B", "in B", "frame passed/us", "SYNC0/us", "margin/us", "DC", "ok"]
    out.extend(table(head, rows, "rllrrrrrrl"))
    for m in bus["messages"]:
        out.append("  " + pdo_text(m, num))
    return out


def pdo_text(m: dict[str, Any], num: Any) -> str:
    """One PDO message's delivery in words (netcfg.protocols.ethercat.messages)."""
    if m["direction"] == "inputs":
        return (
            f"{m['name']}: TxPDO {m['pdo']} of {m['slave']}, its inputs at logical byte {m['logical']}, read "
            f"{num(m['read_offset_ns'] / 1000)} us after the master's send, at the master {num(m['best_us'])} us "
            f"after that at the earliest and {num(m['wcrt_us'])} us after the cycle starts at the latest"
        )
    return (
        f"{m['name']}: RxPDO {m['pdo']} of {m['slave']}, its outputs at logical byte {m['logical']}, copied at the "
        f"master's send, at the slave {num(m['best_us'])} us after that at the earliest and {num(m['wcrt_us'])} us "
        "after the cycle starts at the latest"
    )


def _slave(s: dict[str, Any]) -> list[str]:
    """The columns that name a slave in both tables: position, node, device, output and input bytes."""
    return [str(s["position"]), s["node"], s["device"], str(s["out_bytes"]), str(s["in_bytes"])]


def cycle_view(bus: dict[str, Any], num: Any) -> dict[str, Any]:
    """What report.md shows of the bus's cycle (templates/report.md.j2): the budget's figures, and per slave
    (headers, alignment, rows) for its table."""
    c = bus["cycle"]
    rows = [
        [
            *_slave(s),
            num(s.get("forwarding_us")),
            num(s.get("cable_m")),
            num(s["frame_passed_us"]),
            num(s["sync0_shift_us"]) if s.get("sync0_margin_us") is not None else "-",
            num(s.get("sync0_margin_us")),
            s["assign_activate"],
            "ok" if s["ok"] else "**NO**",
        ]
        for s in bus["slaves"]
    ]
    head = [
        "pos", "slave", "device", "out bytes", "in bytes", "delay (us)", "cable (m)", "frame passed (us)",
        "SYNC0 (us)", "SYNC0 margin (us)", "DC", "verdict",
    ]
    pdos = [pdo_text(m, num) for m in bus.get("messages", ())]
    return {
        "pdos": pdos,
        **{k: num(v) for k, v in c.items() if isinstance(v, (int, float)) and not isinstance(v, bool)},
        "frame_bytes": ", ".join(map(str, c["frame_bytes"])),
        "ok": c["ok"],
        "has_margin": c.get("sync0_margin_us") is not None,
        "slaves": (head, "rllrrrrrrrll", rows),
    }
