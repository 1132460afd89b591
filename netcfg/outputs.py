"""The path guard: netcfg replaces only what it wrote, and never writes over its own input.

Every output folder carries a manifest (MANIFEST: the files netcfg wrote there and the spec's SHA-256). A build
may replace a folder only when it is absent, empty, or carries that manifest; anything else (a user's folder, a
regular file, the current folder or one above it, the folder holding the spec) is refused with OutputError
before anything is touched. Inside its own folder netcfg replaces only what the manifest lists: files the user
added there are carried over into the new tree and named in a warning.

The new tree is written into a temporary folder beside the output and swapped in by two renames, under a lock
on the parent folder, so two builds never mix their trees and a killed build leaves the old or the new tree.
Temporary and backup folders have names ending in TMP_TAG/OLD_TAG and carry a MARKER file; a later build removes
a leftover only when it carries the marker, so a user's folder that happens to look alike is never touched.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import secrets
import shutil
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

from netcfg import jsontext

MANIFEST = ".netcfg-manifest.json"
MANIFEST_FORMAT = "netcfg-output"
MARKER = ".netcfg-temporary"  # inside temporary and backup folders only
TMP_TAG = ".netcfg-tmp-"
OLD_TAG = ".netcfg-old"


class OutputError(OSError):
    """An output netcfg refuses to write (exit 2): the message names the path and what to do."""

    def __init__(self, path: object, message: str) -> None:
        super().__init__(message)
        self.path = str(path)
        self.message = message

    def __str__(self) -> str:
        return self.message


def manifest_bytes(files: Mapping[str, bytes], spec_sha256: str) -> bytes:
    """The manifest of a tree: deterministic (sorted, no time stamps), so it can be committed with the tree."""
    doc = {
        "format": MANIFEST_FORMAT,
        "version": 1,
        "spec_sha256": spec_sha256,
        "files": {name: hashlib.sha256(files[name]).hexdigest() for name in sorted(files)},
    }
    return (jsontext.dumps(doc, indent=2, sort_keys=True) + "\n").encode("utf-8")


def read_manifest(folder: Path) -> set[str] | None:
    """The files a folder's manifest lists; None when the folder has no readable netcfg manifest."""
    try:
        doc = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("format") != MANIFEST_FORMAT or not isinstance(doc.get("files"), dict):
        return None
    return {name for name in doc["files"] if isinstance(name, str)}


def _within(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def check_output_folder(out: Path, inputs: Iterable[Path] = ()) -> Path:
    """The real folder a build may replace, or OutputError (nothing touched). A symlink is followed and its target
    judged by the same rules."""
    real = Path(os.path.realpath(out))
    shown = str(out)
    if real.exists() and not real.is_dir():
        raise OutputError(out, f"{shown} is a file, not a folder; give -o a new or empty folder, or one netcfg wrote")
    cwd = Path(os.path.realpath(Path.cwd()))
    if _within(cwd, real):
        raise OutputError(out, f"{shown} is the current folder or holds it; give -o a folder of its own, e.g. build/")
    for source in inputs:
        if _within(Path(os.path.realpath(source)), real):
            raise OutputError(
                out, f"{shown} holds the input {source}; give -o a folder of its own, e.g. {Path(shown) / 'build'}"
            )
    if real.is_dir() and read_manifest(real) is None and any(real.iterdir()):
        raise OutputError(
            out,
            f"{shown} holds files netcfg did not write (it has no {MANIFEST}); nothing was touched. Give -o a new "
            "or empty folder, or move those files away",
        )
    return real


@contextlib.contextmanager
def locked(folder: Path) -> Iterator[None]:
    """An exclusive lock on folder (flock on the folder itself: no lock file is left behind). A second build into
    the same parent waits for the first to finish."""
    fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def _is_ours(folder: Path) -> bool:
    return folder.is_dir() and not folder.is_symlink() and (folder / MARKER).is_file()


def _make_marked_folder(parent: Path, name: str) -> Path:
    """A new folder created with the umask's mode (mkdtemp would give 0700), holding MARKER."""
    while True:
        path = parent / f"{name}{secrets.token_hex(4)}"
        try:
            os.mkdir(path, 0o777)
        except FileExistsError:
            continue
        (path / MARKER).write_bytes(b"")
        return path


def user_files(folder: Path, owned: set[str]) -> list[str]:
    """Files and folders inside a netcfg folder that its manifest does not list (relative POSIX paths)."""
    out: list[str] = []
    for root, dirs, files in os.walk(folder):
        base = Path(root)
        for name in files + [d for d in dirs if (base / d).is_symlink()]:
            rel = (base / name).relative_to(folder).as_posix()
            if rel not in (MANIFEST, MARKER) and rel not in owned:
                out.append(rel)
        if not files and not dirs and base != folder:
            rel = base.relative_to(folder).as_posix()
            if not any(o.startswith(rel + "/") for o in owned):
                out.append(rel + "/")
    return sorted(out)


def write_tree(out: Path, files: Mapping[str, bytes], spec_sha256: str, inputs: Iterable[Path] = ()) -> list[str]:
    """Replace the folder out with files (and their manifest), atomically. -> the user's own files kept there."""
    from concurrent.futures import ThreadPoolExecutor  # only here: `netcfg import` writes one file, no manifest

    real = check_output_folder(out, inputs)
    parent = real.parent
    parent.mkdir(parents=True, exist_ok=True)
    with locked(parent):
        real = check_output_folder(out, inputs)  # again, under the lock: another build may have just finished
        old = parent / f".{real.name}{OLD_TAG}"
        if _is_ours(old) and not real.exists():  # a build was stopped between its two renames: undo that
            os.rename(old, real)
        for stale in parent.glob(f".{real.name}{TMP_TAG}*"):
            if _is_ours(stale):
                shutil.rmtree(stale)
        if _is_ours(old):
            shutil.rmtree(old)
        owned = read_manifest(real) if real.is_dir() else set()
        kept = user_files(real, owned or set()) if real.is_dir() else []
        clash = [rel for rel in kept if rel in files]
        if clash:
            raise OutputError(
                out, f"{out / clash[0]} was not written by netcfg but this build would write it; move it away"
            )
        tmp = _make_marked_folder(parent, f".{real.name}{TMP_TAG}")
        # the manifest is hashed in a thread while the files are written: both release the GIL (126 drives: 26 MB)
        with ThreadPoolExecutor(max_workers=1) as pool:
            manifest = pool.submit(manifest_bytes, files, spec_sha256)
            try:
                for rel, data in files.items():
                    path = tmp / rel
                    path.parent.mkdir(parents=True, exist_ok=True)
                    path.write_bytes(data)
                (tmp / MANIFEST).write_bytes(manifest.result())
                for rel in kept:
                    _carry_over(real / rel, tmp / rel)
                if real.exists():
                    (real / MARKER).write_bytes(b"")  # so that a build killed after the next rename leaves a backup
                    os.rename(real, old)  # the next build may restore
                os.rename(tmp, real)
                (real / MARKER).unlink()
            except BaseException:
                if not real.exists() and _is_ours(old):
                    os.rename(old, real)
                shutil.rmtree(tmp, ignore_errors=True)
                raise
        if _is_ours(old):
            shutil.rmtree(old)
    return kept


def _carry_over(src: Path, dst: Path) -> None:
    """A user's file into the new tree: a hard link where the file system allows (same data, no copy)."""
    if str(src).endswith("/") or (src.is_dir() and not src.is_symlink()):
        dst.mkdir(parents=True, exist_ok=True)
        return
    dst.parent.mkdir(parents=True, exist_ok=True)
    if src.is_symlink():
        os.symlink(os.readlink(src), dst)
        return
    try:
        os.link(src, dst)
    except OSError as exc:
        if exc.errno not in (errno.EXDEV, errno.EPERM, errno.EMLINK, errno.ENOTSUP):
            raise
        shutil.copy2(src, dst)


def check_import_output(out: Path, inputs: Iterable[Path] = ()) -> None:
    """OutputError when out is one of the inputs or a folder (the checks write_file makes, made early)."""
    real = Path(os.path.realpath(out))
    for source in inputs:
        try:
            same = real == Path(os.path.realpath(source)) or (real.exists() and os.path.samefile(real, source))
        except OSError:
            same = False
        if same:
            raise OutputError(out, f"{out} is the input file; write the result to another file")
    if real.is_dir():
        raise OutputError(out, f"{out} is a folder; give a file name")


def write_file(out: Path, data: bytes, inputs: Iterable[Path] = ()) -> None:
    """Write one output file whole or not at all, never over one of the inputs; its temporary is removed on any
    failure. OutputError when out is an input or a folder."""
    check_import_output(out, inputs)
    real = Path(os.path.realpath(out))
    real.parent.mkdir(parents=True, exist_ok=True)
    tmp = real.parent / f".{real.name}{TMP_TAG}{secrets.token_hex(4)}"
    try:
        tmp.write_bytes(data)
        os.replace(tmp, real)
    finally:
        tmp.unlink(missing_ok=True)
