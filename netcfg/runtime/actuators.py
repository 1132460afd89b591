"""Actuator codecs: an actuator's own CAN protocol, as its device profile describes it, in SI units.

    codec = ActuatorCodec(profile.plain, node_id=3)           # plain: netcfg.devices.actuator_profile's output
    frame = codec.encode("mit_command", position=0.5, velocity=0.0, kp=20.0, kd=1.0, torque=0.0)
    frame.arbitration_id, frame.is_extended, frame.fd, frame.data
    reply = codec.decode(arbitration_id, is_extended, data)   # Decoded(message, values, errors, states) or None

The runtime reads the profile's plain-data form (JSON types only), so a master needs neither YAML nor the compiler;
the compiler's loader checks a profile file and writes that form. Its shape:

    {"name", "link": "can" | "can-fd", "parameters": {name: {"default", "min", "max", "unit"}},
     "messages": [{"name", "from": "host" | "device", "size", "fd", "pad", "remote", "data" (hex of a fixed frame),
                   "id": {"extended": true | false | "auto", "parts": [{"shift", "bits", one of "const" | "param" |
                          "field"}]},
                   "fields": [{"name", "location": "payload" | "id", "start_bit", "bits", "byte_order": "little" |
                               "big", "type": "unsigned" | "signed" | "float", "encoding": "linear" | "span" |
                               "const", "scale", "offset", "range": [bound, bound] | null, "value", "unit",
                               "role": "value" | "error" | "state", "flags": [[bit, name]], "choices": [[raw, name]],
                               "error_values": [raw]}],
                   "reply", "cyclic", "reply_delay_us", "delay_basis"}]}

A bound or a constant's value is a number or {"param": name, "negate": bool}. A field's placement in the payload is
codec.Field's (DBC bit numbering); the identifier is the OR of its parts, each `bits` wide at `shift` (the loader
checks they do not overlap, so "0x140 + node_id" and "0x140 | node_id" are the same).

Encodings. linear: DBC's raw * scale + offset (codec.Field, which rounds to the nearest raw). span: the MIT
"cheetah" packing over [lo, hi]: raw = trunc((x - lo) * (2^bits - 1) / (hi - lo)), x = raw * (hi - lo) / (2^bits - 1)
+ lo, in binary64 as the vendors' Python drivers compute it (their C firmware computes in binary32 and may differ by
one count where a value sits exactly on a count's edge). const: a fixed value the encoder writes and the decoder
requires (a command code, a subframe header, the node id a reply repeats).

Units. A field's `unit` is the wire's; encode() takes and decode() gives SI (rad, rad/s, Nm, A, V, s; temperatures
stay in °C, as every vendor reports them), converting with SI_UNITS. units="wire" skips the conversion.
Out-of-range values raise CodecError; encode(..., clamp=True) saturates span fields as the vendors' drivers do.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from netcfg.runtime.codec import CodecError, Field
from netcfg.runtime.codec import decode as decode_fields
from netcfg.runtime.codec import encode as encode_fields

Number = int | float

# wire unit -> (SI unit, factor): si = wire * factor. Written as the factors a user would write them, so that a
# caller converting the same way gets the same binary64 value.
SI_UNITS: dict[str, tuple[str, float]] = {
    "1": ("1", 1.0),
    "rad": ("rad", 1.0),
    "rad/s": ("rad/s", 1.0),
    "rad/s^2": ("rad/s^2", 1.0),
    "rev": ("rad", 2 * math.pi),
    "rev/s": ("rad/s", 2 * math.pi),
    "rev/s^2": ("rad/s^2", 2 * math.pi),
    "deg": ("rad", math.pi / 180),
    "deg/s": ("rad/s", math.pi / 180),
    "Nm": ("Nm", 1.0),
    "Nm/rad": ("Nm/rad", 1.0),
    "Nm*s/rad": ("Nm*s/rad", 1.0),
    "Nm/(rev/s)": ("Nm*s/rad", 1 / (2 * math.pi)),
    "Nm/rev": ("Nm/rad", 1 / (2 * math.pi)),
    "Nm/(rev/s^2)": ("Nm*s^2/rad", 1 / (2 * math.pi)),
    "1/s": ("1/s", 1.0),
    "A": ("A", 1.0),
    "V": ("V", 1.0),
    "W": ("W", 1.0),
    "degC": ("degC", 1.0),
    "s": ("s", 1.0),
    "ms": ("s", 0.001),
}


@dataclass(frozen=True)
class ActuatorFrame:
    """One CAN frame: what a bus interface sends (as python-can's Message through netcfg.links.pycan_frames); `fd`:
    a CAN FD frame, `brs`: its bit-rate switch."""

    arbitration_id: int
    is_extended: bool
    fd: bool
    data: bytes
    is_remote: bool = False
    brs: bool = False
    dlc: int | None = None  # a remote frame's DLC: the length of the data frame it asks for (the profile's size)


@dataclass(frozen=True)
class Decoded:
    """A frame a device sent, read: its message, its values (SI unless asked otherwise), the names of the errors its
    error fields report (empty: none), and its state fields' value names."""

    message: str
    values: dict[str, Number]
    errors: tuple[str, ...] = ()
    states: dict[str, str] = field(default_factory=dict)


def span_to_raw(x: float, lo: float, hi: float, bits: int) -> int:
    """MIT packing (float_to_uint): truncation of x's place in [lo, hi] to 2^bits - 1 counts."""
    return int((x - lo) * ((1 << bits) - 1) / (hi - lo))


def raw_to_span(raw: int, lo: float, hi: float, bits: int) -> float:
    """MIT unpacking (uint_to_float)."""
    return float(raw) * (hi - lo) / ((1 << bits) - 1) + lo


def _resolve(value: Any, params: Mapping[str, Number | None], what: str) -> Number:
    if isinstance(value, Mapping):
        name = value["param"]
        got = params.get(name)
        if got is None:
            raise CodecError(f"{what} needs the parameter '{name}', which has no value")
        return -got if value.get("negate") else got
    return value  # type: ignore[no-any-return]


class _FieldCodec:
    """One field: where it sits (a codec.Field of its raw bits), how a value becomes raw and back, and what its
    raw value means as an error or a state."""

    def __init__(self, plain: Mapping[str, Any], params: Mapping[str, Number | None]) -> None:
        self.name: str = plain["name"]
        self.location: str = plain.get("location", "payload")
        self.bits: int = plain["bits"]
        self.encoding: str = plain.get("encoding", "linear")
        self.role: str = plain.get("role", "value")
        self.flags = tuple((int(b), str(n)) for b, n in plain.get("flags") or ())
        self.choices = {int(r): str(n) for r, n in plain.get("choices") or ()}
        self.error_values = frozenset(int(v) for v in plain.get("error_values") or ())
        self.shift: int = plain.get("shift", 0)  # in the identifier (location "id")
        unit = plain.get("unit") or "1"
        self.si_unit, self.factor = SI_UNITS[unit]
        kind = plain.get("type", "unsigned")
        big_endian = plain.get("byte_order") == "big"
        self.layout = Field(self.name, plain.get("start_bit", 0), self.bits, big_endian=big_endian)
        lo = hi = None
        if plain.get("range") is not None:
            lo, hi = (float(_resolve(b, params, f"the range of {self.name}")) for b in plain["range"])
        self.lo, self.hi = lo, hi
        self.value = Field(
            self.name, 0, self.bits, signed=kind == "signed", is_float=kind == "float",
            scale=plain.get("scale", 1.0), offset=plain.get("offset", 0.0), minimum=lo, maximum=hi,
        )
        self.const: int | None = None
        if self.encoding == "const":
            raw = int(_resolve(plain["value"], params, f"the value of {self.name}"))
            self.const = raw & ((1 << self.bits) - 1)  # a parameter's low bits (e.g. a node id's low nibble)
        if self.encoding == "span" and (lo is None or hi is None or not hi > lo):
            raise CodecError(f"{self.name}: a span field needs a range [lo, hi] with hi > lo, not [{lo}, {hi}]")

    def to_raw(self, value: Number | str, si: bool, clamp: bool) -> int:
        if self.const is not None:
            return self.const
        if isinstance(value, str):
            named = [raw for raw, name in self.choices.items() if name == value]
            if not named:
                names = sorted(self.choices.values())
                raise CodecError(f"{self.name} = {value!r} is not one of its value names {names}")
            return named[0]
        wire = value / self.factor if si and self.factor != 1.0 else value
        if self.encoding == "span":
            assert self.lo is not None and self.hi is not None
            if not math.isfinite(wire):
                raise CodecError(f"{self.name} = {value} is not a finite number")
            if not self.lo <= wire <= self.hi:
                if not clamp:
                    raise CodecError(f"{self.name} = {value} is outside [{self.lo}, {self.hi}] {self._unit_words(si)}")
                wire = min(max(wire, self.lo), self.hi)
            return span_to_raw(wire, self.lo, self.hi, self.bits)
        return self.value.to_raw(wire)

    def _unit_words(self, si: bool) -> str:
        return f"(wire units; SI factor {self.factor})" if si and self.factor != 1.0 else ""

    def from_raw(self, raw: int, si: bool) -> Number:
        if self.encoding == "span":
            assert self.lo is not None and self.hi is not None
            wire: Number = raw_to_span(raw, self.lo, self.hi, self.bits)
        else:
            wire = self.value.from_raw(raw)
        return wire * self.factor if si and self.factor != 1.0 else wire

    def meaning(self, raw: int) -> tuple[list[str], str | None]:
        """(errors this raw value reports, its state name or None)."""
        errors: list[str] = []
        if self.flags:
            errors = [name for bit, name in self.flags if raw >> bit & 1 and self.role == "error"]
            known = sum(1 << bit for bit, _ in self.flags)
            if self.role == "error" and raw & ~known:
                errors.append(f"{self.name}=0x{raw & ~known:X}")
        name = self.choices.get(raw)
        if self.role == "error" and not self.flags and raw != 0:
            errors.append(name or f"{self.name}={raw}")
        if self.role == "state" and raw in self.error_values:
            errors.append(name or f"{self.name}={raw}")
        return errors, (name or str(raw)) if self.role == "state" else None


class MessageCodec:
    """One message of the profile for one device: its identifier with the device's parameters filled in, and its
    payload's fields."""

    def __init__(self, plain: Mapping[str, Any], params: Mapping[str, Number | None]) -> None:
        self.name: str = plain["name"]
        self.sender: str = plain["from"]
        self.size: int = plain["size"]
        self.fd: bool = bool(plain.get("fd", False))
        self.is_remote: bool = bool(plain.get("remote", False))
        self.pad: int = plain.get("pad", 0)
        self.fixed: bytes | None = bytes.fromhex(plain["data"]) if plain.get("data") else None
        self.reply: str | None = plain.get("reply")
        self.cyclic: str | None = plain.get("cyclic")
        self.reply_delay_us: tuple[float, float] | None = (
            tuple(plain["reply_delay_us"]) if plain.get("reply_delay_us") else None  # type: ignore[assignment]
        )
        self.delay_basis: str = plain.get("delay_basis", "")
        self.extended: bool | str = plain["id"].get("extended", False)
        self.fields = [_FieldCodec(f, params) for f in plain.get("fields") or ()]
        self.by_name = {f.name: f for f in self.fields}
        self.inputs = tuple(f.name for f in self.fields if f.const is None)
        self.payload = [f for f in self.fields if f.location == "payload"]
        self._id_fields: list[tuple[int, int, _FieldCodec]] = []
        # every identifier bit a field does not fill is fixed: a received identifier must match them all
        base, mask = 0, 0x7FF if self.extended is False else 0x1FFFFFFF
        for part in plain["id"]["parts"]:
            shift, bits = part["shift"], part["bits"]
            width = (1 << bits) - 1
            if "field" in part:
                self._id_fields.append((shift, bits, self.by_name[part["field"]]))
                mask &= ~(width << shift)
                continue
            value = part["const"] if "const" in part else params.get(part["param"])
            if value is None:
                raise CodecError(f"{self.name}: its identifier needs the parameter '{part['param']}', which has no "
                                 "value")
            value = int(value)
            if not 0 <= value <= width:
                raise CodecError(f"{self.name}: '{part.get('param', value)}' = {value} does not fit its {bits} bits "
                                 "of the identifier")
            base |= value << shift
        self.base_id, self.id_mask = base, mask
        touched = bytearray(self.size)
        for f in self.payload:
            for op in f.layout.ops:
                if op.index < self.size:
                    touched[op.index] = 1
        self._untouched = [i for i, t in enumerate(touched) if not t]

    @property
    def base(self) -> bytes:
        """The payload before its fields are written: a fixed frame as it is; else the constant fields in place and
        the padding where no field is, zeros under the other fields (what encode() ORs them into, and a C header's
        pack starts from)."""
        if self.fixed is not None or self.is_remote:
            return self.fixed or b""
        consts = {f.name: (f.layout, f.const) for f in self.payload if f.const is not None}
        packed = bytearray(encode_fields([layout for layout, _ in consts.values()], self.size,
                                         {name: value for name, (_, value) in consts.items()}))
        for i in self._untouched:
            packed[i] = self.pad
        return bytes(packed)

    def _frame_extended(self, arbitration_id: int) -> bool:
        return arbitration_id > 0x7FF if self.extended == "auto" else bool(self.extended)

    def encode(self, values: Mapping[str, Number | str], si: bool = True, clamp: bool = False) -> ActuatorFrame:
        unknown = set(values) - set(self.inputs)
        missing = set(self.inputs) - set(values)
        if unknown or missing:
            raise CodecError(f"{self.name} takes {list(self.inputs)}: unknown {sorted(unknown)}, "
                             f"missing {sorted(missing)}")
        raws = {f.name: f.to_raw(values.get(f.name, 0), si, clamp) for f in self.fields}
        arbitration_id = self.base_id
        for shift, _, f in self._id_fields:
            arbitration_id |= raws[f.name] << shift
        if self.fixed is not None:
            data = self.fixed
        elif self.is_remote:
            data = b""
        else:
            layouts = [f.layout for f in self.payload]
            packed = bytearray(encode_fields(layouts, self.size, {f.name: raws[f.name] for f in self.payload}))
            for i in self._untouched:
                packed[i] = self.pad
            data = bytes(packed)
        return ActuatorFrame(arbitration_id, self._frame_extended(arbitration_id), self.fd, data,
                             is_remote=self.is_remote, brs=self.fd, dlc=self.size if self.is_remote else None)

    def matches(self, arbitration_id: int, is_extended: bool, data: bytes) -> bool:
        if self.extended != "auto" and bool(self.extended) != is_extended:
            return False
        if self.is_remote:  # a remote request has no payload: its identifier is all there is
            return arbitration_id & self.id_mask == self.base_id
        if arbitration_id & self.id_mask != self.base_id or len(data) < self.size:
            return False
        if self.fixed is not None:
            return bytes(data[: len(self.fixed)]) == self.fixed
        consts = [f for f in self.payload if f.const is not None]
        if not consts:
            return True
        raws = decode_fields([f.layout for f in consts], bytes(data[: self.size]))
        return all(raws[f.name] == f.const for f in consts)

    def decode(self, arbitration_id: int, data: bytes, si: bool = True) -> Decoded:
        raws = decode_fields([f.layout for f in self.payload], bytes(data[: self.size])) if self.payload else {}
        for shift, bits, f in self._id_fields:
            raws[f.name] = arbitration_id >> shift & ((1 << bits) - 1)
        values: dict[str, Number] = {}
        errors: list[str] = []
        states: dict[str, str] = {}
        for f in self.fields:
            raw = int(raws[f.name])
            if f.const is None:
                values[f.name] = f.from_raw(raw, si)
            more, state = f.meaning(raw)
            errors.extend(more)
            if state is not None:
                states[f.name] = state
        return Decoded(self.name, values, tuple(errors), states)


class ActuatorCodec:
    """Every message of one actuator: encode the host's commands, decode what the device sends.

    `parameters` are the profile's parameters for this device (node_id, host ids, ranges, rates); a parameter not
    given takes the profile's default."""

    def __init__(self, profile: Mapping[str, Any], **parameters: Number) -> None:
        self.profile_name: str = profile["name"]
        declared: Mapping[str, Mapping[str, Any]] = profile.get("parameters") or {}
        unknown = set(parameters) - set(declared)
        if unknown:
            raise CodecError(f"{self.profile_name} has no parameters {sorted(unknown)}; it has {sorted(declared)}")
        # a parameter without a default (a node id) has none until given: None
        self.parameters: dict[str, Number | None] = {n: p.get("default") for n, p in declared.items()}
        self.parameters.update(parameters)
        for name, value in parameters.items():
            low, high = declared[name].get("min"), declared[name].get("max")
            if (low is not None and value < low) or (high is not None and value > high):
                raise CodecError(f"{self.profile_name}: parameter {name} = {value} is outside [{low}, {high}]")
        self.messages = {m["name"]: MessageCodec(m, self.parameters) for m in profile["messages"]}
        self._from_device = [m for m in self.messages.values() if m.sender == "device"]

    def message(self, name: str) -> MessageCodec:
        try:
            return self.messages[name]
        except KeyError:
            raise CodecError(f"{self.profile_name} has no message '{name}'; it has {sorted(self.messages)}") from None

    def encode(self, name: str, values: Mapping[str, Number | str] | None = None, *, units: str = "si",
               clamp: bool = False, **more: Number | str) -> ActuatorFrame:
        """The frame of message `name` with these values (SI units unless units="wire")."""
        return self.message(name).encode({**(values or {}), **more}, si=units == "si", clamp=clamp)

    def decode(self, arbitration_id: int, is_extended: bool, data: bytes, *, units: str = "si") -> Decoded | None:
        """The first message this device sends whose identifier and constant fields the frame matches; None for a
        frame that is not this device's."""
        for m in self._from_device:
            if m.matches(arbitration_id, is_extended, data):
                return m.decode(arbitration_id, data, si=units == "si")
        return None

    def decode_as(self, name: str, arbitration_id: int, data: bytes, *, units: str = "si") -> Decoded:
        """Frame read as message `name`, whether or not it matches (for tests and log tools)."""
        return self.message(name).decode(arbitration_id, data, si=units == "si")


@dataclass(frozen=True)
class ActuatorCommand:
    command: str  # the profile's message
    message: str  # the runtime.json message that carries it
    reply: str | None  # the profile's reply message, and the runtime.json message carrying it
    reply_message: str | None


@dataclass(frozen=True)
class Actuator:
    """An actuator profile's node in runtime.json (runtime.config.Node.actuator): what a master needs to encode
    its commands and decode what the actuator sends."""

    profile: Mapping[str, Any]  # the profile's plain form (netcfg.runtime.actuators)
    parameters: tuple[tuple[str, Number], ...]
    commanded_by: str
    commands: tuple[ActuatorCommand, ...]
    cyclic: tuple[tuple[str, str], ...]  # (profile message, runtime.json message)

    def codec(self) -> ActuatorCodec:
        return ActuatorCodec(self.profile, **dict(self.parameters))
