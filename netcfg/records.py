"""One record's attributes under the same names, for another record or a document that names them alike (the
model's from the spec's, the SRT tables' from the analysis', runtime.json's keys from the model's)."""

from __future__ import annotations

from typing import Any


def same_named(obj: object, names: str) -> dict[str, Any]:
    """{name: obj.name} for each of `names` (space-separated), in their order."""
    return {name: getattr(obj, name) for name in names.split()}
