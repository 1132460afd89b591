"""build -> `import bus-yml` of its bus.yml -> build: the same CANopen files, and for a one-bus system the same
runtime configuration (the master's jitter and queue, tasks, supervision and flows ride in `# netcfg-spec:`
comments). The rule is the README's ("build -> import -> build gives identical CANopen files")."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import ROOT, SPECS, cli


def build(spec: Path, out: Path) -> None:
    proc = cli("build", str(spec), "-o", str(out))
    assert proc.returncode == 0, proc.stdout + proc.stderr


def files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def without_left_out(text: bytes) -> bytes:
    """The header lines naming what runs beyond the bus: a one-bus import cannot have those items any more."""
    return b"".join(line for line in text.splitlines(keepends=True) if b"kept in the netcfg spec: " not in line)


@pytest.mark.parametrize("name", ["allex2", "large_plant"])
def test_build_import_build_gives_the_same_canopen_files(tmp_path: Path, name: str) -> None:
    build(SPECS / f"{name}.yaml", tmp_path / "a")
    proc = cli("import", "bus-yml", str(tmp_path / "a" / "canopen" / "bus.yml"), "-o", str(tmp_path / "again.yaml"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    build(tmp_path / "again.yaml", tmp_path / "b")
    first, second = files(tmp_path / "a" / "canopen"), files(tmp_path / "b" / "canopen")
    assert first.keys() == second.keys()
    for file, content in first.items():
        assert without_left_out(content) == without_left_out(second[file]), file


@pytest.mark.parametrize("spec", [SPECS / "allex2.yaml", ROOT / "examples" / "allex2_recover.yaml"])
def test_a_one_bus_system_comes_back_whole(tmp_path: Path, spec: Path) -> None:
    """ALLEX-2 is one CANopen bus: after the round trip its runtime.json (what the live master and the simulator
    run) differs only in the hash of the spec it came from; the spec's 13 us master_jitter, the master's FIFO of
    depth 16, the SYNC tasks and the seven flows are there again (and, in the recovering variant, on_reboot)."""
    build(spec, tmp_path / "a")
    cli("import", "bus-yml", str(tmp_path / "a" / "canopen" / "bus.yml"), "-o", str(tmp_path / "again.yaml"))
    build(tmp_path / "again.yaml", tmp_path / "b")
    docs = [json.loads((tmp_path / side / "runtime.json").read_text(encoding="utf-8")) for side in "ab"]
    for doc in docs:
        doc.pop("spec_sha256")
    assert docs[0] == docs[1]
    assert docs[1]["buses"][0]["canopen"]["master_jitter_ns"] == 13_000 and len(docs[1]["flows"]) == 7


def test_a_hand_edited_note_is_a_warning_not_a_crash(tmp_path: Path) -> None:
    build(SPECS / "allex2.yaml", tmp_path / "a")
    bus_yml = tmp_path / "a" / "canopen" / "bus.yml"
    lines = bus_yml.read_text(encoding="utf-8").splitlines(keepends=True)
    at = next(i for i, line in enumerate(lines) if line.startswith("# netcfg-spec:"))
    lines[at] = "# netcfg-spec: {not json\n"
    lines.insert(at + 1, '# netcfg-spec: {"node": "elbow", "tx_delay": "1 ms"}\n')
    bus_yml.write_text("".join(lines), encoding="utf-8")
    proc = cli("import", "bus-yml", str(bus_yml), "-o", str(tmp_path / "again.yaml"))
    assert proc.returncode == 0, proc.stderr
    assert f"bus.yml:{at + 1}:" in proc.stderr and "is not JSON" in proc.stderr
    assert f"bus.yml:{at + 2}:" in proc.stderr and "node 'elbow'" in proc.stderr
