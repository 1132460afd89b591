"""Placeholder: being written. Reads a DBC file (cantools)."""

from __future__ import annotations

from pathlib import Path

from netcfg.diagnostics import Collector
from netcfg.importers import Imported, ImportOptions


def import_dbc(path: Path, options: ImportOptions, diags: Collector) -> Imported | None:
    raise NotImplementedError
