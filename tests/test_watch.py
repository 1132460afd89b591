"""`netcfg check --watch`: a check on every save of the spec or of a file it names, a summary each time, Ctrl-C
ends it with exit code 0. The expected findings are check's own (the misspelt key is tests/test_lsp.py's)."""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from netcfg.check import analyse_loaded, named_files
from tests.conftest import EPOS4_EDS, ROOT, SPECS


def start(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "netcfg", "check", "--watch", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
    )


def read_until(proc: subprocess.Popen[str], marker: str, timeout: float = 60) -> str:
    """stdout up to and including the line with marker."""
    assert proc.stdout is not None
    out = []
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        line = proc.stdout.readline()
        if not line:
            break
        out.append(line)
        if marker in line:
            return "".join(out)
    raise AssertionError(f"no {marker!r} in {''.join(out)!r}")


def test_a_save_checks_again_and_the_summary_says_what_check_says(tmp_path: Path) -> None:
    spec = tmp_path / "allex2.yaml"
    shutil.copy(SPECS / "allex2.yaml", spec)
    proc = start(str(spec), "--watch-checks", "2")
    first = read_until(proc, "-- check 1")
    assert "== allex2: OK (0 errors, 0 warnings)" in first
    text = spec.read_text(encoding="utf-8").replace("period: 20 ms", "perod: 20 ms", 1)
    time.sleep(0.05)  # a new modification time even on a coarse clock
    spec.write_text(text, encoding="utf-8")
    second = read_until(proc, "-- check 2")
    assert proc.wait(timeout=30) == 0
    _, report = analyse_loaded(spec)
    (err,) = report["errors"]
    assert f"{err['file']}:{err['line']}:{err['column']}: error: {err['message']} [extra-forbidden]" in second
    assert "FAILED (1 errors, 0 warnings)" in second


def test_it_watches_the_eds_a_spec_names(tmp_path: Path, needs_shared: None) -> None:
    shutil.copy(EPOS4_EDS, tmp_path / "drive.eds")
    spec = tmp_path / "allex2.yaml"
    spec.write_text(
        (SPECS / "allex2.yaml").read_text(encoding="utf-8").replace("device: epos4", "device: {eds: drive.eds}", 1),
        encoding="utf-8",
    )
    loaded, _ = analyse_loaded(spec)
    assert named_files(spec, loaded.data) == [tmp_path / "drive.eds"]
    proc = start(str(spec), "--watch-checks", "2")
    assert "watching 2 file(s)" in read_until(proc, "-- check 1")
    time.sleep(0.05)
    (tmp_path / "drive.eds").write_bytes(EPOS4_EDS.read_bytes() + b"\n")  # saved again: a new check
    assert "OK" in read_until(proc, "-- check 2")
    assert proc.wait(timeout=30) == 0


def test_ctrl_c_ends_it_with_exit_code_0() -> None:
    proc = start(str(SPECS / "cambada.yaml"))
    read_until(proc, "-- check 1")
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=30) == 0
    assert proc.stderr is not None and "Traceback" not in proc.stderr.read()
