"""Quantities as engineers write them: '5 ms', '250 us', '250 kbit/s', '1 Mbit/s', '15 kHz', '2 EC'.

Time is exact inside netcfg: durations become integer nanoseconds, rates integer bit/s. A bare number is
refused because '250' alone could mean anything; the error says which units are understood.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from fractions import Fraction
from typing import Any

NUMBER_PATTERN = r"([0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
_QUANTITY = re.compile(rf"^\s*({NUMBER_PATTERN})\s*([A-Za-zµμ/]+)\s*$", re.ASCII)
_NUMBER_ONLY = re.compile(rf"^-?{NUMBER_PATTERN}$", re.ASCII)

TIME_UNITS_NS: dict[str, int] = {
    "ns": 1,
    "us": 1_000,
    "µs": 1_000,
    "μs": 1_000,
    "ms": 1_000_000,
    "s": 1_000_000_000,
}
RATE_UNITS: dict[str, int] = {
    "bit/s": 1,
    "bps": 1,
    "kbit/s": 1_000,
    "kbps": 1_000,
    "mbit/s": 1_000_000,
    "mbps": 1_000_000,
    "gbit/s": 1_000_000_000,
    "gbps": 1_000_000_000,
}
# the short forms people type for bit rates, in specs and on the command line alike: 500k, 1M (never milli-)
SHORT_RATE_UNITS: dict[str, int] = {"k": 1_000, "m": 1_000_000, "g": 1_000_000_000}
FREQ_UNITS: dict[str, int] = {"hz": 1, "khz": 1_000, "mhz": 1_000_000}
# spellings that are not units here, with the unit meant (the error suggests it)
_UNIT_ALIASES: dict[str, str] = {
    "msec": "ms", "msecs": "ms", "millisecond": "ms", "milliseconds": "ms",
    "usec": "us", "usecs": "us", "microsecond": "us", "microseconds": "us",
    "nsec": "ns", "nsecs": "ns", "nanosecond": "ns", "nanoseconds": "ns",
    "sec": "s", "secs": "s", "second": "s", "seconds": "s",
    "kb/s": "kbit/s", "kbits/s": "kbit/s", "kbaud": "kbit/s", "mb/s": "Mbit/s", "mbits/s": "Mbit/s", "mbaud": "Mbit/s",
    "baud": "bit/s", "bits/s": "bit/s",
}


def _unit_hint(unit: str, known: list[str]) -> str:
    """" (did you mean 'ms'?)" for a unit that is a common spelling or close to a known one, else ""."""
    meant = _UNIT_ALIASES.get(unit.lower())
    if meant is None:
        by_lower = {k.lower(): k for k in known}
        close = difflib.get_close_matches(unit.lower(), list(by_lower), n=1, cutoff=0.6)
        meant = by_lower[close[0]] if close else None
    return f" (did you mean '{meant}'?)" if meant else ""
EC_UNITS = ("ec", "ecs")
MAX_DURATION_NS = 10**15  # about 11.6 days: longer periods are mistakes, and sums must stay in 64 bits
MAX_EC_COUNT = 1_000_000
MAX_BITRATE = 10**12  # 1 Tbit/s: beyond every bus netcfg models
MAX_FREQUENCY_HZ = Fraction(10**9)
MIN_FREQUENCY_HZ = Fraction(10**9, MAX_DURATION_NS)  # its period is the longest duration netcfg handles


MAX_NUMBER_CHARS = 40  # no quantity needs more digits; 5,000-digit numbers are refused before any arithmetic
MAX_EXPONENT = 24  # |exponent| of a number's leading digit: 1e24 of any unit is beyond every range below


def parse_number(text: str, what: str = "number") -> Decimal:
    """A plain decimal number as netcfg reads one everywhere (specs, command line): ASCII digits only, finite, at
    most MAX_NUMBER_CHARS long, its magnitude within 10^-24..10^24 (so no arithmetic on it can blow up or hang).
    ValueError names the problem."""
    t = text.strip()
    if len(t) > MAX_NUMBER_CHARS:
        raise ValueError(f"{what}: a number of {len(t):,} characters is out of range (at most {MAX_NUMBER_CHARS})")
    if not _NUMBER_ONLY.match(t):
        raise ValueError(f"{what}: cannot read {text!r} as a number; write digits 0-9, e.g. 250 or 1.5")
    try:
        number = Decimal(t)
    except InvalidOperation as exc:  # pragma: no cover - the regex only admits decimals
        raise ValueError(f"{what}: cannot read the number {text!r}") from exc
    if number and not -MAX_EXPONENT <= number.adjusted() <= MAX_EXPONENT:
        raise ValueError(f"{what}: {text!r} is out of range (numbers are read between 1e-{MAX_EXPONENT} and "
                         f"1e{MAX_EXPONENT})")
    return number


def _split(value: Any, kind: str, example: str) -> tuple[Decimal, str]:
    if isinstance(value, bool) or not isinstance(value, str):
        raise ValueError(f"write the {kind} with a unit as a string, for example '{example}' (got {value!r})")
    if len(value) > 2 * MAX_NUMBER_CHARS:
        raise ValueError(f"a {kind} of {len(value):,} characters is out of range; write it like '{example}'")
    m = _QUANTITY.match(value)
    if not m:
        raise ValueError(f"cannot read {value!r} as a {kind}; write it like '{example}'")
    number = parse_number(m.group(1), repr(value))
    return number, m.group(m.lastindex or 0)


@dataclass(frozen=True, order=True)
class Duration:
    """A duration given either in time units (ns) or in FTT-CAN elementary cycles (ec)."""

    ns: int | None = None
    ec: int | None = None

    def __str__(self) -> str:
        if self.ec is not None:
            return f"{self.ec} EC"
        return format_ns(self.ns or 0)

    def to_ns(self, ec_ns: int | None) -> int | None:
        """Nanoseconds; None when the duration is in ECs and no EC length is known."""
        if self.ec is not None:
            return None if ec_ns is None else self.ec * ec_ns
        return self.ns


def format_ns(ns: int | float) -> str:
    for unit, scale in (("s", 1_000_000_000), ("ms", 1_000_000), ("us", 1_000)):
        if abs(ns) >= scale and (ns % scale == 0 or unit != "s"):
            text = f"{ns / scale:.6f}".rstrip("0").rstrip(".")
            return f"{text} {unit}"
    return f"{ns} ns"


def parse_duration(value: Any) -> Duration:
    if isinstance(value, Duration):
        return value
    if value == 0 and isinstance(value, int) and not isinstance(value, bool):
        return Duration(ns=0)  # zero needs no unit
    number, unit = _split(value, "duration", "5 ms")
    key = unit.lower()
    if key in EC_UNITS:
        if number != number.to_integral_value() or number < 0 or number > MAX_EC_COUNT:
            raise ValueError(f"{value!r}: a count of elementary cycles must be a whole number, 0..{MAX_EC_COUNT:,}")
        return Duration(ec=int(number))
    scale = TIME_UNITS_NS.get(unit) or TIME_UNITS_NS.get(key)
    if scale is None and key in FREQ_UNITS and number > 0:
        period = Fraction(10**9) / (Fraction(number) * FREQ_UNITS[key])
        meant = f"'{format_ns(int(period))}'" if period.denominator == 1 else "its period"
        raise ValueError(
            f"{value!r} is a frequency, not a time: write {meant}, or 'rate: {value}' where a rate is taken"
        )
    if scale is None:
        hint = _unit_hint(unit, ["ns", "us", "ms", "s", "EC"])
        raise ValueError(f"unknown time unit '{unit}' in {value!r}{hint}; use ns, us, ms, s or EC")
    ns = number * scale
    if ns > MAX_DURATION_NS:
        raise ValueError(f"{value!r} is longer than netcfg handles ({MAX_DURATION_NS // 10**9:,} s)")
    if ns != ns.to_integral_value():
        raise ValueError(f"{value!r} is finer than 1 ns; netcfg keeps time in whole nanoseconds")
    if ns < 0:
        raise ValueError(f"{value!r}: durations cannot be negative")
    return Duration(ns=int(ns))


def parse_bitrate(value: Any) -> int:
    number, unit = _split(value, "bit rate", "250 kbit/s")
    scale = RATE_UNITS.get(unit.lower()) or SHORT_RATE_UNITS.get(unit.lower())
    if scale is None:
        hint = _unit_hint(unit, ["bit/s", "kbit/s", "Mbit/s", "Gbit/s"])
        raise ValueError(
            f"unknown bit-rate unit '{unit}' in {value!r}{hint}; use bit/s, kbit/s, Mbit/s or Gbit/s (or 500k, 1M)"
        )
    rate = number * scale
    if rate != rate.to_integral_value() or rate <= 0 or rate > MAX_BITRATE:
        raise ValueError(f"{value!r}: a bit rate must be a positive whole number of bit/s")
    return int(rate)


def parse_frequency(value: Any) -> Fraction:
    number, unit = _split(value, "frequency", "15 kHz")
    scale = FREQ_UNITS.get(unit.lower())
    if scale is None:
        raise ValueError(f"unknown frequency unit '{unit}' in {value!r}; use Hz, kHz or MHz")
    f = Fraction(number) * scale
    if f < MIN_FREQUENCY_HZ or f > MAX_FREQUENCY_HZ:
        raise ValueError(
            f"{value!r}: a frequency must be between {float(MIN_FREQUENCY_HZ):g} Hz (a period of "
            f"{MAX_DURATION_NS // 10**9:,} s) and 1 GHz"
        )
    return f


def parse_offset(value: Any) -> Duration | str:
    """An offset is a duration or 'auto' (derived from the flows it belongs to, FTT-CAN)."""
    if value == "auto":
        return "auto"
    return parse_duration(value)


# --- the command line: the same grammar, plus the short forms people type there --------------------------------


MIN_PLAIN_BITRATE = 1_000  # a plain --bitrate below this is taken for a forgotten 'k'


def parse_bitrate_option(text: str) -> int:
    """A --bitrate: any spec bit rate ('500 kbit/s', '500k', '1M') or, on the command line only, a plain number of
    bit/s ('250000'). ValueError when not."""
    short = text.strip()
    if _NUMBER_ONLY.match(short):
        number = parse_number(short, f"bit rate {text!r}")
        if number != number.to_integral_value() or not 0 < number <= MAX_BITRATE:
            raise ValueError(f"bit rate {text!r}: give a whole number of bit/s above 0, at most 1 Tbit/s")
        if number < MIN_PLAIN_BITRATE:
            # no bus runs below 1 kbit/s: '500' is kbit/s written without its unit
            raise ValueError(f"{text} bit/s is slower than any bus; did you mean '{short}k'?")
        return int(number)
    return parse_bitrate(text)


def parse_duration_option(text: str, max_ns: int = MAX_DURATION_NS) -> int:
    """A duration on the command line, '10s', '500 ms', '250us', as in a spec; above 0 and at most max_ns.
    -> nanoseconds. ValueError when not."""
    d = parse_duration(text)
    if d.ns is None:
        raise ValueError(f"{text!r}: give the duration in ns, us, ms or s (EC only exists inside a spec)")
    if not 0 < d.ns <= max_ns:
        raise ValueError(f"{text!r}: a duration must be above 0 and at most {format_ns(max_ns)}")
    return d.ns


def parse_instant_option(text: str, max_ns: int = MAX_DURATION_NS) -> int:
    """An instant on the command line, counted from the start ('--fault crash:NODE@2s', '@12.5 ms', '@0'): the
    duration grammar, zero allowed. -> nanoseconds. ValueError when not."""
    t = text.strip()
    d = parse_duration(0 if t == "0" else t)
    if d.ns is None:
        raise ValueError(f"{text!r}: give the time in ns, us, ms or s (EC only exists inside a spec)")
    if d.ns > max_ns:
        raise ValueError(f"{text!r}: a time must be at most {format_ns(max_ns)}")
    return d.ns


def parse_int_option(text: str, what: str, low: int, high: int) -> int:
    """A whole number on the command line (ASCII digits, within [low, high]). ValueError when not."""
    t = text.strip()
    if not re.fullmatch(r"[+-]?[0-9]{1,18}", t, re.ASCII):
        raise ValueError(f"{what} {text!r}: write a whole number with the digits 0-9")
    value = int(t)
    if not low <= value <= high:
        raise ValueError(f"{what} {value}: must be between {low:,} and {high:,}")
    return value
