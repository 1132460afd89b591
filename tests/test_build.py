"""`netcfg build`: refuses bad specs, writes atomically and deterministically, and generated/ is up to date."""

from __future__ import annotations

import filecmp
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from conftest import ROOT, SPECS, cli, load_spec

GENERATED = ROOT / "generated"


def tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_build_writes_every_artifact_and_is_deterministic(tmp_path: Path) -> None:
    first, second = tmp_path / "a", tmp_path / "b"
    assert cli("build", str(SPECS / "cambada.yaml"), "-o", str(first)).returncode == 0
    assert cli("build", str(SPECS / "cambada.yaml"), "-o", str(second)).returncode == 0
    assert tree(first) == tree(second)
    assert (first / "runtime.json").is_file() and (first / "report.md").is_file()


def test_default_output_folder_is_generated_system(tmp_path: Path) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text((SPECS / "ntua_treadmill.yaml").read_text())
    proc = cli("build", str(spec), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "generated" / "ntua_treadmill" / "runtime.json").is_file()


def test_a_spec_with_errors_writes_nothing(tmp_path: Path) -> None:
    data = load_spec("allex2.yaml")
    data["messages"][0]["pdo"]["map"] = [0x6064]  # read-only object in an RPDO
    spec = tmp_path / "bad.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "out"
    proc = cli("build", str(spec), "-o", str(out))
    assert proc.returncode == 1 and "pdo-direction" in proc.stderr and "nothing was written" in proc.stderr
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml"]


@pytest.mark.parametrize("name", ["../../evil", "x*/ #include", "a/b", "..", "con"])
def test_hostile_node_names_are_refused_before_anything_is_written(tmp_path: Path, name: str) -> None:
    data = load_spec("ntua_treadmill.yaml")
    data["nodes"][0]["name"] = name
    spec = tmp_path / "hostile.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    proc = cli("build", str(spec), "-o", str(tmp_path / "out"))
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hostile.yaml"]


def test_a_failing_build_keeps_the_previous_output(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert cli("build", str(SPECS / "cambada.yaml"), "-o", str(out)).returncode == 0
    before = tree(out)
    bad = tmp_path / "bad.yaml"
    bad.write_text("system: cambada\nbuses: [")
    assert cli("build", str(bad), "-o", str(out)).returncode == 1
    assert tree(out) == before


def test_a_build_killed_midway_leaves_old_or_new_output_never_a_mix(tmp_path: Path) -> None:
    """Kill `netcfg build` at many moments; afterwards the folder holds either the previous build of one spec
    or the complete build of the other, and the next build cleans up what the killed one left."""
    out = tmp_path / "out"
    assert cli("build", str(SPECS / "ntua_sahr.yaml"), "-o", str(out)).returncode == 0
    old = tree(out)
    reference = tmp_path / "reference"
    assert cli("build", str(SPECS / "cambada.yaml"), "-o", str(reference)).returncode == 0
    new = tree(reference)
    outcomes = set()
    for delay in [0.05 * k for k in range(2, 26, 2)]:
        proc = subprocess.Popen(
            [sys.executable, "-m", "netcfg", "build", str(SPECS / "cambada.yaml"), "-o", str(out)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        now = tree(out) if out.exists() else None
        if now is None:  # killed between the two renames: the next build restores, then replaces
            assert (tmp_path / ".out.old").exists()
            outcomes.add("between")
        else:
            assert now in (old, new)
            outcomes.add("old" if now == old else "new")
        # back to the old state for the next round
        assert cli("build", str(SPECS / "ntua_sahr.yaml"), "-o", str(out)).returncode == 0
        assert tree(out) == old
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out.")]
    assert "old" in outcomes  # at least one kill landed before the swap


@pytest.mark.parametrize("spec", sorted(SPECS.glob("*.yaml")), ids=lambda p: p.stem)
def test_generated_folder_is_up_to_date(tmp_path: Path, spec: Path) -> None:
    """generated/<system>/ is the committed output of `netcfg build` for specs/ (rebuild with `make generated`)."""
    system = yaml.safe_load(spec.read_text())["system"]
    out = tmp_path / system
    proc = cli("build", str(spec), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    committed = GENERATED / system
    assert committed.is_dir(), f"generated/{system} is missing: run `make generated`"
    cmp = filecmp.dircmp(out, committed)
    what = cmp.diff_files or cmp.left_only or cmp.right_only
    assert tree(out) == tree(committed), f"generated/{system} differs from a fresh build ({what}): make generated"


def test_build_output_paths_never_leave_the_folder() -> None:
    from netcfg.emit import check_relative

    for bad in ["../x", "/etc/passwd", "a/../../b", "", "a/.hidden/../..", "x\\..\\y"]:
        with pytest.raises(ValueError):
            check_relative(bad)
    check_relative("canopen/hip_l.eds")


def test_the_report_drawn_in_a_worker_is_what_drawing_it_here_gives(monkeypatch: pytest.MonkeyPatch) -> None:
    """emit_all renders the report in a forked worker beside the other emitters, forked with the model or (as
    `netcfg build` does) before it and sent it: the same files as one after the other, and no process left
    behind."""
    import multiprocessing

    from netcfg import emit
    from netcfg.check import analyse_spec

    for name in ("allex2", "cambada"):  # a CANopen SYNC cycle plot, an FTT-CAN macro-cycle plot
        early = emit.Background.start()  # before the model exists, as a build starts it
        model, report = analyse_spec(SPECS / f"{name}.yaml")
        assert model is not None
        overlapped = emit.emit_all(model, report)
        assert emit.emit_all(model, report, early) == overlapped, name
        with monkeypatch.context() as m:
            m.setattr(emit, "BACKGROUND", ())
            assert emit.emit_all(model, report) == overlapped, name
        with monkeypatch.context() as m:  # a platform without fork: the report is rendered here
            m.setattr(multiprocessing, "get_all_start_methods", lambda: ["spawn"])
            assert emit.Background.start(model, report).process is None
            assert emit.Background.start().process is None
            assert emit.emit_all(model, report) == overlapped, name
        assert any(path.endswith(".png") for path in overlapped)
    if sys.platform.startswith("linux"):  # where the worker is forked: it is, and its files are the report's
        for worker in (emit.Background.start(model, report), emit.Background.start()):
            assert worker.process is not None
            worker.feed(model, report)
            assert worker.result("report", model, report).items() <= overlapped.items()
            worker.close()
    assert multiprocessing.active_children() == []


def test_a_worker_that_gets_no_model_is_stopped_and_one_that_cannot_be_sent_it_changes_nothing(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A build forks its worker before reading the spec: a refused spec, or a model that does not pickle, leaves
    no process behind and the same output as without the worker."""
    import multiprocessing
    import pickle

    from netcfg import emit
    from netcfg.build import build
    from netcfg.check import analyse_spec

    bad = tmp_path / "bad.yaml"
    bad.write_text("system: x\nbuses: []\n", encoding="utf-8")
    report, target, files = build(bad, tmp_path / "out")
    assert target is None and files == {} and not (tmp_path / "out").exists()
    assert multiprocessing.active_children() == []

    model, report = analyse_spec(SPECS / "allex2.yaml")
    assert model is not None
    expected = emit.emit_all(model, report)

    def refuse(*args: object, **kwargs: object) -> bytes:
        raise pickle.PicklingError("no")

    worker = emit.Background.start()
    monkeypatch.setattr(pickle, "dumps", refuse)
    assert emit.emit_all(model, report, worker) == expected
    assert multiprocessing.active_children() == []


@pytest.mark.parametrize("failing", ["report", "canopen", "bus_yml"])
def test_a_failing_emitter_raises_as_in_order(monkeypatch: pytest.MonkeyPatch, failing: str) -> None:
    """Whichever emitter fails, beside or in the worker, emit_all raises the error running EMITTERS in order would
    raise, and leaves no process behind."""
    import importlib
    import multiprocessing

    from netcfg import emit
    from netcfg.check import analyse_spec

    model, report = analyse_spec(SPECS / "allex2.yaml")
    assert model is not None

    def broken(*args: object) -> dict[str, bytes]:
        raise RuntimeError(f"{failing} is broken")

    module, _, func = emit.EMITTERS[failing].partition(":")
    monkeypatch.setattr(importlib.import_module(module), func, broken)
    with pytest.raises(RuntimeError, match=f"^{failing} is broken$"):
        emit.emit_all(model, report)
    if failing == "bus_yml":  # after the report in EMITTERS: a failing report comes first, as in sequence
        report_module, _, report_func = emit.EMITTERS["report"].partition(":")
        monkeypatch.setattr(importlib.import_module(report_module), report_func, broken_report)
        with pytest.raises(RuntimeError, match=r"^the report is broken$"):
            emit.emit_all(model, report)
    assert multiprocessing.active_children() == []


def broken_report(*args: object) -> dict[str, bytes]:
    raise RuntimeError("the report is broken")
