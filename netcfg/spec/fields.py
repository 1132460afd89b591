"""The unit-bearing fields of the spec's pydantic models: each parses with `netcfg.spec.units` and says what it
accepts in the JSON Schema. Kept apart from the parsers so that commands which only parse a `--duration` or read a
runtime configuration (simulate, run, verify) do not import pydantic.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Annotated

from pydantic import PlainSerializer, PlainValidator, WithJsonSchema

from netcfg.spec.units import NUMBER_PATTERN, Duration, parse_bitrate, parse_duration, parse_frequency, parse_offset

_DURATION_SCHEMA = {
    "anyOf": [
        {"type": "string", "pattern": rf"^\s*{NUMBER_PATTERN}\s*(ns|us|µs|ms|s|EC|ec)\s*$"},
        {"const": 0},
    ],
    "description": "a duration with its unit, e.g. '5 ms', '250 us', or elementary cycles on FTT-CAN, e.g. '2 EC'",
}
_BITRATE_SCHEMA = {
    "type": "string",
    "pattern": rf"^\s*{NUMBER_PATTERN}\s*(?i:bit/s|bps|kbit/s|kbps|Mbit/s|Mbps|Gbit/s|Gbps|k|M|G)\s*$",
    "description": "a bit rate with its unit, e.g. '250 kbit/s', '1 Mbit/s', '100 Mbit/s', or short: '500k', '1M'",
}
_FREQ_SCHEMA = {
    "type": "string",
    "pattern": rf"^\s*{NUMBER_PATTERN}\s*(?i:Hz|kHz|MHz)\s*$",
    "description": "a frequency with its unit, e.g. '15 kHz'",
}

DurationField = Annotated[
    Duration,
    PlainValidator(parse_duration),
    PlainSerializer(str),
    WithJsonSchema(_DURATION_SCHEMA),
]
BitRateField = Annotated[int, PlainValidator(parse_bitrate), WithJsonSchema(_BITRATE_SCHEMA)]
FrequencyField = Annotated[
    Fraction,
    PlainValidator(parse_frequency),
    PlainSerializer(lambda f: f"{float(f):g} Hz"),
    WithJsonSchema(_FREQ_SCHEMA),
]
OffsetField = Annotated[
    Duration | str,
    PlainValidator(parse_offset),
    PlainSerializer(str),
    WithJsonSchema({"anyOf": [_DURATION_SCHEMA, {"const": "auto"}]}),
]
