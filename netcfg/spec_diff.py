"""What changed between two specs (or two build folders) in timing terms: the comparison of `netcfg diff A B`.

Each side is an analysis report (a spec is analysed in memory; a build folder brings its report.json) and a set of
artifacts (a spec's are emitted in memory; a folder's are its files). The comparison is of reports: the load of
each bus, each message's worst-case response time, deadline and verdict, each flow's latency bounds, and then
which artifacts are added, removed or changed. The command (netcfg.commands.diff) prints it; its exit codes follow
diff(1): 0 the same, 1 different, 2 unreadable.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from netcfg.report_text import num

Files = dict[str, bytes]
# what a spec sets for a message, as report.json states it (label for the text); offsets are the resolved ones,
# so `offset: auto` placing a message elsewhere shows too
PARAMETERS = {
    "id": "id",
    "ftt_id": "FTT id",
    "producer": "producer",
    "size": "bytes",
    "period_us": "period us",
    "offset_us": "offset us",
}


class DiffInputError(Exception):
    """A side that cannot be compared: the message says why and what to do."""


@dataclass
class Side:
    name: str
    report: dict[str, Any]
    files: Files | None  # None: not built (the spec has errors)


@dataclass
class Difference:
    buses: list[dict[str, Any]] = field(default_factory=list)
    messages: list[dict[str, Any]] = field(default_factory=list)
    flows: list[dict[str, Any]] = field(default_factory=list)
    artifacts: dict[str, list[str]] = field(default_factory=lambda: {"added": [], "removed": [], "changed": []})
    verdict: tuple[bool, bool] = (True, True)

    def empty(self) -> bool:
        return not (self.buses or self.messages or self.flows or any(self.artifacts.values()))

    def as_json(self) -> dict[str, Any]:
        return {
            "ok": {"a": self.verdict[0], "b": self.verdict[1]},
            "buses": self.buses,
            "messages": self.messages,
            "flows": self.flows,
            "artifacts": self.artifacts,
            "same": self.empty(),
        }


def load_side(path: Path) -> Side:
    if path.is_dir():
        report_file = path / "report.json"
        if not report_file.is_file():
            raise DiffInputError(f"{path} is a folder without report.json; give a spec or a folder netcfg built")
        report = json.loads(report_file.read_text(encoding="utf-8"))
        on_disk = {
            p.relative_to(path).as_posix(): p.read_bytes()
            for p in sorted(path.rglob("*"))
            if p.is_file() and not _bookkeeping(p.relative_to(path))
        }
        return Side(str(path), report, on_disk)
    from netcfg.check import analyse_spec

    model, report = analyse_spec(path)
    if model is None:
        first = report["errors"][0] if report["errors"] else None
        where = f"{first['file']}:{first['line']}:{first['column']}: {first['message']}" if first else str(path)
        raise DiffInputError(f"{where}; fix it (netcfg check {path}) before comparing")
    files: Files | None = None
    if report["ok"]:
        from netcfg.emit import emit_all

        files = emit_all(model, report)
    return Side(str(path), report, files)


def _bookkeeping(rel: Path) -> bool:
    """Files that describe a build rather than belong to it (hidden files, the output folder's manifest)."""
    return any(part.startswith(".") for part in rel.parts) or "manifest" in rel.name.lower()


def compare(a: Side, b: Side) -> Difference:
    d = Difference(verdict=(bool(a.report["ok"]), bool(b.report["ok"])))
    buses_a = {x["name"]: x for x in a.report["buses"]}
    buses_b = {x["name"]: x for x in b.report["buses"]}
    for name in sorted(buses_a.keys() | buses_b.keys()):
        ua = buses_a[name]["utilization"] if name in buses_a else None
        ub = buses_b[name]["utilization"] if name in buses_b else None
        if ua != ub:
            d.buses.append({"name": name, "utilization": [ua, ub]})
    msgs_a = _messages(a.report)
    msgs_b = _messages(b.report)
    for name in sorted(msgs_a.keys() | msgs_b.keys()):
        ma, mb = msgs_a.get(name), msgs_b.get(name)
        keys = ("bus", *PARAMETERS, "wcrt_us", "deadline_us", "schedulable")
        va = {k: ma.get(k) for k in keys} if ma else None
        vb = {k: mb.get(k) for k in keys} if mb else None
        if va != vb:
            d.messages.append({"name": name, "a": va, "b": vb})
    flows_a = {f["name"]: f for f in a.report["flows"]}
    flows_b = {f["name"]: f for f in b.report["flows"]}
    for name in sorted(flows_a.keys() | flows_b.keys()):
        flow_keys = ("latency_min_us", "latency_max_us", "deadline_us", "meets_deadline")
        fa = {k: flows_a[name].get(k) for k in flow_keys} if name in flows_a else None
        fb = {k: flows_b[name].get(k) for k in flow_keys} if name in flows_b else None
        if fa != fb:
            d.flows.append({"name": name, "a": fa, "b": fb})
    if a.files is not None and b.files is not None:
        d.artifacts["added"] = sorted(b.files.keys() - a.files.keys())
        d.artifacts["removed"] = sorted(a.files.keys() - b.files.keys())
        d.artifacts["changed"] = sorted(k for k in a.files.keys() & b.files.keys() if a.files[k] != b.files[k])
    return d


def _messages(report: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {m["name"]: {**m, "bus": bus["name"]} for bus in report["buses"] for m in bus["messages"]}


def render_text(a: Side, b: Side, d: Difference) -> str:
    out = [f"--- {a.name}", f"+++ {b.name}"]
    if d.verdict[0] != d.verdict[1]:
        out.append(f"verdict: {_ok(d.verdict[0])} -> {_ok(d.verdict[1])}")
    for bus in d.buses:
        ua, ub = bus["utilization"]
        change = f" ({(ub - ua) * 100:+.1f} points)" if ua is not None and ub is not None else ""
        out.append(f"bus {bus['name']}: load {_pct(ua)} -> {_pct(ub)}{change}")
    for m in d.messages:
        out.append(_message_line(m["name"], m["a"], m["b"]))
    for f in d.flows:
        out.append(f"flow {f['name']}: {_flow(f['a'])} -> {_flow(f['b'])}")
    for kind in ("added", "removed", "changed"):
        names = d.artifacts[kind]
        if names:
            out.append(f"artifacts {kind} ({len(names)}): {', '.join(names)}")
    if None in (a.files, b.files):
        missing = a.name if a.files is None else b.name
        out.append(f"artifacts: not compared, {missing} has errors and would not be built")
    if d.empty():
        out.append("no difference in timing or artifacts")
    return "\n".join(out)


def _message_line(name: str, a: dict[str, Any] | None, b: dict[str, Any] | None) -> str:
    if a is None:
        return f"message {name}: added, {_bound(b)}"
    if b is None:
        return f"message {name}: removed"
    parts = []
    for key, label in (("bus", "bus"), *PARAMETERS.items()):
        if a[key] != b[key]:
            parts.append(f"{label} {_fmt(key, a[key])} -> {_fmt(key, b[key])}")
    if (a["wcrt_us"], a["deadline_us"], a["schedulable"]) != (b["wcrt_us"], b["deadline_us"], b["schedulable"]):
        parts.append(f"{_bound(a)} -> {_bound(b)}")
    return f"message {name}: {'; '.join(parts)}"


def _bound(m: dict[str, Any] | None) -> str:
    if m is None:
        return "-"
    wcrt = "unbounded" if m["wcrt_us"] is None else f"{num(m['wcrt_us'])} us"
    verdict = {True: "ok", False: "MISSES", None: "not analysed"}[m["schedulable"]]
    return f"wcrt {wcrt} / deadline {num(m['deadline_us'])} us ({verdict})"


def _flow(f: dict[str, Any] | None) -> str:
    if f is None:
        return "absent"
    if f["deadline_us"] is None:
        verdict = "no deadline"
    else:
        verdict = f"{'meets' if f['meets_deadline'] else 'MISSES'} its {num(f['deadline_us'])} us deadline"
    return f"{num(f['latency_min_us'])}..{num(f['latency_max_us'])} us ({verdict})"


def _fmt(key: str, value: Any) -> str:
    return f"0x{value:X}" if key == "id" and isinstance(value, int) and value >= 0 else num(value)


def _pct(u: float | None) -> str:
    return "absent" if u is None else f"{u:.1%}"


def _ok(ok: bool) -> str:
    return "OK" if ok else "FAILED"
