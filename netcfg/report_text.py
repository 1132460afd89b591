"""Text rendering of a check report: the tables a person wants to look at."""

from __future__ import annotations

from typing import Any


def _fmt(value: Any, digits: int = 1) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def table(headers: list[str], rows: list[list[str]], align: str) -> list[str]:
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(headers)]
    def line(cells: list[str]) -> str:
        return "  ".join(c.ljust(w) if a == "l" else c.rjust(w) for c, w, a in zip(cells, widths, align)).rstrip()
    return [line(headers), line(["-" * w for w in widths]), *(line(r) for r in rows)]


def render(report: dict[str, Any]) -> str:
    out: list[str] = []
    status = "OK" if report["ok"] else "FAILED"
    out.append(f"== {report.get('system') or report['file']}: {status} "
               f"({len(report['errors'])} errors, {len(report['warnings'])} warnings)")
    for bus in report["buses"]:
        out.append("")
        out.append(f"bus {bus['name']} ({bus['protocol']}, {bus['bitrate'] / 1000:g} kbit/s): "
                   f"utilisation {bus['utilization']:.1%} worst case")
        if "ftt" in bus:
            f = bus["ftt"]
            out.append(f"  FTT-CAN: EC {f['ec_us']:g} us, trigger message {f['tm_us']:g} us "
                       f"(overhead {f['tm_overhead']:.1%}), LSW {_fmt(f['lsw_us'])} us")
        rows = []
        for m in bus["messages"]:
            ident = f"0x{m['id']:X}" if m["id"] >= 0 else "-"
            rows.append([m["name"], ident, str(m["size"]), _fmt(m["interval_us"], 0),
                         str(m["frame_bits_worst"]), _fmt(m["tx_us"]), f"{m['utilization']:.2%}",
                         _fmt(m["wcrt_us"]), _fmt(m["deadline_us"], 0), _fmt(m["schedulable"])])
        headers = ["message", "id", "bytes", "every/us", "bits", "tx/us", "load", "wcrt/us", "deadline/us", "ok"]
        out.extend("  " + line for line in table(headers, rows, "lrrrrrrrrl"))
    for w in report["warnings"]:
        out.append(f"{w['file']}:{w['line']}:{w['column']}: warning: {w['message']} [{w['code']}]")
    return "\n".join(out)
