"""`netcfg check --watch SPEC...`, check's mode that checks again on every save of a spec or of a file it names
(an EDS, an imported DBC), with a summary that fits one screen. Polls modification times (standard library only: no
file-system notification package, and a save is seen within POLL_S). Ctrl-C ends it with exit code 0."""

from __future__ import annotations

import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from netcfg.importers import ImportOptions

POLL_S = 0.25
Stamp = tuple[int, int] | None


def watch(
    paths: list[Path],
    options: ImportOptions | None = None,
    werror: frozenset[str] = frozenset(),
    max_checks: int | None = None,
    out: TextIO | None = None,
    poll_s: float = POLL_S,
) -> int:
    """Check, print a summary, wait for a save, again; max_checks stops after that many checks (for tests)."""
    from netcfg.check import spec_files

    out = out or sys.stdout
    try:
        specs = spec_files(paths)
    except OSError as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    checks = 0
    try:
        while True:
            files, summary = _check_all(specs, options, werror)
            stamps = {f: _stamp(f) for f in files}
            checks += 1
            clear = "\033[2J\033[H" if out.isatty() else ""
            when = time.strftime("%H:%M:%S")
            out.write(f"{clear}{summary}\n-- check {checks} at {when}; watching {len(files)} file(s), Ctrl-C ends\n")
            out.flush()
            if max_checks is not None and checks >= max_checks:
                return 0
            while all(_stamp(f) == s for f, s in stamps.items()):
                time.sleep(poll_s)
    except KeyboardInterrupt:
        return 0


def _stamp(path: Path) -> Stamp:
    try:
        info = os.stat(path)
    except OSError:
        return None
    return info.st_mtime_ns, info.st_size


def _check_all(
    specs: list[Path], options: ImportOptions | None, werror: frozenset[str]
) -> tuple[list[Path], str]:
    """Every spec checked; -> (the files to watch, the summary)."""
    from netcfg.check import analyse_loaded, named_files, promote_warnings

    files: list[Path] = []
    parts: list[str] = []
    height = max(shutil.get_terminal_size((100, 40)).lines - 2, 10) // max(len(specs), 1)
    for spec in specs:
        files.append(spec)
        try:
            loaded, report = analyse_loaded(spec, options)
        except OSError as exc:
            parts.append(f"== {spec}: cannot read it: {exc.strerror or exc}")
            continue
        report = promote_warnings(report, werror)
        files.extend(named_files(spec, loaded.data))
        files.extend(Path(d["file"]) for d in report["errors"] + report["warnings"])
        parts.append(summary(report, height))
    return list(dict.fromkeys(files)), "\n".join(parts)


def summary(report: dict[str, Any], height: int = 20) -> str:
    """The status, each bus's load and misses, flows past their deadline, then the problems, cut to height lines."""
    from netcfg.report_text import num

    status = "OK" if report["ok"] else "FAILED"
    out = [
        f"== {report.get('system') or report['file']}: {status} "
        f"({len(report['errors'])} errors, {len(report['warnings'])} warnings)"
    ]
    for bus in report["buses"]:
        missed = [m["name"] for m in bus["messages"] if m["schedulable"] is False]
        tail = f", {len(missed)} past their deadline: {', '.join(missed[:5])}" if missed else ""
        out.append(f"  bus {bus['name']}: {bus['utilization']:.1%} load, {len(bus['messages'])} messages{tail}")
    for f in report["flows"]:
        if f.get("meets_deadline") is False:
            out.append(f"  flow {f['name']}: up to {num(f['latency_max_us'])} us, deadline {num(f['deadline_us'])} us")
    problems = [("error", d) for d in report["errors"]] + [("warning", d) for d in report["warnings"]]
    room = max(height - len(out), 1)
    for kind, d in problems[:room]:
        out.append(f"{d['file']}:{d['line']}:{d['column']}: {kind}: {d['message']} [{d['code']}]")
    if len(problems) > room:
        out.append(f"  ... and {len(problems) - room} more (netcfg check {report['file']} lists them all)")
    return "\n".join(out)
