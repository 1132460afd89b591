"""`netcfg check DIR`, `check --quiet` and `simulate --force`: the small things a new user expects."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from tests.conftest import SPECS, cli

OVERLOADED = """\
system: over
buses:
  - {name: can0, protocol: can, bitrate: 125 kbit/s}
nodes:
  - {name: a, buses: [can0]}
  - {name: b, buses: [can0]}
messages:
  - {name: m1, producer: a, consumers: [b], id: 0x100, size: 8, period: 1 ms}
  - {name: m2, producer: a, consumers: [b], id: 0x101, size: 8, period: 1 ms}
"""


def test_check_a_folder_checks_every_spec_in_it() -> None:
    proc = cli("check", "specs", "--format", "json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    expected = sorted(p.stem for p in SPECS.glob("*.yaml"))  # each example spec names its system after its file
    assert sorted(r["system"] for r in doc["results"]) == expected


def test_a_bad_spec_in_the_folder_fails_the_run_and_quiet_prints_only_it(tmp_path: Path) -> None:
    shutil.copy(SPECS / "cambada.yaml", tmp_path / "cambada.yaml")
    (tmp_path / "over.yaml").write_text(OVERLOADED)
    (tmp_path / "notes.txt").write_text("not a spec")
    proc = cli("check", str(tmp_path), "--quiet")
    assert proc.returncode == 1
    assert proc.stdout == ""  # no tables, no line for the good spec
    problems = proc.stderr.splitlines()
    assert problems and all(line.startswith(f"{tmp_path / 'over.yaml'}:") for line in problems), problems
    assert any("[overload]" in line for line in problems)


def test_quiet_prints_nothing_for_good_specs() -> None:
    proc = cli("check", "-q", "specs/cambada.yaml", "specs/allex2.yaml")
    assert (proc.returncode, proc.stdout, proc.stderr) == (0, "", "")


def test_a_folder_without_specs_is_a_usage_error(tmp_path: Path) -> None:
    proc = cli("check", str(tmp_path))
    assert proc.returncode == 2 and "no specs" in proc.stderr and "Traceback" not in proc.stderr


def test_simulate_refuses_a_refused_spec_unless_forced(tmp_path: Path) -> None:
    """Two 8-byte frames every 1 ms at 125 kbit/s: 135 bits (55 + 10 * 8, Davis et al. 2007) = 1,080 us each,
    216 % of the bus. check refuses it; simulate --force runs it and shows the misses, never more frames than
    the bus can carry: 100 ms / 1,080 us = 92 frames."""
    spec = tmp_path / "over.yaml"
    spec.write_text(OVERLOADED)
    refused = cli("simulate", str(spec), "--duration", "100ms")
    assert refused.returncode == 1 and "--force" in refused.stderr and refused.stdout == ""
    forced = cli("simulate", str(spec), "--duration", "100ms", "--force", "--format", "json")
    assert forced.returncode == 1  # it misses deadlines, and says so
    assert "warning" in forced.stderr and "--force" in forced.stderr
    doc = json.loads(forced.stdout)
    assert 0 < doc["frames"] <= 92
    assert doc["deadline_misses"] > 0
