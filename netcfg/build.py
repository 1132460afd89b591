"""`netcfg build`: check, then emit every artifact into the output folder, atomically.

Files are written into a temporary folder next to the output and swapped in only when everything succeeded,
so an interrupted or failed build leaves the previous output as it was.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from netcfg.check import analyse_spec
from netcfg.emit import Files, emit_all


def build(spec: Path, out: Path | None) -> tuple[dict[str, Any], Path | None, Files]:
    """-> (check report, output folder or None when the spec was refused, files written)."""
    model, report = analyse_spec(spec)
    if model is None or not report["ok"]:
        return report, None, {}
    files = emit_all(model, report)
    target = out if out is not None else Path("generated") / model.system
    write_tree(target, files)
    return report, target, files


def write_tree(out: Path, files: Files) -> None:
    parent = out.parent
    parent.mkdir(parents=True, exist_ok=True)
    old = parent / f".{out.name}.old"
    if old.exists() and not out.exists():  # a build was stopped between the two renames: undo it
        os.rename(old, out)
    for stale in parent.glob(f".{out.name}.*.tmp"):
        shutil.rmtree(stale, ignore_errors=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=parent))
    try:
        for rel, data in files.items():
            path = tmp / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        if old.exists():
            shutil.rmtree(old)
        if out.exists():
            os.rename(out, old)
        os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    shutil.rmtree(old, ignore_errors=True)
