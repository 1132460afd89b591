"""Payload codecs: the one definition of how a signal sits in a frame, shared by the Python runtime and, through
the generated C headers, the microcontrollers.

Layout: little-endian (Intel) bit numbering, as CANopen PDOs and DBC '@1' signals use. A payload of n bytes is
read as one little-endian integer; a signal occupies `bits` bits starting at `start_bit`, its least significant
bit. Integers are unsigned or two's complement; floats are IEEE 754 binary32/binary64. Physical values are
raw * scale + offset; min/max, when given, bound the physical value.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

Number = int | float


class CodecError(ValueError):
    pass


def int_range(bits: int, signed: bool) -> tuple[int, int]:
    """The smallest and largest integer of `bits` bits: two's complement when signed, else unsigned."""
    if signed:
        return -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    return 0, (1 << bits) - 1


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

    @property
    def is_integer(self) -> bool:
        """Values are plain integers (no scaling): decoded as int, encoded exactly."""
        return not self.is_float and self.scale == 1 and self.offset == 0

    def raw_range(self) -> tuple[int, int]:
        return int_range(self.bits, self.signed)

    def to_raw(self, value: Number) -> int:
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


def encode(fields: Iterable[Field], size: int, values: Mapping[str, Number]) -> bytes:
    """Pack named physical values into `size` bytes; every field must be given, and nothing else."""
    fields = list(fields)
    names = {f.name for f in fields}
    unknown = set(values) - names
    missing = names - set(values)
    if unknown or missing:
        raise CodecError(f"unknown fields {sorted(unknown)}, missing fields {sorted(missing)}")
    word = 0
    for f in fields:
        word |= f.to_raw(values[f.name]) << f.start_bit
    return word.to_bytes(size, "little")


def decode(fields: Iterable[Field], payload: bytes) -> dict[str, Number]:
    word = int.from_bytes(payload, "little")
    return {f.name: f.from_raw((word >> f.start_bit) & ((1 << f.bits) - 1)) for f in fields}
