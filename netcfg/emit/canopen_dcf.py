"""Placeholder: being written."""

from __future__ import annotations

from typing import Any

from netcfg.model import Model


def emit(model: Model, report: dict[str, Any]) -> dict[str, bytes]:
    return {}
