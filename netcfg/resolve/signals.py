"""A message's signals: their bit layout (start bits from the order the spec lists them, byte order, multiplexing)
and the overlaps of signals that are sent together."""

from __future__ import annotations

from typing import TYPE_CHECKING

from netcfg import model
from netcfg.spec import schema
from netcfg.spec.source import Path

if TYPE_CHECKING:
    from netcfg.rules import Resolution


def layout_signals(r: Resolution, sigs: list[schema.Signal], path: Path) -> tuple[model.Signal, ...]:
    from netcfg.runtime.codec import int_range  # the runtime package only when a spec has signals

    out: list[model.Signal] = []
    start, seen = 0, set()
    names = {s.name for s in sigs}
    switches = {s.mux.signal for s in sigs if s.mux is not None}
    for k, s in enumerate(sigs):
        if s.name in seen:
            r.err("duplicate-name", f"signal '{s.name}' appears twice", (*path, k, "name"))
        seen.add(s.name)
        if s.min is not None and s.max is not None and s.min > s.max:
            r.err("signal-range", f"signal '{s.name}': min {s.min} is above max {s.max}", (*path, k))
        if s.float and s.bits not in (32, 64):
            r.err("signal-float", f"signal '{s.name}': a float has 32 or 64 bits", (*path, k, "bits"))
        big = s.byte_order == "big_endian"
        if big and s.start_bit is None:
            r.err(
                "signal-start",
                f"signal '{s.name}' is big-endian: give its start_bit (its most significant bit, DBC numbering)",
                (*path, k),
            )
            continue
        begin = start if s.start_bit is None else s.start_bit
        if big and s.bits > begin % 8 + 1 + 8 * (63 - begin // 8):  # runs past the largest payload
            r.err("signal-start", f"signal '{s.name}' runs past byte 63", (*path, k, "start_bit"))
            continue
        if s.mux is not None and (s.mux.signal not in names or s.mux.signal == s.name):
            r.err(
                "signal-mux",
                f"signal '{s.name}' is multiplexed by '{s.mux.signal}', which is not another signal of the "
                "message",
                (*path, k, "mux", "signal"),
            )
        lo, hi = int_range(s.bits, s.signed)
        for raw in s.enum or {}:
            if not lo <= raw <= hi:
                r.err(
                    "signal-enum",
                    f"signal '{s.name}': value {raw} of its enum does not fit {s.bits} bits ({lo}..{hi})",
                    (*path, k, "enum"),
                )
        out.append(
            model.Signal(
                s.name,
                begin,
                s.bits,
                s.signed,
                s.float,
                s.scale,
                s.offset,
                s.min,
                s.max,
                s.unit,
                big_endian=big,
                mux=s.mux.signal if s.mux is not None else None,
                mux_values=tuple(s.mux.values) if s.mux is not None else (),
                choices=tuple(sorted((s.enum or {}).items())),
                is_multiplexer=s.name in switches,
            )
        )
        if not big:
            start = begin + s.bits
    check_signal_overlap(r, out, {s.name: k for k, s in enumerate(sigs)}, path)
    return tuple(out)

def check_signal_overlap(r: Resolution, signals: list[model.Signal], index: dict[str, int], path: Path) -> None:
    """Two signals may share bits only when no frame carries both (different values of one multiplexer)."""
    from netcfg.runtime.codec import byte_ops

    by_name = {s.name: s for s in signals}

    def conditions(s: model.Signal) -> dict[str, set[int]]:
        out: dict[str, set[int]] = {}
        while s.mux is not None and s.mux not in out and s.mux in by_name:
            out[s.mux] = set(s.mux_values)
            s = by_name[s.mux]
        return out

    masks = [sum(op.mask << (8 * op.index) for op in byte_ops(s.start_bit, s.bits, s.big_endian)) for s in signals]
    conds = [conditions(s) for s in signals]
    for b, sb in enumerate(signals):
        for a in range(b):
            if not masks[a] & masks[b]:
                continue
            if any(m in conds[b] and not (v & conds[b][m]) for m, v in conds[a].items()):
                continue  # never in the same frame
            sa = signals[a]
            r.err(
                "signal-overlap",
                f"signal '{sb.name}' (start bit {sb.start_bit}, {sb.bits} bits) overlaps signal '{sa.name}' "
                f"(start bit {sa.start_bit}, {sa.bits} bits); move it to free bits",
                (*path, index[sb.name], "start_bit"),
            )
            break


def last_byte(s: model.Signal) -> int:
    """The highest payload byte a signal touches (imported here: the runtime package only for signals)."""
    from netcfg.runtime.codec import last_byte

    return last_byte(s.start_bit, s.bits, s.big_endian)
