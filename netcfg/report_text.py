"""Text rendering of a check report: the tables a person wants to look at."""

from __future__ import annotations

from typing import Any


def num(value: Any, false: str = "no") -> str:
    """One way for every number of the reports (this text and report.md): thousands separated, at most 3
    decimals, no trailing zeros; None is '-', a boolean 'yes' or `false`."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else false
    if isinstance(value, (int, float)):
        return f"{value:,.3f}".rstrip("0").rstrip(".")
    return str(value)


def master_loop_text(loop: dict[str, Any]) -> str:
    """One sentence on the SYNC producer's cycle as analysed (netcfg.timing.canopen_sync.MasterLoop)."""
    late = f", starting up to {num(loop['jitter_us'])} us late" if loop["jitter_us"] else ""
    if not loop["tasks"]:
        late = f" up to {num(loop['jitter_us'])} us late" if loop["jitter_us"] else ""
        return f"SYNC right after the RxPDO writes{late}; no SYNC task on {loop['node']}, so no computation modelled."
    return (
        f"{', '.join(loop['tasks'])} starts {num(loop['offset_us'])} us after SYNC and runs "
        f"{num(loop['bcet_us'])} .. {num(loop['wcet_us'])} us{late}; its RxPDO writes are queued by "
        f"{num(loop['writes_done_us'])} us after SYNC, and the next SYNC waits for its instant."
    )


def rate(bitrate: int) -> str:
    """A bit rate in the largest unit it reaches: 1 Mbit/s, 250 kbit/s."""
    for unit, scale in (("Gbit/s", 10**9), ("Mbit/s", 10**6), ("kbit/s", 10**3)):
        if bitrate >= scale:
            return f"{num(bitrate / scale)} {unit}"
    return f"{bitrate} bit/s"


def table(headers: list[str], rows: list[list[str]], align: str, indent: str = "  ") -> list[str]:
    widths = [max([len(h)] + [len(r[i]) for r in rows]) for i, h in enumerate(headers)]

    def line(cells: list[str]) -> str:
        text = "  ".join(c.ljust(w) if a == "l" else c.rjust(w) for c, w, a in zip(cells, widths, align))
        return indent + text.rstrip()

    return [line(headers), line(["-" * w for w in widths]), *(line(r) for r in rows)]


def errors_text(e: dict[str, Any]) -> str:
    """One sentence on a CAN bus's bit-error assumption and how likely its environment is to break it in an hour."""
    odds = (
        f"at a bit error rate of {e['ber']:g}, about {e['errors_per_hour']:g} errors an hour hit frames, and the "
        f"probability that an hour breaks that assumption is {'at most ' if e['model'] else ''}"
        f"{e['exceed_probability_per_hour']:.3g}"
    )
    if e["model"] is None:
        return f"bit errors: none assumed, every bound here holds for an error-free bus only; {odds}"
    m = e["model"]
    return (
        f"bit errors: the bounds allow {e['assumption']} (each an error frame of up to {m['error_frame_bits']} bits, "
        f"{m['error_frame_us']:g} us, and the frame sent again); {odds}"
    )


def render(report: dict[str, Any]) -> str:
    out: list[str] = []
    status = "OK" if report["ok"] else "FAILED"
    out.append(
        f"== {report.get('system') or report['file']}: {status} "
        f"({len(report['errors'])} errors, {len(report['warnings'])} warnings)"
    )
    for bus in report["buses"]:
        out.append("")
        out.append(
            f"bus {bus['name']} ({bus['protocol']}, {rate(bus['bitrate'])}"
            + (f", data {rate(bus['data_bitrate'])}" if bus.get("data_bitrate") else "")
            + "): "
            f"utilisation {bus['utilization']:.1%} worst case"
            + (f", {bus['utilization_with_tm']:.1%} with the trigger message" if "ftt" in bus else "")
        )
        if "errors" in bus:
            out.append("  " + errors_text(bus["errors"]))
        rows = []
        # by identifier, the order of priority on CAN and how people look frames up; ones without an id last
        # (a remote frame after the data frame of its identifier, which wins over it)
        for m in sorted(bus["messages"], key=lambda m: (m["id"] < 0, m.get("extended", False), m["id"],
                                                        m.get("remote", False), m["name"])):
            ident = f"0x{m['id']:X}" if m["id"] >= 0 else "-"
            rows.append(
                [
                    m["name"],
                    ident,
                    "RTR" if m.get("remote") else str(m["size"]),
                    num(m["interval_us"]),
                    str(m["frame_bits_worst"]),
                    num(m["tx_us"]),
                    f"{m['utilization']:.2%}",
                    num(m["wcrt_us"]),
                    num(m["deadline_us"]),
                    num(m["schedulable"], false="NO"),
                ]
            )
        headers = ["message", "id", "bytes", "every/us", "bits", "tx/us", "load", "wcrt/us", "deadline/us", "ok"]
        if rows or "cycle" not in bus:  # an EtherCAT segment's process data is its cycle's rows
            out.extend(table(headers, rows, "lrrrrrrrrl"))
        if "cycle" in bus:
            from netcfg.protocols.ethercat.report import render_cycle

            out.extend(render_cycle(bus, table, num))
        if "ftt" in bus:
            out.extend(render_ftt(bus["ftt"]))
        if "sync" in bus:
            s = bus["sync"]
            out.append(
                f"  SYNC every {num(s['period_us'])} us from {s['producer']}: up to {s['max_tpdos_per_cycle']} "
                f"synchronous TPDOs, the last done {num(s['worst_completion_us'])} us after SYNC "
                f"(window {num(s['window_us'])} us, read window {num(s['read_window_us'])} us)"
            )
            out.append(f"  master: {master_loop_text(s['master'])}")
        for q in bus.get("tx_queues", ()):
            out.append(f"  transmit queue of {q['node']}: {tx_queue_text(q)}")
        if bus.get("assumes"):
            out.append("  the bounds assume:")
            out.extend(f"    - {a}" for a in bus["assumes"])
        if "links" in bus:
            out.append(
                f"  minimum frame {num(bus['min_frame_us'])} us, f_max {bus['f_max_hz'] / 1000:.2f} kHz per link"
            )
            rows = [
                [
                    f"{ll['from']} -> {ll['to']}",
                    str(ll["senders"]),
                    f"{ll['frames_per_s'] / 1000:.2f}",
                    f"{ll['f_max_per_sender_hz'] / 1000:.2f}",
                    f"{ll['utilization']:.2%}",
                    f"{'-' if ll['backlog_frames'] is None else ll['backlog_frames']} / {ll['queue_frames']}",
                    num(ll["ok"], false="NO"),
                ]
                for ll in bus["links"]
            ]
            head = ["link", "senders", "kHz", "f_max/n kHz", "load", "queue (frames)", "ok"]
            out.extend(table(head, rows, "lrrrrrl"))
    if report.get("nodes"):
        out.append("")
        out.append("processors (worst-case response of each task from its nominal release, jitter included, us):")
        rows = [
            [
                n["name"],
                n["scheduling"],
                f"{n['utilization']:.1%}",
                ", ".join(f"{t['name']} {num(t['wcrt_us'], false='-')}" for t in n["tasks"]),
            ]
            for n in report["nodes"]
        ]
        out.extend(table(["node", "scheduling", "load", "tasks by priority"], rows, "llrl"))
    if report["flows"]:
        out.append("")
        out.append("flows (latency from the first activation to the last use, us):")
        rows = []
        for f in report["flows"]:
            u = f["unsynchronised"]
            sync = f.get("synchronised")
            rows.append(
                [
                    f["name"],
                    f["mode"],
                    f"{num(sync['latency_min_us'])} .. {num(sync['latency_max_us'])}" if sync else "-",
                    f"{num(u['latency_min_us'])} .. {num(u['latency_max_us'])}",
                    num(f["deadline_us"]),
                ]
            )
        out.extend(table(["flow", "mode", "synchronised", "unsynchronised", "deadline"], rows, "llrrr"))
    for w in report["warnings"]:
        out.append(f"{w['file']}:{w['line']}:{w['column']}: warning: {w['message']} [{w['code']}]")
    return "\n".join(out)


def render_ftt(f: dict[str, Any]) -> list[str]:
    out = [
        f"  FTT-CAN: EC {num(f['ec_us'])} us, trigger message {num(f['tm_us'])} us (overhead "
        f"{f['tm_overhead']:.1%}), LSW {num(f['lsw_us'])} us, macro-cycle {num(f['macro_cycle_ec'])} ECs"
    ]
    if "worst_ec" in f:
        w = f["worst_ec"]
        out[0] += f"; busiest EC {w['index']} needs {num(w['sync_us'])} us of synchronous window"
    rows = [
        [
            str(e["id"]),
            e["name"],
            e["type"],
            e["producer"] or "-",
            str(e["period_ec"]),
            str(e["init_ec"]),
            num(e["c_us"]),
        ]
        for e in f["srt"]
    ]
    out.extend(
        table(["FTT id", "entry", "type", "producer", "period/EC", "init/EC", "C/us"], rows, "rlllrrr", indent="    ")
    )
    return out


def tx_queue_text(q: dict[str, Any]) -> str:
    """A FIFO transmit queue's bound and its terms (Davis, Kollmann, Pollex, Slomka 2011), in one line."""
    head = f"FIFO, depth {q['depth']}, {q['on_full']} when full, {len(q['messages'])} messages"
    if q["queue_us"] is None:
        return f"{head}; no bound ({q.get('unbounded')})"
    apart, n = q.get("by_offsets", False), len(q.get("together", ()))
    return (
        (
            f"{head} kept apart by their offsets, the longest bound {num(q['queue_us'])} us (blocking "
            f"{num(q['blocking_us'])} + the frames that can be queued together ({n}) "
            if apart
            else f"{head} sharing one bound of {num(q['queue_us'])} us (blocking {num(q['blocking_us'])} + the whole "
            "queue "
        )
        + f"{num(q['queued_us'])} + other nodes' frames above {q['lowest']} {num(q['interference_us'])}"
        + (f" + bit errors {num(q['error_us'])}" if q.get("error_us") else "")
        + "); at most "
        f"{q['backlog_max']} frame{'s' if q['backlog_max'] != 1 else ''} queued"
        + (f"; can drop {', '.join(q['dropped'])}" if q.get("dropped") else "")
    )
