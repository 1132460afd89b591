"""A wheel holds every package of the source tree: a user who runs `pip install .` (not -e) gets a working netcfg."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from tests.conftest import ROOT


def test_every_package_is_listed_in_pyproject() -> None:
    if sys.version_info < (3, 11):
        pytest.skip("tomllib is in the standard library from Python 3.11")
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    listed = set(config["tool"]["setuptools"]["packages"])
    in_tree = {
        ".".join(p.parent.relative_to(ROOT).parts)
        for p in (ROOT / "netcfg").rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    assert in_tree - listed == set(), "packages missing from [tool.setuptools] packages"
    for mapped in config["tool"]["setuptools"]["package-dir"]:
        assert mapped in listed


def test_the_wheel_builds_without_a_warning(tmp_path: Path) -> None:
    """setuptools warns of a deprecated `license` table and of data folders missing from `packages`: a user who
    installs netcfg should see neither."""
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w", str(tmp_path), str(ROOT)],
        capture_output=True, text=True, timeout=300, cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout + proc.stderr
    assert "Warning" not in out and "deprecated" not in out, out
    (wheel,) = tmp_path.glob("netcfg-*.whl")
    with zipfile.ZipFile(wheel) as whl:
        assert "netcfg/devices/profiles/epos4.yaml" in whl.namelist()
