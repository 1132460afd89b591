"""Text rendering of a check report: the tables a person wants to look at."""

from __future__ import annotations

from typing import Any


def _fmt(value: Any, digits: int = 1) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if isinstance(value, float):
        return f"{value:,.{digits}f}"
    return str(value)


def table(headers: list[str], rows: list[list[str]], align: str, indent: str = "  ") -> list[str]:
    widths = [max([len(h)] + [len(r[i]) for r in rows]) for i, h in enumerate(headers)]

    def line(cells: list[str]) -> str:
        text = "  ".join(c.ljust(w) if a == "l" else c.rjust(w) for c, w, a in zip(cells, widths, align))
        return indent + text.rstrip()

    return [line(headers), line(["-" * w for w in widths]), *(line(r) for r in rows)]


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
            f"bus {bus['name']} ({bus['protocol']}, {bus['bitrate'] / 1000:g} kbit/s): "
            f"utilisation {bus['utilization']:.1%} worst case"
            + (f", {bus['utilization_with_tm']:.1%} with the trigger message" if "ftt" in bus else "")
        )
        rows = []
        for m in bus["messages"]:
            ident = f"0x{m['id']:X}" if m["id"] >= 0 else "-"
            rows.append(
                [
                    m["name"],
                    ident,
                    str(m["size"]),
                    _fmt(m["interval_us"], 0),
                    str(m["frame_bits_worst"]),
                    _fmt(m["tx_us"]),
                    f"{m['utilization']:.2%}",
                    _fmt(m["wcrt_us"]),
                    _fmt(m["deadline_us"], 0),
                    _fmt(m["schedulable"]),
                ]
            )
        headers = ["message", "id", "bytes", "every/us", "bits", "tx/us", "load", "wcrt/us", "deadline/us", "ok"]
        out.extend(table(headers, rows, "lrrrrrrrrl"))
        if "ftt" in bus:
            out.extend(render_ftt(bus["ftt"]))
        if "sync" in bus:
            s = bus["sync"]
            out.append(
                f"  SYNC every {s['period_us']:g} us from {s['producer']}: up to {s['max_tpdos_per_cycle']} "
                f"synchronous TPDOs, the last done {_fmt(s['worst_completion_us'])} us after SYNC "
                f"(window {_fmt(s['window_us'], 0)} us, read window {_fmt(s['read_window_us'], 0)} us)"
            )
        if "links" in bus:
            out.append(f"  minimum frame {bus['min_frame_us']:g} us, f_max {bus['f_max_hz'] / 1000:.2f} kHz per link")
            rows = [
                [
                    f"{ll['from']} -> {ll['to']}",
                    str(ll["senders"]),
                    f"{ll['frames_per_s'] / 1000:.2f}",
                    f"{ll['f_max_per_sender_hz'] / 1000:.2f}",
                    f"{ll['utilization']:.2%}",
                    _fmt(ll["ok"]),
                ]
                for ll in bus["links"]
            ]
            out.extend(table(["link", "senders", "kHz", "f_max/n kHz", "load", "ok"], rows, "lrrrrl"))
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
                    f"{_fmt(sync['latency_min_us'])} .. {_fmt(sync['latency_max_us'])}" if sync else "-",
                    f"{_fmt(u['latency_min_us'])} .. {_fmt(u['latency_max_us'])}",
                    _fmt(f["deadline_us"], 0),
                ]
            )
        out.extend(table(["flow", "mode", "synchronised", "unsynchronised", "deadline"], rows, "llrrr"))
    for w in report["warnings"]:
        out.append(f"{w['file']}:{w['line']}:{w['column']}: warning: {w['message']} [{w['code']}]")
    return "\n".join(out)


def render_ftt(f: dict[str, Any]) -> list[str]:
    out = [
        f"  FTT-CAN: EC {f['ec_us']:g} us, trigger message {f['tm_us']:g} us (overhead {f['tm_overhead']:.1%}), "
        f"LSW {_fmt(f['lsw_us'], 0)} us, macro-cycle {f['macro_cycle_ec']} ECs; busiest EC {f['worst_ec']['index']} "
        f"needs {f['worst_ec']['sync_us']:g} us of synchronous window"
    ]
    rows = [
        [
            str(e["id"]),
            e["name"],
            e["type"],
            e["producer"] or "-",
            str(e["period_ec"]),
            str(e["init_ec"]),
            _fmt(e["c_us"]),
        ]
        for e in f["srt"]
    ]
    out.extend(
        table(["FTT id", "entry", "type", "producer", "period/EC", "init/EC", "C/us"], rows, "rlllrrr", indent="    ")
    )
    return out
