"""The fault drills of a CANopen network, written once for both places that play them:

    netcfg run SPEC --simulated-drives --reset knee_r@1s+50ms     (the live master, on simulated drives)
    netcfg simulate SPEC --fault reset:knee_r@1s+50ms             (the simulator, in virtual time)

`simulate --fault KIND:ARG` is `run --KIND ARG`, the same ARG:

    kill:NODE@T                  the node drops off the bus at T (simulate's crash:NODE@T)
    emcy:NODE@T[=CODE]           the node sends an EMCY (default 0x2310, CiA 402 "continuous over-current") and faults
    reset:NODE@T+OUTAGE          the node reboots at T: silent for OUTAGE, then its boot-up message, PRE-OPERATIONAL
    sdo-abort:NODE:INDEX[:SUB][=CODE]   the node aborts every SDO write to that object (default 0x08000020)
    stall:T..T2                  the master's loop pauses from T to T2: no SYNC, no RxPDO
    bus-off:T..T2                the master's CAN controller is bus-off from T to T2

Times are instants from the start in the one unit grammar of specs and the command line (netcfg.spec.units).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from netcfg.spec.units import format_ns, parse_instant_option

__all__ = [
    "ACTUATOR_KINDS", "DEFAULT_ABORT", "DEFAULT_EMCY", "KINDS", "NODE_KINDS", "Drill", "DrillError", "parse_drill",
    "split_drill",
]

DEFAULT_EMCY = 0x2310  # CiA 402: "continuous over-current", a drive's typical fault
DEFAULT_ABORT = 0x08000020  # CiA 301: "data cannot be transferred or stored to the application"
NODE_KINDS = ("kill", "emcy", "reset", "sdo-abort")  # drills on a node (simulated drives)
KINDS = (*NODE_KINDS, "stall", "bus-off")  # and on the master
ACTUATOR_KINDS = ("kill", "fault")  # on a simulated actuator (run's actuator bus): silent, or its error fields set
EXAMPLES = {
    "kill": "knee_r@1s",
    "fault": "elbow@0.6s",
    "emcy": "knee_r@1s=0x2310",
    "reset": "knee_r@1s+50ms",
    "sdo-abort": "knee_r:0x1A00:0=0x06010002",
    "stall": "1s..1.2s",
    "bus-off": "1s..1.2s",
}


class DrillError(ValueError):
    """A drill that cannot be read: says what the grammar wants."""


@dataclass(frozen=True)
class Drill:
    kind: str  # one of KINDS
    node: str | None = None  # the node drills: its name
    at_ns: int = 0  # when it happens (stall, bus-off: its start)
    until_ns: int = 0  # stall, bus-off: its end; reset: the boot-up (at + outage)
    code: int = 0  # emcy: its error code; sdo-abort: its abort code
    obj: int | tuple[int, int] | None = None  # sdo-abort: the index, or (index, sub-index)

    @property
    def at_s(self) -> float:
        return self.at_ns / 1e9

    @property
    def until_s(self) -> float:
        return self.until_ns / 1e9

    @property
    def outage_s(self) -> float:
        return (self.until_ns - self.at_ns) / 1e9

    def text(self) -> str:
        """The drill as `simulate --fault` writes it: KIND:ARG, ARG as `run --KIND` takes it."""
        return f"{self.kind}:{_FORMS[self.kind][0](self)}"

    def description(self) -> str:
        """What the drill does, as the drills' lines of `run` and `simulate` say it."""
        return _FORMS[self.kind][1](self)


def _s(ns: int) -> str:
    return format_ns(ns).replace(" ", "")


def _span(d: Drill) -> str:
    return f"{_s(d.at_ns)}..{_s(d.until_ns)}"


def _abort_object(d: Drill) -> str:
    index, sub = d.obj if isinstance(d.obj, tuple) else (d.obj, None)
    return f"0x{index:04X}" + ("" if sub is None else f":{sub}")


# each kind's ARG as parse_drill reads it, and its sentence: one entry to write for a new kind
_FORMS: dict[str, tuple[Callable[[Drill], str], Callable[[Drill], str]]] = {
    "kill": (lambda d: f"{d.node}@{_s(d.at_ns)}", lambda d: f"{d.node} killed"),
    "fault": (lambda d: f"{d.node}@{_s(d.at_ns)}", lambda d: f"{d.node} reports an error"),
    "emcy": (
        lambda d: f"{d.node}@{_s(d.at_ns)}=0x{d.code:04X}",
        lambda d: f"{d.node} sends EMCY 0x{d.code:04X}",
    ),
    "reset": (
        lambda d: f"{d.node}@{_s(d.at_ns)}+{_s(d.until_ns - d.at_ns)}",
        lambda d: f"{d.node} reboots, silent for {1e3 * d.outage_s:g} ms",
    ),
    "sdo-abort": (
        lambda d: f"{d.node}:{_abort_object(d)}=0x{d.code:08X}",
        lambda d: f"{d.node} aborts every SDO write to {_abort_object(d)}=0x{d.code:08X}",
    ),
    "stall": (_span, lambda d: f"the master's loop stalls until {d.until_s:g} s: no SYNC, no RxPDO"),
    "bus-off": (_span, lambda d: f"the master's CAN controller goes bus-off until {d.until_s:g} s"),
}


def split_drill(text: str) -> tuple[str, str] | None:
    """'KIND:ARG' with a drill's KIND -> (KIND, ARG); None for any other text (simulate's own faults)."""
    kind, colon, arg = text.strip().partition(":")
    return (kind, arg) if colon and kind in KINDS else None


def parse_drill(kind: str, text: str) -> Drill:
    """`run --KIND TEXT` (= `simulate --fault KIND:TEXT`) -> the drill; DrillError saying the grammar otherwise."""
    if kind not in KINDS and kind not in ACTUATOR_KINDS:
        raise DrillError(f"no drill '{kind}': the drills are {', '.join(dict.fromkeys((*KINDS, *ACTUATOR_KINDS)))}")
    t = text.strip()
    if kind in ("stall", "bus-off"):
        start, dots, end = t.partition("..")
        if not dots:
            raise DrillError(f"--{kind} {text!r}: write FROM..TO, e.g. {EXAMPLES[kind]}")
        span = _instant(start, kind, text), _instant(end, kind, text)
        if span[1] <= span[0]:
            raise DrillError(f"--{kind} {text!r}: the span ends before it begins")
        return Drill(kind, at_ns=span[0], until_ns=span[1])
    if kind == "sdo-abort":
        return _abort(t)
    node, at, rest = t.partition("@")
    if not at or not node:
        what = "NODE@TIME+OUTAGE" if kind == "reset" else "NODE@TIME"
        raise DrillError(f"--{kind} {text!r}: write {what}, e.g. {EXAMPLES[kind]}")
    if kind == "reset":
        instant, plus, outage = rest.partition("+")
        if not plus:
            raise DrillError(f"--reset {text!r}: write NODE@TIME+OUTAGE, e.g. {EXAMPLES['reset']}")
        begin = _instant(instant, kind, text)
        length = _instant(outage, kind, text)
        if length <= 0:
            raise DrillError(f"--reset {text!r}: the outage must be longer than 0, e.g. +50ms")
        return Drill(kind, node, begin, begin + length)
    when, eq, code = rest.partition("=")
    if eq and kind != "emcy":
        raise DrillError(f"--{kind} {text!r}: only --emcy takes a code")
    try:
        value = int(code, 0) if eq else DEFAULT_EMCY
    except ValueError:
        raise DrillError(f"--emcy {text!r}: the code is a number such as 0x2310") from None
    if not 0 <= value <= 0xFFFF:
        raise DrillError(f"--emcy {text!r}: an EMCY error code has 16 bits")
    return Drill(kind, node, _instant(when, kind, text), code=value if kind == "emcy" else 0)


def _instant(text: str, kind: str, whole: str) -> int:
    try:
        return parse_instant_option(text.strip())
    except ValueError as exc:
        raise DrillError(f"--{kind} {whole!r}: {exc}") from None


def _abort(text: str) -> Drill:
    """'NODE:INDEX[:SUB][=CODE]'."""
    where, eq, code = text.partition("=")
    node, *obj = where.split(":")
    try:
        if not node or len(obj) not in (1, 2):
            raise ValueError
        numbers = [int(o, 0) for o in obj]
        value = int(code, 0) if eq else DEFAULT_ABORT
    except ValueError:
        raise DrillError(
            f"--sdo-abort {text!r}: write NODE:INDEX[:SUB][=CODE], e.g. {EXAMPLES['sdo-abort']}"
        ) from None
    if not 0 <= numbers[0] <= 0xFFFF or (len(numbers) == 2 and not 0 <= numbers[1] <= 0xFF) or not 0 <= value < 2**32:
        raise DrillError(f"--sdo-abort {text!r}: an index has 16 bits, a sub-index 8, an abort code 32")
    where_obj: int | tuple[int, int] = numbers[0] if len(numbers) == 1 else (numbers[0], numbers[1])
    return Drill("sdo-abort", node, code=value, obj=where_obj)
