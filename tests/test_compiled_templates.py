"""Templates compiled at install: a build reads them and never writes them, renders what the sources render, and
compiles a template anew when its source changed since."""

from __future__ import annotations

from pathlib import Path

import jinja2
import pytest

from netcfg import emit, templating
from netcfg.check import analyse_spec

SPECS = Path(__file__).resolve().parent.parent / "specs"


def _no_compiling(*args: object, **kwargs: object) -> None:
    raise AssertionError("a template was compiled from its source")


def test_a_build_renders_the_same_from_compiled_templates(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every artifact of allex2 and cambada (C headers, DCFs, SRT, report, bus.yml) from templates compiled
    beforehand, with jinja's compiler switched off, is byte for byte what the sources give."""
    written = templating.precompile_templates(tmp_path)
    names = templating.make_environment(None).list_templates(extensions=["j2"])
    assert {p.name.split(".jinja2-")[0] for p in written} == set(names)
    built = {}
    for spec in ("allex2", "cambada"):
        model, report = analyse_spec(SPECS / f"{spec}.yaml")
        assert model is not None
        built[spec] = emit.emit_all(model, report)
    templating.environment.cache_clear()
    monkeypatch.setattr(templating, "compiled_templates_folder", lambda: tmp_path)
    monkeypatch.setattr(jinja2.Environment, "compile", _no_compiling)
    try:
        for spec, files in built.items():
            model, report = analyse_spec(SPECS / f"{spec}.yaml")
            assert model is not None
            assert emit.emit_all(model, report) == files, spec
    finally:
        templating.environment.cache_clear()


def test_a_changed_template_is_compiled_from_its_source(tmp_path: Path) -> None:
    """The compiled file carries its source's checksum: a template edited since is compiled from the edit."""
    compiled = tmp_path / "compiled"
    old = jinja2.Environment(loader=jinja2.DictLoader({"t.j2": "old {{ x }}"}))
    cache = templating.CompiledTemplates(compiled)
    compiled.mkdir()
    bucket = jinja2.bccache.Bucket(old, "t.j2", cache.get_source_checksum("old {{ x }}"))
    bucket.code = old.compile("old {{ x }}", "t.j2", None)
    cache.path("t.j2").write_bytes(bucket.bytecode_to_string())
    stale = jinja2.Environment(loader=jinja2.DictLoader({"t.j2": "new {{ x }}"}), bytecode_cache=cache)
    assert stale.get_template("t.j2").render(x=1) == "new 1"
    same = jinja2.Environment(loader=jinja2.DictLoader({"t.j2": "old {{ x }}"}), bytecode_cache=cache)
    same.compile = _no_compiling  # type: ignore[method-assign,assignment]
    assert same.get_template("t.j2").render(x=1) == "old 1"


def test_loading_templates_writes_nothing(tmp_path: Path) -> None:
    """Without compiled files a build compiles in memory and leaves the folder as it was (netcfg writes only
    into the output folder it owns)."""
    cache = templating.CompiledTemplates(tmp_path)
    env = jinja2.Environment(loader=jinja2.DictLoader({"t.j2": "{{ x }}"}), bytecode_cache=cache)
    assert env.get_template("t.j2").render(x=2) == "2"
    assert list(tmp_path.iterdir()) == []


def test_a_damaged_compiled_file_is_compiled_from_its_source(tmp_path: Path) -> None:
    """A file cut short after jinja's header (its checksum cannot be read) is passed over, not a crash."""
    cache = templating.CompiledTemplates(tmp_path)
    cache.path("t.j2").write_bytes(jinja2.bccache.bc_magic + b"\x80")
    env = jinja2.Environment(loader=jinja2.DictLoader({"t.j2": "{{ x }}"}), bytecode_cache=cache)
    assert env.get_template("t.j2").render(x=3) == "3"
