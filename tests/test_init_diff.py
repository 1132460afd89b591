"""`netcfg init` writes starting specs that check accepts; `netcfg diff` says what changed in timing terms."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.conftest import SPECS, cli, cli_json


def test_init_writes_a_commented_spec_that_checks(tmp_path: Path) -> None:
    spec = tmp_path / "robot.yaml"
    proc = cli("init", "-o", str(spec))
    assert proc.returncode == 0, proc.stderr
    text = spec.read_text()
    assert text.count("\n#") >= 5 and "system: robot" in text  # commented, named after the file
    code, report = cli_json("check", str(spec))
    assert code == 0 and report["ok"] and report["warnings"] == [], report["errors"]


def test_init_to_stdout(tmp_path: Path) -> None:
    proc = cli("init")
    assert proc.returncode == 0 and proc.stdout.startswith("# A starting netcfg spec")
    (tmp_path / "s.yaml").write_text(proc.stdout)
    assert cli_json("check", str(tmp_path / "s.yaml"))[0] == 0


def test_init_never_overwrites_a_file(tmp_path: Path) -> None:
    spec = tmp_path / "mine.yaml"
    spec.write_text("my own work\n")
    proc = cli("init", "-o", str(spec))
    assert proc.returncode == 2 and "exists" in proc.stderr
    assert spec.read_text() == "my own work\n"


@pytest.mark.parametrize(("source", "example"), [("allex2", "allex2"), ("cambada", "cambada"), ("ntua", "ntua_sahr")])
def test_init_from_an_example_system(source: str, example: str, tmp_path: Path) -> None:
    """The example spec itself (its comments name the seed tables), under a header saying where it came from."""
    spec = tmp_path / f"{source}.yaml"
    assert cli("init", "--from", source, "-o", str(spec)).returncode == 0
    text = spec.read_text()
    assert text.startswith("# Started from") and text.endswith((SPECS / f"{example}.yaml").read_text())
    code, report = cli_json("check", str(spec))
    assert code == 0 and report["ok"], report["errors"]


VEHICLE_DBC = """\
VERSION ""

NS_ :

BS_:

BU_: ECU GW

BO_ 256 Speed: 8 ECU
 SG_ Speed : 0|16@1+ (0.01,0) [0|655.35] "km/h" GW

BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_ "GenMsgCycleTime" BO_ 256 10;
"""


def test_init_from_a_dbc(tmp_path: Path) -> None:
    """One 8-byte standard frame every 10 ms (GenMsgCycleTime) at 500 kbit/s: 55 + 10 * 8 = 135 bits worst case
    (Davis et al. 2007) = 270 us, 2.7 % of the bus."""
    dbc = tmp_path / "vehicle.dbc"
    dbc.write_text(VEHICLE_DBC)
    spec = tmp_path / "vehicle.yaml"
    proc = cli("init", "--from", "dbc", str(dbc), "--bitrate", "500k", "-o", str(spec))
    assert proc.returncode == 0, proc.stderr
    code, report = cli_json("check", str(spec))
    assert code == 0, report["errors"]
    assert report["buses"][0]["utilization"] == pytest.approx(0.027)
    assert cli("init", "--from", "dbc", "-o", str(tmp_path / "x.yaml")).returncode == 2  # which DBC?


def _slower_allex2(tmp_path: Path) -> Path:
    text = (SPECS / "allex2.yaml").read_text()
    assert text.count("period: 20 ms") >= 2
    slow = tmp_path / "allex2_slow.yaml"
    slow.write_text(text.replace("period: 20 ms", "period: 40 ms"))
    return slow


def test_diff_of_a_slower_cycle(tmp_path: Path) -> None:
    """SYNC period and every PDO period 20 ms -> 40 ms. Load is the sum of frame time / period over the
    messages, so that part halves exactly; the six drives' heartbeats (1 byte every 100 ms: 55 + 10 * 1 = 65 bits
    worst case at 1 Mbit/s, Davis et al. 2007, = 65 us / 100 ms each) stay. Every periodic message reports its new
    period and deadline; the files that carry the period change, the drives' EDS/DCF do not (the EPOS4 has no
    0x1006 to write)."""
    slow = _slower_allex2(tmp_path)
    proc = cli("diff", "specs/allex2.yaml", str(slow), "--format", "json")
    assert proc.returncode == 1  # different, as diff(1)
    d = json.loads(proc.stdout)
    (bus,) = d["buses"]
    before, after = bus["utilization"]
    heartbeats = 6 * 65 / 100_000
    assert after == pytest.approx((before - heartbeats) / 2 + heartbeats, rel=1e-9)
    cmd = next(m for m in d["messages"] if m["name"] == "hip_l_cmd")
    assert (cmd["a"]["period_us"], cmd["b"]["period_us"]) == (20_000, 40_000)
    assert (cmd["a"]["deadline_us"], cmd["b"]["deadline_us"]) == (20_000, 40_000)
    assert {"runtime.json", "canopen/master.dcf", "dbc/can0.dbc"} <= set(d["artifacts"]["changed"])
    assert not any(p.endswith(("hip_l.dcf", "hip_l.eds")) for p in d["artifacts"]["changed"])
    text = cli("diff", "specs/allex2.yaml", str(slow)).stdout
    assert "bus can0: load" in text and "-> " in text and "message hip_l_cmd: period us 20,000 -> 40,000" in text


def test_diff_of_the_same_system_is_empty_across_specs_and_build_folders(tmp_path: Path) -> None:
    """A spec, its build folder and a second build are the same system: no difference, exit 0."""
    for name in ("b1", "b2"):
        assert cli("build", "specs/cambada.yaml", "-o", str(tmp_path / name)).returncode == 0
    for a, b in (("specs/cambada.yaml", "specs/cambada.yaml"), (str(tmp_path / "b1"), str(tmp_path / "b2")),
                 ("specs/cambada.yaml", str(tmp_path / "b1"))):
        proc = cli("diff", a, b)
        assert proc.returncode == 0 and "no difference" in proc.stdout, proc.stdout + proc.stderr


def test_diff_refuses_what_it_cannot_compare(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    proc = cli("diff", "specs/cambada.yaml", str(tmp_path / "empty"))
    assert proc.returncode == 2 and "report.json" in proc.stderr and "Traceback" not in proc.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text("system: x\nbuses: []\nnodes: []\nmessages:\n  - {name: m, producer: ghost, size: 1}\n")
    proc = cli("diff", "specs/cambada.yaml", str(bad))
    assert proc.returncode == 2 and f"{bad}:" in proc.stderr and "Traceback" not in proc.stderr
