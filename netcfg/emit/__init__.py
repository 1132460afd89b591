"""Emitters: one module per output format, each reading the one resolved Model (and the analysis report).

An emitter is a function `emit(model, report) -> {relative path: bytes}`. Text formats render one jinja2
template from templates/ each; the Python side only prepares a view of the model. Adding a format is one
module, one template and one line in EMITTERS.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import os
import re
import sys
import threading
from collections.abc import Callable
from functools import cache
from importlib import resources
from pathlib import Path, PurePosixPath
from typing import Any

import jinja2

from netcfg.model import Model, Signal
from netcfg.runtime.codec import Field

Files = dict[str, bytes]
Emitter = Callable[[Model, dict[str, Any]], Files]

# name -> "module:function"; imported only when a build runs
EMITTERS: dict[str, str] = {
    "canopen": "netcfg.emit.canopen_dcf:emit",  # canopen/<node>.eds, canopen/<node>.dcf
    "concise_dcf": "netcfg.emit.concise_dcf:emit",  # canopen/<node>.bin (Lely's concise DCF, per slave)
    "c_headers": "netcfg.emit.c_header:emit",  # c/<node>.h
    "srt": "netcfg.emit.srt:emit",  # ftt/<bus>_srt.{c,h,csv,md}
    "runtime": "netcfg.emit.runtime_json:emit",  # runtime.json
    "dbc": "netcfg.emit.dbc:emit",  # dbc/<bus>.dbc
    "report": "netcfg.emit.report_html:emit",  # report.md, report/*.png (report_md) and report.html from them
    "report_json": "netcfg.emit.report_json:emit",  # report.json: the check report, for tools and `netcfg diff`
    "bus_yml": "netcfg.emit.bus_yml:emit",  # canopen/bus.yml
}


# Rendered in a forked worker while this process runs the other emitters: the report (importing matplotlib,
# drawing, Markdown to HTML) is a third of a build's CPU and needs nothing the other emitters make.
BACKGROUND = "report"


def emit_all(model: Model, report: dict[str, Any]) -> Files:
    """Every emitter's files, sorted by path. The result, and which error is raised when emitters fail, are those
    of running EMITTERS one after the other; BACKGROUND only overlaps in time where the platform can fork."""
    files: Files = {}
    worker = _Worker.start(BACKGROUND, model, report) if BACKGROUND in EMITTERS else None
    after: list[tuple[str, Files]] = []  # run after BACKGROUND's slot, merged once its files are in
    try:
        for name, target in EMITTERS.items():
            if worker is not None and name == worker.name:
                continue
            try:
                out = _emitter(target)(model, report)
            except Exception:  # (an interrupt is not waited on: the finally below stops the worker)
                if worker is not None and worker.name in _before(name):
                    _merge(files, worker.name, worker.result())  # in sequence its failure would come first
                raise
            if worker is not None and worker.name in _before(name):
                after.append((name, out))
            else:
                _merge(files, name, out)
        if worker is not None:
            _merge(files, worker.name, worker.result())
        for name, out in after:
            _merge(files, name, out)
    finally:
        if worker is not None:
            worker.close()
    return dict(sorted(files.items()))


def _emitter(target: str) -> Emitter:
    module, _, func = target.partition(":")
    emitter: Emitter = getattr(importlib.import_module(module), func)
    return emitter


def _before(name: str) -> list[str]:
    names = list(EMITTERS)
    return names[: names.index(name)]


def _merge(files: Files, name: str, out: Files) -> None:
    for path, data in out.items():
        check_relative(path)
        if path in files:
            raise ValueError(f"emitters '{name}' and another both write {path}")
        files[path] = data


class _Worker:
    """One emitter run in a forked child that sends its files back through a pipe. Where the child cannot give
    them (no fork, the emitter failed, the child died), result() runs the emitter here: the same files, or the
    same exception with its own traceback, as without a worker."""

    def __init__(self, name: str, model: Model, report: dict[str, Any]) -> None:
        self.name, self.model, self.report = name, model, report
        self.process: Any = None
        self.conn: Any = None

    @classmethod
    def start(cls, name: str, model: Model, report: dict[str, Any]) -> _Worker:
        worker = cls(name, model, report)
        # fork without exec is unsafe beside other threads and with macOS's system libraries (CPython's default
        # there is spawn, which would pickle the model over: slower than not overlapping)
        if sys.platform == "darwin" or threading.active_count() > 1:
            return worker
        import multiprocessing

        if "fork" not in multiprocessing.get_all_start_methods():
            return worker
        context = multiprocessing.get_context("fork")
        try:
            receiver, sender = context.Pipe(duplex=False)
        except OSError:  # no descriptor to spare: run it here
            return worker
        for stream in (sys.stdout, sys.stderr):  # else the child would flush the same buffered text again as it exits
            if stream is not None:
                with contextlib.suppress(OSError, ValueError):  # closed or broken: nothing of ours to lose there
                    stream.flush()
        process = context.Process(
            target=_run_worker, args=(EMITTERS[name], model, report, sender, receiver), daemon=True
        )
        gc.freeze()  # the child's collections then leave the inherited objects (and their pages) alone
        try:
            process.start()
        except OSError:  # no process to spare: run it here
            receiver.close()
            sender.close()
            return worker
        finally:
            gc.unfreeze()
        sender.close()  # the child's copy stays open: end of file here once it exits
        worker.process, worker.conn = process, receiver
        return worker

    def result(self) -> Files:
        files = None
        if self.conn is not None:
            try:
                files = self.conn.recv()
            except (EOFError, OSError):
                files = None
            self.process.join()  # it exits once it has sent them
            self.close()
        return files if files is not None else _emitter(EMITTERS[self.name])(self.model, self.report)

    def close(self) -> None:
        """Stop the child if it still runs (another emitter failed) and reap it."""
        if self.process is None:
            return
        if self.process.is_alive():
            self.process.kill()
        self.process.join()
        self.conn.close()
        self.process = self.conn = None


def _run_worker(target: str, model: Model, report: dict[str, Any], conn: Any, parents_end: Any) -> None:
    parents_end.close()  # else, the parent killed, sending would block on a pipe no one reads instead of failing
    try:
        files: Files | None = _emitter(target)(model, report)
    except BaseException:  # the parent runs the emitter again and raises the error itself
        files = None
    # the parent may be gone, or the files may not pickle: then it finds no result and runs the emitter itself
    with contextlib.suppress(BaseException):
        conn.send(files)


def check_relative(path: str) -> None:
    """Generated paths stay inside the output folder (names are checked in the spec already; this is the
    second lock on the door)."""
    p = PurePosixPath(path)
    if p.is_absolute() or ".." in p.parts or not p.parts or any(not _SAFE_PART.match(part) for part in p.parts):
        raise ValueError(f"refusing to write outside the output folder: {path!r}")


_SAFE_PART = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


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
