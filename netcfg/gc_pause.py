"""The cyclic garbage collector held off around work that builds one large object graph living until it ends (a
batch command, a language-server check): each collection meanwhile would only walk objects that all survive it.
The figures that justify it are beside each use."""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def gc_paused() -> Iterator[None]:
    """The collector off while the block runs, and on again after it if it was on before."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
