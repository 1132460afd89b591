"""The payload codec (netcfg.runtime.codec) over many frames at once: payloads as rows of a uint8 array.

The same layouts (byte_ops), signs, floats, scaling and multiplexing as codec.encode / codec.decode, one array
operation per field and byte: what verify's checker decodes a log with and what the simulator writes random
in-range payloads with.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import NDArray

from netcfg.runtime.codec import Field, raw_interval, selectors

__all__ = ["fill_in_range", "fits", "physical", "place", "present_rows", "take"]


def fits(f: Field, columns: int) -> bool:
    """Whether the field lies inside the first `columns` payload bytes."""
    return all(op.index < columns for op in f.ops)


def take(f: Field, data: NDArray[np.uint8]) -> NDArray[np.uint64]:
    """Each row's raw bits of the field (data: (n, bytes), the field inside them)."""
    raw = np.zeros(len(data), np.uint64)
    for op in f.ops:
        part = data[:, op.index].astype(np.uint64) & np.uint64(op.mask)
        raw |= (part << np.uint64(op.shift)) if op.shift >= 0 else (part >> np.uint64(-op.shift))
    return raw


def place(f: Field, data: NDArray[np.uint8], raw: NDArray[np.uint64], rows: NDArray[np.bool_]) -> None:
    """Write the raw bits of the field into the selected rows of data, in place."""
    for op in f.ops:
        part = (raw >> np.uint64(op.shift)) if op.shift >= 0 else (raw << np.uint64(-op.shift))
        byte = part.astype(np.uint8) & np.uint8(op.mask)  # astype keeps the low 8 bits
        column = data[:, op.index]
        data[:, op.index] = np.where(rows, (column & np.uint8(~op.mask & 0xFF)) | byte, column)


def physical(f: Field, raw: NDArray[np.uint64]) -> NDArray[np.float64]:
    """The physical values of raw bit patterns (codec.Field.from_raw, row by row)."""
    if f.is_float:
        if f.bits == 32:
            return raw.astype(np.uint32).view(np.float32).astype(np.float64)
        return raw.view(np.float64).copy()
    if f.signed:
        sign = np.uint64(1 << (f.bits - 1))
        value = ((raw ^ sign).astype(np.int64) - np.int64(1 << (f.bits - 1))).astype(np.float64)
    else:
        value = raw.astype(np.float64)
    return value * f.scale + f.offset


def present_rows(fields: Iterable[Field], data: NDArray[np.uint8]) -> dict[str, NDArray[np.bool_]]:
    """For each field, the rows that carry it (codec.present): every row for a plain field; for a multiplexed
    one, the rows whose multiplexer is present and holds one of its values (compared as bit patterns)."""
    by_name = {f.name: f for f in fields}
    return {f.name: _rows_of(f, by_name, data, frozenset()) for f in by_name.values()}


def _rows_of(f: Field, by_name: dict[str, Field], data: NDArray[np.uint8], seen: frozenset[str]) -> NDArray[np.bool_]:
    if f.mux is None:
        return np.ones(len(data), bool)
    switch = by_name.get(f.mux)
    if switch is None or switch.name in seen or not fits(switch, data.shape[1]):  # never present (a cycle, ...)
        return np.zeros(len(data), bool)
    mask = (1 << switch.bits) - 1
    wanted = np.array(sorted({v & mask for v in f.mux_values}), np.uint64)
    return _rows_of(switch, by_name, data, seen | {f.name}) & np.isin(take(switch, data), wanted)


def fill_in_range(fields: Iterable[Field], data: NDArray[np.uint8], rng: np.random.Generator) -> None:
    """Random payloads (data, in place) made to decode inside every present field's [minimum, maximum]: each
    such field's raw value drawn uniformly from those in range (codec.raw_interval; a float uniformly between
    its limits). Multiplexers are drawn first, among the values that select a field; bits of no limited
    field stay as they are."""
    by_name = {f.name: f for f in fields}
    options = selectors(by_name.values())
    todo = [f for f in by_name.values() if fits(f, data.shape[1])]
    done: set[str] = set()
    while todo:  # multiplexers first: a field is drawn once the one that selects it is
        ready = [f for f in todo if f.mux is None or f.mux in done or f.mux not in by_name]
        if not ready:
            break  # a cycle of multiplexers: nothing of it is ever present
        for f in ready:
            rows = _rows_of(f, by_name, data, frozenset())
            if f.name in options:  # a multiplexer selects one of its fields (codec.selectors)
                choice = np.array(options[f.name], np.uint64)[rng.integers(0, len(options[f.name]), len(data))]
                place(f, data, choice, rows)
            else:
                _draw(f, data, rng, rows)
            done.add(f.name)
        todo = [f for f in todo if f.name not in done]


def _draw(f: Field, data: NDArray[np.uint8], rng: np.random.Generator, rows: NDArray[np.bool_]) -> None:
    if f.minimum is None and f.maximum is None:
        return
    n = len(data)
    raw: NDArray[np.uint64]
    if f.is_float:
        width = np.float32 if f.bits == 32 else np.float64
        low = f.minimum if f.minimum is not None else -1.0
        high = f.maximum if f.maximum is not None else 1.0
        values = np.clip(rng.uniform(low, high, n).astype(width), *(np.array([low, high]).astype(width)))
        bits = values.view(np.uint32 if f.bits == 32 else np.uint64).astype(np.uint64)
        inside = (physical(f, bits) >= low) & (physical(f, bits) <= high)  # binary32 may round a limit outwards
        raw = np.where(inside, bits, np.uint64(0))
    else:
        interval = raw_interval(f)
        if interval is None:
            return
        lo, hi = interval
        drawn = rng.integers(lo, hi, n, endpoint=True, dtype=np.uint64 if lo >= 0 else np.int64)
        raw = drawn.astype(np.uint64) & np.uint64((1 << f.bits) - 1)
    place(f, data, raw, rows)
