"""The input guard: every file netcfg reads (spec, EDS/DCF, DBC, bus.yml, runtime.json) comes through here.

A file is refused before any byte is read when it is not a regular file (/dev/zero, a FIFO, a folder) or is
larger than the limit for its kind, so an endless or huge input is refused at once instead of filling memory.
Text is decoded as UTF-8 (a byte-order mark is dropped); vendor EDS/DCF files may fall back to Windows-1252,
as CANopen tools accept them. JSON is checked for nesting depth before it is parsed.

Standard library only: netcfg.runtime, which a live master imports without the compiler, reads through it.
"""

from __future__ import annotations

import codecs
import json
import os
import stat
from pathlib import Path
from typing import Any

SPEC_SUFFIXES = (".yaml", ".yml")  # what a folder of specs holds: check's and the language server's

MiB = 1024 * 1024
# The largest files of each kind netcfg accepts. Real ones are far smaller: the 126-drive bus.yml benchmark is
# under 100 kB, maxon's EPOS4 EDS about 400 kB, the largest spec in specs/ under 200 kB.
MAX_BYTES: dict[str, int] = {
    "spec": 16 * MiB,
    "EDS": 16 * MiB,
    "DCF": 16 * MiB,
    "DBC": 32 * MiB,
    "bus.yml": 16 * MiB,
    "runtime config": 64 * MiB,
}
DEFAULT_MAX_BYTES = 16 * MiB
MAX_JSON_DEPTH = 64  # runtime.json nests 6 levels; anything deeper is not one
UTF8_BOM = b"\xef\xbb\xbf"


class InputError(OSError):
    """An input that cannot be read; the message names the file and what to do. An OSError, so every command
    already reports it as an I/O problem (exit 2)."""

    def __init__(self, path: object, message: str, line: int | None = None) -> None:
        super().__init__(message)
        self.path = str(path)
        self.message = message
        self.line = line  # where in the file, for problems of its content

    def __str__(self) -> str:
        return self.message


def read_input_bytes(path: str | os.PathLike[str], what: str = "input") -> bytes:
    """The whole file, refused (InputError) when it is not a regular file or is too large for `what`."""
    limit = MAX_BYTES.get(what, DEFAULT_MAX_BYTES)
    name = os.fspath(path)
    if "\0" in name:
        raise InputError(name, f"{name!r}: not a valid path (it contains a NUL byte)")
    try:
        # O_NONBLOCK: opening a FIFO must not wait for a writer; we refuse it right after
        fd = os.open(name, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise InputError(name, f"cannot read {what} {name}: {exc.strerror or exc}") from exc
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputError(name, f"{name} is a folder; give the {what} file inside it")
        if not stat.S_ISREG(info.st_mode):
            raise InputError(name, f"{name} is not a regular file (a device or pipe); give the {what} file itself")
        if info.st_size > limit:
            raise InputError(name, f"{name} is {info.st_size:,} bytes; a {what} file may be at most {limit:,}")
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(limit + 1)  # a file that grows while we read stays bounded too
    except InputError:
        raise
    except OSError as exc:
        raise InputError(name, f"cannot read {what} {name}: {exc.strerror or exc}") from exc
    finally:
        os.close(fd)
    if len(data) > limit:
        raise InputError(name, f"{name} is larger than {limit:,} bytes, the most a {what} file may be")
    return data


def decode_text(data: bytes, path: str | os.PathLike[str], what: str = "input", legacy: bool = False) -> str:
    """UTF-8 text without its byte-order mark. legacy=True: Windows-1252 when the bytes are not UTF-8 (vendor EDS
    files written on Windows), with latin-1 for the five bytes cp1252 leaves undefined."""
    data = data.removeprefix(UTF8_BOM)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        if not legacy:
            line = data[: exc.start].count(b"\n") + 1
            message = f"{os.fspath(path)}:{line}: the {what} is not UTF-8 text; save it as UTF-8"
            raise InputError(path, message, line) from exc
        text = data.decode("cp1252", errors=_LATIN1_FALLBACK)
    if "\0" in text:
        line = text[: text.index("\0")].count("\n") + 1
        raise InputError(path, f"{os.fspath(path)}:{line}: the {what} contains a NUL byte; it is not a text file", line)
    return text


def _latin1(exc: UnicodeError) -> tuple[str, int]:
    assert isinstance(exc, UnicodeDecodeError)
    return exc.object[exc.start : exc.end].decode("latin-1"), exc.end


_LATIN1_FALLBACK = "netcfg-latin1"
codecs.register_error(_LATIN1_FALLBACK, _latin1)


def read_input_text(path: str | os.PathLike[str], what: str = "input", legacy: bool = False) -> str:
    """The file as text, through the size guard and decode_text (see there); InputError when it cannot be."""
    return decode_text(read_input_bytes(path, what), path, what, legacy)


def json_depth_ok(text: str, limit: int = MAX_JSON_DEPTH) -> bool:
    """True when no bracket nesting in the JSON text goes deeper than limit (strings are skipped)."""
    depth = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > limit:
                return False
        elif ch in "]}":
            depth -= 1
    return True


class JsonInputError(ValueError):
    """The text is not JSON netcfg reads: message says where and why."""


def parse_json(text: str, limit: int = MAX_JSON_DEPTH) -> Any:
    """json.loads with a depth limit checked before parsing and integers bounded (no 5,000-digit numbers)."""
    if not json_depth_ok(text, limit):
        raise JsonInputError(f"nested deeper than {limit} levels")
    try:
        return json.loads(text, parse_int=_bounded_int, parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise JsonInputError(f"line {exc.lineno} column {exc.colno}: not valid JSON ({exc.msg})") from exc


MAX_INT_DIGITS = 64  # 10^40 still reaches the range checks (and is refused there with its field named)


def _bounded_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise JsonInputError(f"an integer of {len(text)} digits; no field of it holds more than {MAX_INT_DIGITS}")
    return int(text)


def _no_constant(name: str) -> Any:
    raise JsonInputError(f"{name} is not a number JSON allows")


def check_input_path(base: Path, relative: str, what: str) -> Path:
    """A path written inside an input (e.g. a spec's `eds:`), resolved against base. ValueError with the reason
    (a NUL byte, a symlink loop, not a file) so that the caller can place it at the spec's line."""
    if "\0" in relative:
        raise ValueError(f"{relative!r} is not a valid path (it contains a NUL byte); write the file's name")
    try:
        file = (base / relative).resolve()
        ok = file.is_file()
    except (OSError, RuntimeError) as exc:  # RuntimeError: Python < 3.13 reports a symlink loop so
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else "Too many levels of symbolic links"
        raise ValueError(f"cannot read {what} '{relative}': {reason}") from exc
    if not ok:
        raise ValueError(f"{what} '{relative}' not found (looked for {file}); paths are relative to the spec")
    return file
