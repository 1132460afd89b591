"""A DBC message's signals as the spec's: which of them netcfg can lay out in the frame (layout_drops), the
spec entry of each (signal_entry) and the note on where it came from (signal_note).
"""

from __future__ import annotations

import math
from typing import Any

from cantools.database.can import Message, Signal

from netcfg.importers.dbc_text import MAX_FRAME_BYTES, DbcFile, DbcLines
from netcfg.runtime.codec import byte_ops, int_range, last_byte


def _number(value: float) -> float | int:
    """Integral floats as ints: the spec reads the same, and the YAML says '1' rather than '1.0'."""
    return int(value) if isinstance(value, float) and abs(value) < 2**53 and value.is_integer() else value


def layout_drops(msg: Message, signals: list[Signal]) -> dict[str, str]:
    """The signals netcfg cannot lay out, with the reason: reaching outside the frame, a float of other than
    32 or 64 bits, a multiplexer that is not a signal, or overlapping a signal that can be in the same
    frame. Of overlapping signals the narrower ones are kept (a wide one is often a group of the others)."""
    names = {s.name: s for s in signals}
    drops: dict[str, str] = {}
    masks: dict[str, int] = {}
    for s in signals:
        big = s.byte_order != "little_endian"
        if s.conversion.scale == 0:
            drops[s.name] = "has a scale of 0 (every raw value would mean the offset)"
        elif s.is_float and s.length not in (32, 64):
            drops[s.name] = f"is a float of {s.length} bits (IEEE 754 floats have 32 or 64)"
        elif s.multiplexer_signal is not None and s.multiplexer_signal not in names:
            drops[s.name] = f"is multiplexed by '{s.multiplexer_signal}', which is not a signal of the message"
        elif big and s.length > s.start % 8 + 1 + 8 * (MAX_FRAME_BYTES - 1 - s.start // 8):
            drops[s.name] = "runs past the end of the largest frame"
        elif last_byte(s.start, s.length, big) >= msg.length:
            drops[s.name] = f"reaches outside the frame of {msg.length} bytes"
        else:
            masks[s.name] = sum(op.mask << (8 * op.index) for op in byte_ops(s.start, s.length, big))

    def conditions(s: Signal) -> dict[str, set[int]]:
        out: dict[str, set[int]] = {}
        while s.multiplexer_signal is not None and s.multiplexer_signal in names:
            if s.multiplexer_signal in out:
                break
            out[s.multiplexer_signal] = set(s.multiplexer_ids or ())
            s = names[s.multiplexer_signal]
        return out

    kept: list[Signal] = []
    for s in sorted((s for s in signals if s.name in masks), key=lambda s: (s.length, s.start, s.name)):
        cond = conditions(s)
        clash = next(
            (
                k
                for k in kept
                if masks[k.name] & masks[s.name]
                and not any(m in cond and not (v & cond[m]) for m, v in conditions(k).items())
            ),
            None,
        )
        if clash is None:
            kept.append(s)
        else:
            drops[s.name] = f"overlaps signal '{clash.name}'"
    # a signal multiplexed by a left-out multiplexer cannot be placed either
    changed = True
    while changed:
        changed = False
        for s in signals:
            if s.name not in drops and s.multiplexer_signal in drops:
                drops[s.name] = f"is multiplexed by '{s.multiplexer_signal}', which is left out"
                changed = True
    return drops


def signal_note(lines: DbcLines, s: Signal, dbc_id: int) -> str:
    """Where the signal is, and what the spec has no place for: its DBC comment and value names (VAL_)."""
    at = lines.signals.get((dbc_id, s.name))
    note = f"SG_ {s.name}" + (f", line {at[0]}" if at else "")
    if s.comment and s.comment.strip():
        note += ": " + " ".join(s.comment.split())
    return note


def signal_entry(
    dbc: DbcFile, name: str, s: Signal, safe: dict[str, str], message: str = "", at: tuple[int, int] | None = None
) -> dict[str, Any]:
    """The spec's entry of one signal, under its safe name (safe: every signal's, for its multiplexer's)."""
    out: dict[str, Any] = {"name": name, "bits": s.length}
    if s.byte_order != "little_endian":
        out["byte_order"] = "big_endian"
    if s.is_float:
        out["float"] = True
    elif s.is_signed:
        out["signed"] = True
    scale, offset = s.conversion.scale, s.conversion.offset
    if scale != 1:
        out["scale"] = _number(float(scale))
    if offset != 0:
        out["offset"] = _number(float(offset))
    low, high = s.minimum, s.maximum
    if low is not None and high is not None and low > high:
        dbc.add(
            "dbc-signal-range",
            f"signal '{s.name}' of message '{message}': its range [{low}|{high}] has min above max (cantools "
            "only tolerates this); imported without a range",
            at,
            "warning",
        )
        low = high = None
    for key, bound in (("min", low), ("max", high)):
        if bound is not None and math.isfinite(float(bound)):
            out[key] = _number(float(bound))
    if s.unit:
        out["unit"] = s.unit
    if s.multiplexer_signal is not None:
        out["mux"] = {"signal": safe[s.multiplexer_signal], "values": sorted(set(s.multiplexer_ids or ()))}
    if s.choices:
        lo, hi = int_range(s.length, s.is_signed)
        fits = {int(raw): str(text) for raw, text in s.choices.items() if lo <= int(raw) <= hi}
        if len(fits) < len(s.choices):
            dbc.add(
                "dbc-signal-enum",
                f"signal '{s.name}' of message '{message}': {len(s.choices) - len(fits)} of its value names "
                f"(VAL_) are for values that {s.length} bits cannot hold ({lo}..{hi}); left out",
                at,
                "warning",
            )
        if fits:
            out["enum"] = dict(sorted(fits.items()))
    return out
