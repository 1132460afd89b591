"""Shared helpers: the repository layout and a way to check a spec, from a file or from YAML text."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
import yaml

if TYPE_CHECKING:
    from netcfg.runtime import RuntimeConfig

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))  # tests import the benchmarks' modules (soundness, sim_peers)
SPECS = ROOT / "specs"
SHARED = ROOT.parent / "shared"
EPOS4_EDS = SHARED / "devices" / "maxon_epos4_50-5.eds"

# The modules whose tests run a master on the wall clock (python-can's virtual bus, the simulated drives and
# actuators as threads of the test's own process) and judge it against the analysis' bounds. They are marked `live`:
# `make test` runs them after the others, alone, so that no other test shares the cores with them; the others run
# one worker per core (pytest-xdist).
LIVE_MODULES = frozenset({
    "test_actuator_remote", "test_canopen_master", "test_closure_run_verify", "test_fault_drills", "test_run",
    "test_run_actuators", "test_udp_runtime", "test_verify_fault_phases",
})


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if item.path.stem in LIVE_MODULES:
            item.add_marker(pytest.mark.live)


def check(path: Path) -> dict[str, Any]:
    from netcfg.check import check as run

    return run(path)


def check_data(tmp_path: Path, data: dict[str, Any], name: str = "spec.yaml") -> dict[str, Any]:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return check(path)


def runtime_config(path: Path) -> RuntimeConfig:
    """The runtime configuration `netcfg build` writes for a spec, which check must accept."""
    from netcfg import runtime
    from netcfg.check import analyse_spec
    from netcfg.emit.runtime_json import runtime_document

    model, report = analyse_spec(path)
    assert model is not None and not report["errors"], report["errors"]
    return runtime.parse(json.loads(json.dumps(runtime_document(model, report))), str(path))


def runtime_config_of(path: Path, data: dict[str, Any]) -> RuntimeConfig:
    """The same for a spec written as a dict, which is saved at path first."""
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return runtime_config(path)


def load_spec(name: str) -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load((SPECS / name).read_text(encoding="utf-8"))
    return data


def cli(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "netcfg", *args], capture_output=True, text=True, cwd=cwd, timeout=120)


def cli_json(*args: str) -> tuple[int, dict[str, Any]]:
    proc = cli(*args, "--format", "json")
    return proc.returncode, json.loads(proc.stdout)


def bus(report: dict[str, Any], name: str) -> dict[str, Any]:
    return next(b for b in report["buses"] if b["name"] == name)


def message(bus_report: dict[str, Any], name: str) -> dict[str, Any]:
    return next(m for m in bus_report["messages"] if m["name"] == name)


@pytest.fixture
def needs_shared() -> None:
    if not EPOS4_EDS.is_file():
        pytest.skip("the shared vendor device files are not next to this checkout")


@pytest.fixture
def no_leaked_threads() -> Iterator[None]:
    """The drives' heartbeat and Notifier threads and the master's are all stopped by the end of each test (the live
    master's tests use it: `pytestmark = pytest.mark.usefixtures("no_leaked_threads")`)."""
    before = set(threading.enumerate())
    yield
    deadline = time.monotonic() + 2.0
    while (
        left := [t for t in threading.enumerate() if t not in before and t.is_alive()]
    ) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert left == [], left


def allex2_cia402_over_pdos() -> str:
    """ALLEX-2's spec with hip_l's controlword in its RxPDO1 (beside 0x60FF) and its statusword in its TPDO2 (16 + 32
    + 16 = 64 bits): the master walks it through CiA 402 over those PDOs."""
    text = (SPECS / "allex2.yaml").read_text(encoding="utf-8")
    for old, new in (
        ("pdo: {rpdo: 1, transmission: 255, map: [0x60FF, 0x60B1]}",
         "pdo: {rpdo: 1, transmission: 255, map: [0x60FF, 0x6040]}"),
        ('pdo: {tpdo: 2, transmission: 1, map: [0x6077, "0x30D1:2"]}',
         'pdo: {tpdo: 2, transmission: 1, map: [0x6077, "0x30D1:2", 0x6041]}'),
    ):
        assert old in text, old
        text = text.replace(old, new, 1)
    return text
