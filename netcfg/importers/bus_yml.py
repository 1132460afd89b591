"""Placeholder: being written. Reads a ros2_canopen / Lely dcfgen bus.yml."""

from __future__ import annotations

from pathlib import Path

from netcfg.diagnostics import Collector
from netcfg.importers import Imported, ImportOptions


def import_bus_yml(path: Path, options: ImportOptions, diags: Collector) -> Imported | None:
    raise NotImplementedError
