"""Emitters: one module per output format, each reading the one resolved Model (and the analysis report).

An emitter is a function `emit(model, report) -> {relative path: bytes}`. Text formats render one jinja2
template from templates/ each; the Python side only prepares a view of the model. Adding a format is one
module, one template and one line in EMITTERS.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import pickle
import re
import sys
import threading
from collections.abc import Callable
from pathlib import PurePosixPath
from typing import Any

from netcfg.model import Model
from netcfg.templating import field_of, precompile_templates, render

__all__ = ["EMITTERS", "Background", "Files", "emit_all", "field_of", "precompile_templates", "render"]

Files = dict[str, bytes]
Emitter = Callable[[Model, dict[str, Any]], Files]

# name -> "module:function"; imported only when a build runs
EMITTERS: dict[str, str] = {
    "canopen": "netcfg.protocols.canopen.dcf:emit",  # canopen/<node>.eds, canopen/<node>.dcf
    "concise_dcf": "netcfg.protocols.canopen.concise_dcf:emit",  # canopen/<node>.bin (Lely's concise DCF, per slave)
    "c_headers": "netcfg.emit.c_header:emit",  # c/<node>.h
    "srt": "netcfg.protocols.ftt.srt:emit",  # ftt/<bus>_srt.{c,h,csv,md}
    "runtime": "netcfg.emit.runtime_json:emit",  # runtime.json
    "dbc": "netcfg.emit.dbc:emit",  # dbc/<bus>.dbc
    "report": "netcfg.emit.report_html:emit",  # report.md, report/*.png (report_md) and report.html from them
    "report_json": "netcfg.emit.report_json:emit",  # report.json: the check report, for tools and `netcfg diff`
    "bus_yml": "netcfg.emit.bus_yml:emit",  # canopen/bus.yml
    "ros2_control": "netcfg.emit.ros2_control:emit",  # ros2_control/<system>.ros2_control.xacro, controllers.yaml
    "ethercat_ros2": "netcfg.protocols.ethercat.ros2:emit",  # ethercat/<bus>/<node>.yaml (ethercat_driver_ros2)
    "ethercat_image": "netcfg.protocols.ethercat.c_image:emit",  # ethercat/<bus>_image.h
}


# Run in a forked worker while this process runs the other emitters. Forked at the start of a build, the worker
# imports what they need (matplotlib and Python-Markdown: a fifth of a build's CPU) while this process reads and
# analyses the spec; then it is sent the model and renders them. They need nothing the others make.
BACKGROUND: tuple[str, ...] = ("report",)


def emit_all(model: Model, report: dict[str, Any], worker: Background | None = None) -> Files:
    """Every emitter's files, sorted by path. The result, and which error is raised when emitters fail, are those
    of running EMITTERS one after the other; BACKGROUND only overlaps in time where the platform can fork.

    worker: one started before the model existed (Background.start()); it is sent the model here. Without one,
    a worker is forked here, with the model in its memory. Either way it is closed on return."""
    if worker is None:
        worker = Background.start(model, report)
    outputs: dict[str, Files] = {}
    try:
        worker.feed(model, report)
        for name, target in EMITTERS.items():
            if name in worker.names:
                continue
            try:
                outputs[name] = _emitter(target)(model, report)
            except Exception:  # (an interrupt is not waited on: the finally below stops the worker)
                for earlier in _before(name):  # in sequence, their failure would have come first
                    if earlier in worker.names:
                        worker.result(earlier, model, report)
                raise
        for name in worker.names:
            outputs[name] = worker.result(name, model, report)
    finally:
        worker.close()
    files: Files = {}
    for name in EMITTERS:
        _merge(files, name, outputs[name])
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


class Background:
    """The BACKGROUND emitters, run in a forked child that sends their files back through a pipe. Where the child
    cannot give an emitter's files (no fork, the emitter failed, the model did not reach it, the child died),
    result() runs that emitter here: the same files, or the same exception with its own traceback, as without a
    worker. names is empty where nothing runs in the background."""

    def __init__(self, names: tuple[str, ...]) -> None:
        self.names = names
        self.process: Any = None
        self.results: Any = None  # the child's end of its results pipe, then {name: files or None}
        self.model_feed: Any = None  # where the model goes, for a worker forked before it existed
        self.sender: threading.Thread | None = None

    @classmethod
    def start(cls, model: Model | None = None, report: dict[str, Any] | None = None) -> Background:
        """Fork the worker; without a model it waits for feed() meanwhile importing what its emitters need."""
        names = tuple(n for n in EMITTERS if n in BACKGROUND)
        worker = cls(names)
        # fork without exec is unsafe beside other threads and with macOS's system libraries (CPython's default
        # there is spawn, which would pickle the model over: slower than not overlapping)
        if not names or sys.platform == "darwin" or threading.active_count() > 1:
            return worker
        import multiprocessing

        if "fork" not in multiprocessing.get_all_start_methods():
            return worker
        context = multiprocessing.get_context("fork")
        ends: list[tuple[Any, Any]] = []
        try:
            ends.append(context.Pipe(duplex=False))  # results: child -> here
            if model is None:
                ends.append(context.Pipe(duplex=False))  # the model: here -> child
        except OSError:  # no descriptor to spare: run them here
            for pair in ends:
                for end in pair:
                    end.close()
            return worker
        (receiver, sender), feed = ends[0], (ends[1] if len(ends) > 1 else (None, None))
        for stream in (sys.stdout, sys.stderr):  # else the child would flush the same buffered text again as it exits
            if stream is not None:
                with contextlib.suppress(OSError, ValueError):  # closed or broken: nothing of ours to lose there
                    stream.flush()
        keep: list[Any] = [sender, feed[0]]  # the child's ends
        drop: list[Any] = [receiver, feed[1]]  # ours, which the child closes
        process = context.Process(target=_serve, args=(names, model, report, keep, drop), daemon=True)
        gc.freeze()  # the child's collections then leave the inherited objects (and their pages) alone
        try:
            process.start()
        except OSError:  # no process to spare: run them here
            for end in keep + drop:
                if end is not None:
                    end.close()
            return worker
        finally:
            gc.unfreeze()
        for end in keep:  # the child's copies stay open: end of file here once it exits
            if end is not None:
                end.close()
        worker.process, worker.results, worker.model_feed = process, receiver, feed[1]
        return worker

    def feed(self, model: Model, report: dict[str, Any]) -> None:
        """Send the model to a worker that was started without one (from a thread: the child may still be
        importing, and the pipe holds only a part of it)."""
        if self.model_feed is None:
            return
        conn, self.model_feed = self.model_feed, None
        try:
            data = pickle.dumps((model, report), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # something in the model does not pickle: the child gets nothing, these run here
            conn.close()
            return

        def send() -> None:
            with contextlib.suppress(OSError):  # the child is gone: result() finds nothing and runs them here
                conn.send_bytes(data)
            conn.close()

        self.sender = threading.Thread(target=send, name="netcfg-feed", daemon=True)
        self.sender.start()

    def result(self, name: str, model: Model, report: dict[str, Any]) -> Files:
        if self.results is not None and not isinstance(self.results, dict):
            conn = self.results
            try:
                received = conn.recv()
            except (EOFError, OSError, pickle.UnpicklingError):
                received = None
            self.results = received if isinstance(received, dict) else {}
            self.process.join()  # it exits once it has sent them
            conn.close()
        files = self.results.get(name) if isinstance(self.results, dict) else None
        return files if files is not None else _emitter(EMITTERS[name])(model, report)

    def close(self) -> None:
        """Stop the child if it still runs (an emitter here failed, or the spec was refused) and reap it."""
        if self.model_feed is not None:
            self.model_feed.close()
            self.model_feed = None
        if self.process is not None:
            if self.process.is_alive():
                self.process.kill()
            self.process.join()
            self.process = None
        if self.sender is not None:
            self.sender.join()  # ends once the child has read it or is gone
            self.sender = None
        if self.results is not None and not isinstance(self.results, dict):
            self.results.close()
        self.results = None


def _serve(
    names: tuple[str, ...], model: Model | None, report: dict[str, Any] | None, ends: list[Any], parents: list[Any]
) -> None:
    """The worker: the BACKGROUND emitters' files, or None for one that failed (the parent runs it again and
    raises the error itself), sent as one {name: files}."""
    for end in parents:  # else, the parent killed, sending would block on a pipe no one reads instead of failing
        if end is not None:
            end.close()
    results, feed = ends
    outputs: dict[str, Files | None] = {}
    try:
        for name in names:  # imported while the parent reads and analyses the spec
            module = importlib.import_module(EMITTERS[name].partition(":")[0])
            warm_up = getattr(module, "warm_up", None)
            if warm_up is not None:
                warm_up()
        if feed is not None:
            model, report = pickle.loads(feed.recv_bytes())
            feed.close()
    except BaseException:
        model = None
    if model is not None and report is not None:
        for name in names:
            try:
                outputs[name] = _emitter(EMITTERS[name])(model, report)
            except BaseException:
                outputs[name] = None
    # the parent may be gone, or the files may not pickle: then it finds nothing and runs the emitters itself
    with contextlib.suppress(BaseException):
        results.send(outputs)


def check_relative(path: str) -> None:
    """Generated paths stay inside the output folder (names are checked in the spec already; this is the
    second lock on the door)."""
    p = PurePosixPath(path)
    if p.is_absolute() or ".." in p.parts or not p.parts or any(not _SAFE_PART.match(part) for part in p.parts):
        raise ValueError(f"refusing to write outside the output folder: {path!r}")


_SAFE_PART = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
