"""The jinja2 templates every text emitter renders (templates/, shipped as netcfg.templates): the environment and its
filters for C and identifiers, the templates compiled once at install, and the codec field of a model's signal that
the C headers share with the runtime. The protocols' emitters (netcfg.protocols) render with it as netcfg.emit's do.
"""

from __future__ import annotations

import os
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import jinja2

from netcfg.model import Signal
from netcfg.runtime.codec import Field


def c_comment(text: object) -> str:
    """Text that cannot close or nest a C comment, nor break the line."""
    return " ".join(str(text).replace("*/", "* /").replace("/*", "/ *").split())


def c_string(text: object) -> str:
    """Contents of a C string literal: printable ASCII as is, everything else as 3-digit octal escapes."""
    out = []
    for byte in str(text).encode("utf-8"):
        ch = chr(byte)
        if ch in '"\\?':
            out.append("\\" + ch)
        elif 32 <= byte < 127:
            out.append(ch)
        else:
            out.append(f"\\{byte:03o}")
    return "".join(out)


def hex_id(value: int, width: int = 3) -> str:
    return f"0x{value:0{width}X}"


def c_uint(value: int) -> str:
    """An unsigned C integer constant of at least the value's width."""
    return f"{'UINT32_C' if value < 4294967296 else 'UINT64_C'}({value})"


class CompiledTemplates(jinja2.BytecodeCache):
    """Templates compiled once, at install (precompile_templates), and only read while netcfg runs: jinja would
    otherwise lex, parse and compile every template again in every process (0.07 s of a build), and netcfg
    writes nothing outside the output folder it owns. jinja uses a file only when its own checks pass (the same
    template source by checksum, its bytecode format, this Python's version) and else compiles from the source."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def get_cache_key(self, name: str, filename: str | None = None) -> str:
        return name  # our template names are plain file names; where the package is installed does not matter

    def path(self, key: str) -> Path:
        # jinja checks its bytecode format, not the code it generates: another jinja version compiles anew
        return self.folder / f"{key}.jinja2-{jinja2.__version__}.cache"

    def load_bytecode(self, bucket: jinja2.bccache.Bucket) -> None:
        try:
            data = self.path(bucket.key).read_bytes()
        except OSError:
            return
        try:
            bucket.bytecode_from_string(data)
        except Exception:  # a damaged file (jinja checks the header, not the rest): compile from the source
            bucket.reset()

    def dump_bytecode(self, bucket: jinja2.bccache.Bucket) -> None:
        pass  # never written while netcfg runs; precompile_templates writes them


def templates_folder() -> Path:
    return Path(str(resources.files("netcfg.templates")))


def compiled_templates_folder() -> Path:
    return templates_folder() / "__pycache__"  # beside the package's own compiled modules, ignored by git


def precompile_templates(folder: Path | None = None) -> list[Path]:
    """Compile every template into folder (default: compiled_templates_folder()), for `make` after installing.
    -> the files written."""
    cache = CompiledTemplates(folder or compiled_templates_folder())
    env = make_environment(None)
    cache.folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name in env.list_templates(extensions=["j2"]):
        source, filename, _ = env.loader.get_source(env, name)  # type: ignore[union-attr]
        bucket = jinja2.bccache.Bucket(env, cache.get_cache_key(name), cache.get_source_checksum(source))
        bucket.code = env.compile(source, name, filename)
        path = cache.path(bucket.key)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_bytes(bucket.bytecode_to_string())
        os.replace(tmp, path)  # a build reading it meanwhile sees the old file or the new one
        written.append(path)
    return written


@cache
def environment() -> jinja2.Environment:
    return make_environment(CompiledTemplates(compiled_templates_folder()))


def make_environment(compiled: jinja2.BytecodeCache | None) -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_folder())),
        bytecode_cache=compiled,
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
        autoescape=False,
    )
    env.filters.update(
        c_comment=c_comment, c_string=c_string, c_uint=c_uint, hex_id=hex_id, upper_ident=lambda s: str(s).upper()
    )
    return env


def render(template: str, **context: Any) -> bytes:
    return environment().get_template(template).render(**context).encode("utf-8")


def field_of(sig: Signal) -> Field:
    """The codec field of a model signal (the runtime and the C headers share this layout)."""
    return Field(
        sig.name,
        sig.start_bit,
        sig.bits,
        sig.signed,
        sig.is_float,
        sig.scale,
        sig.offset,
        sig.minimum,
        sig.maximum,
        sig.big_endian,
        sig.mux,
        sig.mux_values,
        sig.choices,
    )
