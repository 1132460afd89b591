"""report.json: the analysis of the build as `netcfg check --format json` prints it, for tools (and `netcfg diff`
of two build folders). File names only, no machine paths: generated/ stays the same wherever it is built."""

from __future__ import annotations

from pathlib import PurePath
from typing import Any

from netcfg import jsontext
from netcfg.model import Model


def emit(model: Model, report: dict[str, Any]) -> dict[str, bytes]:
    doc = dict(report)
    doc["file"] = PurePath(model.file).name
    for key in ("errors", "warnings"):
        doc[key] = [{**d, "file": PurePath(d["file"]).name} for d in report.get(key, [])]
    return {"report.json": (jsontext.dumps(doc, indent=1, sort_keys=True, allow_nan=False) + "\n").encode("utf-8")}
