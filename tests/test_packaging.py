"""A wheel holds every package of the source tree: a user who runs `pip install .` (not -e) gets a working netcfg."""

from __future__ import annotations

import sys

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
