"""'Did you mean' for every name the spec looks up: keys, nodes, buses, messages, tasks, flow steps, enum values.

One helper so every lookup answers a misspelling the same way. difflib's ratio is enough for names people type;
a match that differs only in case is preferred, since names are case-sensitive but people's memory is not.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from netcfg.spec.schema import Spec


def closest(name: str, known: Iterable[str]) -> str | None:
    """The known name `name` was most likely meant to be, or None when nothing is close."""
    candidates = sorted(set(known))
    if not isinstance(name, str) or not candidates:
        return None
    folded = [c for c in candidates if c.lower() == name.lower() and c != name]
    if folded:
        return folded[0]
    matches = difflib.get_close_matches(name, candidates, n=1, cutoff=0.6)
    return matches[0] if matches and matches[0] != name else None


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """" (did you mean 'x'?)" to put right after the unknown name's sentence, or "" when no known name is close."""
    return suggestion(closest(name, known))


def suggestion(match: str | None) -> str:
    """did_you_mean's words for a match found already (closest), or "" for None."""
    return f" (did you mean '{match}'?)" if match is not None else ""


def nodes_on_bus(spec: Spec, bus: str) -> list[str]:
    """The nodes of the spec that sit on `bus` (the names a per-bus role may refer to)."""
    return [n.name for n in spec.nodes if bus in n.buses]


def some_names(names: Iterable[str], limit: int = 8) -> str:
    items = sorted(names)
    more = f" (+{len(items) - limit} more)" if len(items) > limit else ""
    return (", ".join(items[:limit]) or "none") + more
