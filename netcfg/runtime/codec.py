"""Payload codecs: the one definition of how a signal sits in a frame, shared by the Python runtime and, through
the generated C headers, the microcontrollers.

Layout, as DBC files define it. Bit k of the payload is bit k % 8 of byte k // 8.
- little-endian (Intel, DBC '@1', CANopen PDOs): the signal occupies `bits` consecutive bits from `start_bit`,
  its least significant bit, upwards (a payload of n bytes read as one little-endian integer);
- big-endian (Motorola, DBC '@0'): `start_bit` is the signal's most significant bit; the following bits run
  down inside a byte and continue at bit 7 of the next byte (the DBC "sawtooth" numbering).
Integers are unsigned or two's complement; floats are IEEE 754 binary32/binary64. Physical values are
raw * scale + offset; min/max, when given, bound the physical value.

Multiplexing (DBC 'M' / 'mN', also extended multiplexing): a field with `mux` set is present only when the
field named by `mux` holds one of `mux_values` and is itself present. encode() takes exactly the present
fields; decode() returns exactly them. Value names (DBC VAL_) are accepted by encode() in place of the number.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from functools import lru_cache

Number = int | float


class CodecError(ValueError):
    pass


def int_range(bits: int, signed: bool) -> tuple[int, int]:
    """The smallest and largest integer of `bits` bits: two's complement when signed, else unsigned."""
    if signed:
        return -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    return 0, (1 << bits) - 1


@dataclass(frozen=True)
class ByteOp:
    """The part of a signal that lies in byte `index`: the byte bits in `mask` hold raw bits from `shift` up
    (byte bits = (raw >> shift) & mask for shift >= 0, (raw << -shift) & mask below). C headers emit the same."""

    index: int
    shift: int
    mask: int


@lru_cache(maxsize=4096)  # a pure function of three small integers, asked for every signal and frame
def byte_ops(start_bit: int, bits: int, big_endian: bool = False) -> tuple[ByteOp, ...]:
    """Where each byte's share of the signal goes (see the module docstring for the two numberings)."""
    ops: list[ByteOp] = []
    if not big_endian:
        for k in range(start_bit // 8, (start_bit + bits - 1) // 8 + 1):
            lo = max(start_bit, 8 * k) - 8 * k  # lowest byte bit used
            hi = min(start_bit + bits, 8 * k + 8) - 8 * k  # one past the highest
            ops.append(ByteOp(k, 8 * k - start_bit, ((1 << hi) - 1) & ~((1 << lo) - 1)))
        return tuple(ops)
    remaining, k, top = bits, start_bit // 8, start_bit % 8  # the MSB sits at bit `top` of byte k
    while remaining > 0:
        take = min(top + 1, remaining)  # bits top down to top - take + 1 of this byte
        low = top - take + 1
        remaining -= take
        ops.append(ByteOp(k, remaining - low, ((1 << (top + 1)) - 1) & ~((1 << low) - 1)))
        k, top = k + 1, 7
    return tuple(ops)


def last_byte(start_bit: int, bits: int, big_endian: bool = False) -> int:
    """The highest payload byte the signal touches (the payload needs one more byte than this)."""
    return max(op.index for op in byte_ops(start_bit, bits, big_endian))


@dataclass(frozen=True)
class Field:
    name: str
    start_bit: int
    bits: int
    signed: bool = False
    is_float: bool = False
    scale: float = 1.0
    offset: float = 0.0
    minimum: float | None = None
    maximum: float | None = None
    big_endian: bool = False
    mux: str | None = None  # the multiplexer field this one depends on
    mux_values: tuple[int, ...] = ()  # ... and the raw values of it for which this field is present
    choices: tuple[tuple[int, str], ...] = ()  # value names (DBC VAL_): raw value -> name

    @property
    def ops(self) -> tuple[ByteOp, ...]:
        return byte_ops(self.start_bit, self.bits, self.big_endian)

    @property
    def is_integer(self) -> bool:
        """Values are plain integers (no scaling): decoded as int, encoded exactly."""
        return not self.is_float and self.scale == 1 and self.offset == 0

    def raw_range(self) -> tuple[int, int]:
        return int_range(self.bits, self.signed)

    def to_raw(self, value: Number | str) -> int:
        if isinstance(value, str):
            named = [raw for raw, name in self.choices if name == value]
            if not named:
                raise CodecError(f"{self.name} = {value!r} is not one of its value names")
            value = self.from_raw(named[0] & ((1 << self.bits) - 1))
        if isinstance(value, float) and not math.isfinite(value) and not self.is_float:
            raise CodecError(f"{self.name} = {value} is not a finite number")
        if (self.minimum is not None and value < self.minimum) or (self.maximum is not None and value > self.maximum):
            raise CodecError(f"{self.name} = {value} is outside [{self.minimum}, {self.maximum}]")
        if self.is_float:
            fmt, ifmt = ("<f", "<I") if self.bits == 32 else ("<d", "<Q")
            return int(struct.unpack(ifmt, struct.pack(fmt, float(value)))[0])
        if self.is_integer:
            if isinstance(value, float) and not value.is_integer():
                raise CodecError(f"{self.name} = {value} is not a whole number")
            raw = int(value)
        else:
            raw = round((value - self.offset) / self.scale)
        lo, hi = self.raw_range()
        if not lo <= raw <= hi:
            raise CodecError(f"{self.name} = {value} does not fit {self.bits} bits ({lo}..{hi} raw)")
        return raw & ((1 << self.bits) - 1)

    def from_raw(self, raw: int) -> Number:
        if self.is_float:
            fmt, ifmt = ("<f", "<I") if self.bits == 32 else ("<d", "<Q")
            return float(struct.unpack(fmt, struct.pack(ifmt, raw))[0])
        if self.signed and raw >> (self.bits - 1):
            raw -= 1 << self.bits
        if self.is_integer:
            return raw
        return raw * self.scale + self.offset


def raw_interval(f: Field) -> tuple[int, int] | None:
    """The raw integers (signed as the field is) whose physical values lie inside [minimum, maximum] and which fit
    the field's bits; None when there are none (a range the layout cannot reach) or the field is a float."""
    if f.is_float:
        return None
    lo, hi = f.raw_range()
    if f.scale == 0:
        inside = (f.minimum is None or f.offset >= f.minimum) and (f.maximum is None or f.offset <= f.maximum)
        return (lo, hi) if inside else None
    bounds = [(f.minimum, math.ceil), (f.maximum, math.floor)] if f.scale > 0 else [(f.maximum, math.ceil),
                                                                                    (f.minimum, math.floor)]
    (low, up), (high, down) = bounds
    if low is not None:
        lo = max(lo, up((low - f.offset) / f.scale))
    if high is not None:
        hi = min(hi, down((high - f.offset) / f.scale))
    while lo <= hi and not _inside(f, f.from_raw(lo & ((1 << f.bits) - 1))):  # the float rounding at the edges
        lo += 1
    while lo <= hi and not _inside(f, f.from_raw(hi & ((1 << f.bits) - 1))):
        hi -= 1
    return (lo, hi) if lo <= hi else None


def _inside(f: Field, value: Number) -> bool:
    return (f.minimum is None or value >= f.minimum) and (f.maximum is None or value <= f.maximum)


def resting_raw(f: Field) -> int:
    """The bit pattern of the field's resting value: the value nearest 0 inside its [minimum, maximum] that its
    layout can carry (0 itself when the range holds it). What a simulated frame carries when nothing sets the
    field, so that a trace decodes inside every signal's range. A range no raw value reaches: raw 0."""
    mask = (1 << f.bits) - 1
    if f.is_float:
        value = min(max(0.0, f.minimum if f.minimum is not None else 0.0), f.maximum if f.maximum is not None else 0.0)
        raw = f.to_raw(value) if _inside(f, value) else 0
        # binary32 may round a bound outwards: the neighbouring bit patterns are the neighbouring floats
        return next((r for r in (raw, raw + 1, raw - 1) if _inside(f, f.from_raw(r & mask))), raw) & mask
    interval = raw_interval(f)
    if interval is None:
        return 0
    lo, hi = interval
    zero = 0 if f.scale == 0 else round(-f.offset / f.scale)  # the raw value of physical 0
    return min(max(zero, lo), hi) & mask


def resting_payload(fields: Iterable[Field], size: int) -> bytes:
    """`size` bytes with every field the frame then carries at its resting value (resting_raw); a multiplexer
    rests too, so the fields it selects at its resting value are the ones present."""
    fields = list(fields)
    raws = {f.name: resting_raw(f) for f in fields}
    options = selectors(fields)
    for f in fields:  # a multiplexer rests at the selector nearest 0, so that it selects something
        if f.name in options:
            raws[f.name] = min(options[f.name], key=lambda raw: (abs(f.from_raw(raw)), raw))
    word = 0
    for f in present(fields, {f.name: f.from_raw(raws[f.name]) for f in fields}):
        word |= _place(f, raws[f.name])
    return (word & ((1 << (8 * size)) - 1)).to_bytes(size, "little")


def selectors(fields: Iterable[Field]) -> dict[str, list[int]]:
    """Per multiplexer, the bit patterns that select one of its fields and lie inside its own range, in order."""
    fields = list(fields)
    by_name = {f.name: f for f in fields}
    out: dict[str, set[int]] = {}
    for f in fields:
        switch = by_name.get(f.mux) if f.mux is not None else None
        if switch is None:
            continue
        mask = (1 << switch.bits) - 1
        inside = {v & mask for v in f.mux_values if _inside(switch, switch.from_raw(v & mask))}
        out.setdefault(switch.name, set()).update(inside)
    return {name: sorted(values) for name, values in out.items() if values}


def present(fields: Iterable[Field], values: Mapping[str, Number | str] | None = None) -> list[Field]:
    """The fields a frame carries: every plain field, and a multiplexed one when its multiplexer is present
    and holds one of its values. `values` maps multiplexer names to their (physical or named) values."""
    fields = list(fields)
    by_name = {f.name: f for f in fields}
    raws: dict[str, int | None] = {}

    def raw_of(f: Field) -> int | None:
        if f.name not in raws:
            raws[f.name] = None  # a cycle of multiplexers is never present
            if values is not None and f.name in values and is_present(f):
                try:
                    raws[f.name] = f.to_raw(values[f.name])
                except CodecError:
                    raws[f.name] = None
        return raws[f.name]

    def is_present(f: Field) -> bool:
        if f.mux is None:
            return True
        switch = by_name.get(f.mux)
        if switch is None:
            return False
        raw = raw_of(switch)
        # compared as bit patterns: a signed multiplexer's value may be listed as -1 or as 255 (C does the same)
        mask = (1 << switch.bits) - 1
        return raw is not None and (raw & mask) in {v & mask for v in f.mux_values}

    return [f for f in fields if is_present(f)]


def _place(f: Field, raw: int) -> int:
    """The raw value's bits at their place in the payload word (payload byte k = bits 8k..8k+7)."""
    if not f.big_endian:
        return raw << f.start_bit
    word = 0
    for op in f.ops:
        part = (raw >> op.shift) if op.shift >= 0 else (raw << -op.shift)
        word |= (part & op.mask) << (8 * op.index)
    return word


def _take(f: Field, word: int) -> int:
    if not f.big_endian:
        return (word >> f.start_bit) & ((1 << f.bits) - 1)
    raw = 0
    for op in f.ops:
        part = (word >> (8 * op.index)) & op.mask
        raw |= (part << op.shift) if op.shift >= 0 else (part >> -op.shift)
    return raw


def encode(fields: Iterable[Field], size: int, values: Mapping[str, Number | str]) -> bytes:
    """Pack named physical values into `size` bytes; every present field must be given, and nothing else."""
    fields = present(fields, values)
    names = {f.name for f in fields}
    unknown = set(values) - names
    missing = names - set(values)
    if unknown or missing:
        raise CodecError(f"unknown fields {sorted(unknown)}, missing fields {sorted(missing)}")
    word = 0
    for f in fields:
        word |= _place(f, f.to_raw(values[f.name]))
    return word.to_bytes(size, "little")


def decode(fields: Iterable[Field], payload: bytes) -> dict[str, Number]:
    """The present fields' physical values (multiplexed fields: those the payload's multiplexers select)."""
    word = int.from_bytes(payload, "little")
    fields = list(fields)
    if not any(f.mux for f in fields):
        return {f.name: f.from_raw(_take(f, word)) for f in fields}
    raw_values = {f.name: f.from_raw(_take(f, word)) for f in fields}
    return {f.name: raw_values[f.name] for f in present(fields, raw_values)}


def decoder(fields: Iterable[Field]) -> Callable[[bytes], dict[str, Number]]:
    """decode() for these fields, with each field's layout worked out once: a master decodes the same messages
    thousands of times a second. Plain little-endian integer fields (every CANopen PDO's) take a shift, a mask and
    the sign; the others go through Field.from_raw, and multiplexed sets through decode() itself."""
    fields = tuple(fields)
    if any(f.mux for f in fields):
        return lambda payload: decode(fields, payload)
    # per field: name, the field for the general path (or None), start bit, mask, 2^bits if signed, its sign bit,
    # and scale and offset (None when the value is the raw integer)
    plan = [
        (
            f.name,
            f if f.is_float or f.big_endian else None,
            f.start_bit,
            (1 << f.bits) - 1,
            (1 << f.bits) if f.signed else 0,
            f.bits - 1,
            None if f.is_integer else (f.scale, f.offset),
        )
        for f in fields
    ]

    def run(payload: bytes) -> dict[str, Number]:
        word = int.from_bytes(payload, "little")
        out: dict[str, Number] = {}
        for name, general, start, mask, wrap, top, linear in plan:
            if general is not None:
                out[name] = general.from_raw(_take(general, word))
                continue
            raw = (word >> start) & mask
            if wrap and raw >> top:
                raw -= wrap
            out[name] = raw if linear is None else raw * linear[0] + linear[1]
        return out

    unpack = _struct_layout(fields)
    if unpack is None:
        return run
    names = tuple(f.name for f in fields)
    # a dict display takes half the time of dict(zip(...)): one or two fields are the commonest PDO mappings
    if len(names) == 1:
        (name,) = names

        def unpacked1(payload: bytes) -> dict[str, Number]:
            try:
                (value,) = unpack(payload)
            except struct.error:  # shorter than the fields: the missing bits read as zeros, as in run()
                return run(payload)
            return {name: value}

        return unpacked1
    if len(names) == 2:
        first, second = names

        def unpacked2(payload: bytes) -> dict[str, Number]:
            try:
                a, b = unpack(payload)
            except struct.error:
                return run(payload)
            return {first: a, second: b}

        return unpacked2

    def unpacked(payload: bytes) -> dict[str, Number]:
        try:
            return dict(zip(names, unpack(payload)))
        except struct.error:
            return run(payload)

    return unpacked


# struct's codes for integers of (bits, signed) and for floats of bits
_STRUCT_CODES = {(8, False): "B", (8, True): "b", (16, False): "H", (16, True): "h", (32, False): "I", (32, True): "i",
                 (64, False): "Q", (64, True): "q"}
_FLOAT_CODES = {32: "f", 64: "d"}


def _struct_layout(fields: tuple[Field, ...]) -> Callable[[bytes], tuple[Number, ...]] | None:
    """Fields that are whole little-endian bytes of C's integer or IEEE float widths, unscaled, listed in payload
    order without overlapping (every CANopen PDO mapping netcfg writes): one struct.unpack_from gives their values,
    the same as Field.from_raw's. None for any other layout."""
    fmt, at = "<", 0
    for f in fields:
        if f.big_endian or f.start_bit % 8 or f.start_bit < 8 * at or not (f.is_float or f.is_integer):
            return None
        code = _FLOAT_CODES.get(f.bits) if f.is_float else _STRUCT_CODES.get((f.bits, f.signed))
        if code is None:
            return None
        fmt += "x" * (f.start_bit // 8 - at) + code
        at = (f.start_bit + f.bits) // 8
    return struct.Struct(fmt).unpack_from

