"""The command line contract of DESIGN.md: commands, exit codes, the JSON shape, determinism."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from conftest import ROOT, SPECS, cli, cli_json

SEED_SPECS = ["allex2.yaml", "cambada.yaml", "ntua_sahr.yaml", "ntua_treadmill.yaml"]


@pytest.mark.parametrize("name", SEED_SPECS)
def test_check_json_has_the_contract_keys(name: str) -> None:
    code, report = cli_json("check", str(SPECS / name))
    assert code == 0
    assert {"system", "ok", "errors", "warnings", "buses", "flows"} <= report.keys()
    assert isinstance(report["system"], str) and report["ok"] is True
    for b in report["buses"]:
        assert {"name", "protocol", "bitrate", "utilization", "messages"} <= b.keys()
        assert b["protocol"] in ("can", "canopen", "ftt-can", "ethernet-udp")
        assert 0 <= b["utilization"] <= 1
        for m in b["messages"]:
            keys = {"name", "id", "size", "period_us", "frame_bits_worst", "wcrt_us", "deadline_us", "schedulable"}
            assert keys <= m.keys()
    for f in report["flows"]:
        assert {"name", "latency_min_us", "latency_max_us", "deadline_us"} <= f.keys()
        assert f["latency_min_us"] <= f["latency_max_us"]


def test_check_is_deterministic_and_text_is_readable() -> None:
    first = cli("check", str(SPECS / "cambada.yaml"), "--format", "json").stdout
    second = cli("check", str(SPECS / "cambada.yaml"), "--format", "json").stdout
    assert first == second
    text = cli("check", str(SPECS / "cambada.yaml"))
    assert text.returncode == 0
    assert "utilisation 27.0% worst case" in text.stdout and "trigger message 420 us" in text.stdout


def test_several_specs_in_one_run() -> None:
    code, doc = cli_json("check", *(str(SPECS / n) for n in SEED_SPECS))
    assert (
        code == 0
        and doc["ok"]
        and [r["system"] for r in doc["results"]] == ["allex2", "cambada", "ntua_sahr", "ntua_treadmill"]
    )


def test_one_bad_spec_among_good_ones_fails_the_run(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("system: x\n")
    proc = cli("check", str(SPECS / "cambada.yaml"), str(bad))
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert f"{bad}:1:1: error: missing required key 'buses'" in proc.stderr


def test_exit_codes_for_usage_and_io_problems(tmp_path: Path) -> None:
    missing = cli("check", str(tmp_path / "nope.yaml"))
    assert missing.returncode == 2 and "cannot read" in missing.stderr and "Traceback" not in missing.stderr
    directory = cli("check", str(tmp_path))
    assert directory.returncode == 2 and "Traceback" not in directory.stderr
    assert cli("frobnicate").returncode == 2
    assert cli("check").returncode == 2


def test_check_writes_nothing(tmp_path: Path) -> None:
    spec = tmp_path / "cambada.yaml"
    spec.write_text((SPECS / "cambada.yaml").read_text())
    before = sorted(p.name for p in tmp_path.iterdir())
    assert cli("check", str(spec), cwd=tmp_path).returncode == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_schema_describes_the_spec_language() -> None:
    proc = cli("schema")
    assert proc.returncode == 0
    schema = json.loads(proc.stdout)
    assert schema["title"] == "netcfg spec"
    assert {"system", "buses", "nodes"} <= set(schema["required"])
    assert schema["additionalProperties"] is False
    bus = schema["$defs"]["Bus"]["properties"]
    assert bus["protocol"]["enum"] == ["can", "can-fd", "canopen", "ftt-can", "ethernet-udp", "ethercat"]


def test_every_example_spec_validates_against_the_json_schema() -> None:
    """The schema an editor gets accepts the examples (checked with a JSON Schema validator if installed)."""
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads(cli("schema").stdout)
    for path in sorted(SPECS.glob("*.yaml")):
        jsonschema.validate(json.loads(json.dumps(yaml.safe_load(path.read_text()))), schema)


def test_readme_quick_start_names_real_commands() -> None:
    readme = (ROOT / "README.md").read_text()
    assert "make demo" in readme and "make test" in readme
    assert "make test" in (ROOT / ".ci" / "run").read_text()


def test_readme_spec_example_checks(tmp_path: Path) -> None:
    """The spec shown in the README is a valid spec."""
    import re

    block = re.search(r"```yaml[^\n]*\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert block is not None
    spec = tmp_path / "readme.yaml"
    spec.write_text(block.group(1))
    code, report = cli_json("check", str(spec))
    assert code == 0 and report["ok"], report["errors"]


@pytest.mark.parametrize("rate", ["0", "0k"])
def test_a_zero_bit_rate_is_a_usage_error(rate: str) -> None:
    """A bus of 0 bit/s cannot carry a frame; --bitrate refuses it as argparse refuses bad options (exit 2)."""
    r = cli("check", str(SPECS / "cambada.yaml"), "--bitrate", rate)
    assert r.returncode == 2
    assert "is not a bit rate" in r.stderr and "Traceback" not in r.stderr
