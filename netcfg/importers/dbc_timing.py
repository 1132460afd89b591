"""When a DBC message is sent and how fast its bus runs, as the spec says them.

Owns the reading of GenMsgSendType and the time attributes (Vector's Gen* ones in ms, and netcfg's own exact
Netcfg* ones, which win) into a spec message's period, min_interarrival or on-demand type (message_timing, by the
rules in netcfg.importers.dbc's docstring), and of Baudrate/BusSpeed and Baudrate_CANFD into the bus's bit rates.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from decimal import Decimal
from typing import Any

from cantools.database.can import Database, Message

from netcfg.importers import ImportOptions
from netcfg.importers.dbc_text import DbcFile
from netcfg.links.dbc_frames import fd_frame
from netcfg.spec.units import format_ns

KBIT_LIMIT = 1000  # Baudrate/BusSpeed values up to this are kbit/s: no CAN bus runs at 1000 bit/s or less
TIME_ATTRIBUTES = (
    "GenMsgCycleTime",
    "GenMsgCycleTimeFast",
    "GenMsgDelayTime",
    "GenMsgStartDelayTime",
    "NetcfgPeriod",
    "NetcfgMinInterarrival",
    "NetcfgOffset",
    "NetcfgJitter",
    "NetcfgDeadline",
)

# GenMsgSendType values seen in DBCs in the wild, lower-cased without punctuation (see send_kind)
_NONE_KINDS = ("none", "nomsgsendtype", "nosendtype", "notused", "reserved", "")
_EVENT_WORDS = ("event", "spontan", "trigger", "ifactive", "onchange", "onwrite", "request")


@dataclass
class Timing:
    data: dict[str, Any]  # period / min_interarrival / type keys of the spec message
    note: str  # for the provenance comment


def send_kind(send_type: str | None) -> str:
    """GenMsgSendType -> 'cyclic', 'event', 'mixed', 'none', 'absent' or 'unknown' (see netcfg.importers.dbc)."""
    if send_type is None:
        return "absent"
    key = re.sub(r"[^a-z]", "", send_type.lower())
    if key in _NONE_KINDS or key.startswith("notused"):
        return "none"
    if key in ("ce", "ca"):  # Vector's short forms: Cyclic+Event, Cyclic+IfActive
        return "mixed"
    if key.startswith("cyclic"):
        rest = key[len("cyclic") :].removeprefix("ifactive")  # cyclicIfActive: cyclic while active, no events
        return "mixed" if "and" in rest or any(w in rest for w in _EVENT_WORDS) else "cyclic"
    if any(w in key for w in _EVENT_WORDS):
        return "event"
    return "unknown"


def ms_text(ms: float) -> str:
    """A DBC time attribute (ms) as a spec duration, exact: 10 -> '10 ms', 2.5 -> '2.5 ms'."""
    value = Decimal(str(ms))
    text = format(value.normalize(), "f") if value != value.to_integral_value() else str(int(value))
    return f"{text} ms"


def ms_exact(ms: float) -> str:
    """netcfg's own FLOAT ms attributes carry whole nanoseconds: back to the exact duration."""
    return format_ns(round(ms * 1_000_000))


# netcfg's exact timing attributes (ms, FLOAT), by spec key
EXACT = {
    "period": "NetcfgPeriod",
    "min_interarrival": "NetcfgMinInterarrival",
    "offset": "NetcfgOffset",
    "jitter": "NetcfgJitter",
    "deadline": "NetcfgDeadline",
}


def bitrate_text(bps: int) -> str:
    for unit, scale in (("Mbit/s", 1_000_000), ("kbit/s", 1_000)):
        if bps % scale == 0:
            return f"{bps // scale} {unit}"
    return f"{bps} bit/s"


def data_bitrate(dbc: DbcFile, db: Database, options: ImportOptions) -> tuple[int, str] | None:
    """The CAN FD data rate: --data-bitrate, else Vector's Baudrate_CANFD attribute."""
    if options.data_bitrate is not None:
        return options.data_bitrate, "from the command line (--data-bitrate), which wins over the DBC"
    fd_names = [f"message '{m.name}'" for m in db.messages if fd_frame(m)]
    more = f" and {len(fd_names) - 3} more" if len(fd_names) > 3 else ""
    got = dbc.db_attribute(db, "Baudrate_CANFD")
    if got is not None:
        try:
            number = round(float(str(got[0]).strip()))
        except ValueError:
            number = 0
        if number > 0:
            return number, f"{got[1]}, in bit/s"
    dbc.add(
        "dbc-data-bitrate",
        f"the DBC has CAN FD frames ({', '.join(fd_names[:3])}{more}) but no data bit rate (no Baudrate_CANFD "
        "attribute); give one on the command "
        'line, e.g. `--data-bitrate 2M`, or add `BA_ "Baudrate_CANFD" 2000000;` to the DBC',
        dbc.lines.attributes.get("Baudrate_CANFD"),
    )
    return None

def bitrate(dbc: DbcFile, db: Database, options: ImportOptions) -> tuple[int, str] | None:
    if options.bitrate is not None:
        return options.bitrate, "from the command line (--bitrate), which wins over the DBC"
    for name in ("Baudrate", "BusSpeed"):
        got = dbc.db_attribute(db, name)
        if got is None:
            continue
        value, where = got
        at = dbc.lines.attributes.get(name)
        try:
            number = float(str(value).strip())
        except ValueError:
            dbc.add("dbc-bitrate", f"cannot read {where} as a bit rate; give one with --bitrate 500k", at)
            return None
        if number <= 0:
            continue
        if number <= KBIT_LIMIT:
            bps = round(number * 1000)
            dbc.add(
                "dbc-bitrate",
                f"{where}: read as {number:g} kbit/s (values up to {KBIT_LIMIT} cannot be bit/s); "
                "give --bitrate to override",
                at,
                "warning",
            )
            return bps, f"{where}, read as kbit/s"
        return round(number), f"{where}, in bit/s"
    dbc.add(
        "dbc-bitrate",
        "no bit rate: the DBC has no Baudrate or BusSpeed attribute; give one on the command line, e.g. "
        "`--bitrate 500k` (netcfg check FILE.dbc --bitrate 500k, netcfg import dbc FILE.dbc --bitrate 500k -o "
        'SPEC), or add `BA_ "Baudrate" 500000;` to the DBC',
        None,
    )
    return None


def message_timing(
    dbc: DbcFile, db: Database, msg: Message, at: tuple[int, int] | None, options: ImportOptions
) -> Timing:
    """The spec's keys for when the message is sent, and where they came from."""
    exact = {key: dbc.message_attribute(db, msg, name, zero=True) for key, name in EXACT.items()}
    if exact["period"] is not None or exact["min_interarrival"] is not None:
        # netcfg's own attributes: the spec's timing, exactly (written by netcfg.emit.dbc); the rounded
        # Gen* attributes beside them are for other tools
        key = "period" if exact["period"] is not None else "min_interarrival"
        timing = Timing({key: ms_exact(exact[key] or 0)}, f"{EXACT[key]} {ms_exact(exact[key] or 0)}")
    elif "period" in (timing := _send_timing(dbc, db, msg, at, options)).data:
        start = dbc.message_attribute(db, msg, "GenMsgStartDelayTime")
        if start is not None:
            timing.data["offset"] = ms_text(start)
            timing.note += f", GenMsgStartDelayTime {ms_text(start)} (offset)"
    for key in ("offset", "jitter", "deadline"):
        if exact[key] is not None and "type" not in timing.data:
            timing.data[key] = ms_exact(exact[key] or 0)
            timing.note += f", {EXACT[key]} {ms_exact(exact[key] or 0)}"
    return timing


def _send_timing(
    dbc: DbcFile, db: Database, msg: Message, at: tuple[int, int] | None, options: ImportOptions
) -> Timing:
    """The timing by GenMsgSendType and the Gen* time attributes (no exact Netcfg* period or gap given)."""
    send_type = msg.send_type
    kind = send_kind(send_type)
    cycle = dbc.message_attribute(db, msg, "GenMsgCycleTime")
    fast = dbc.message_attribute(db, msg, "GenMsgCycleTimeFast")
    delay = dbc.message_attribute(db, msg, "GenMsgDelayTime")
    said = f"GenMsgSendType {send_type}" if send_type is not None else "no GenMsgSendType"
    cyc = f"GenMsgCycleTime {ms_text(cycle)}" if cycle else "no GenMsgCycleTime"

    def on_demand(why: str) -> Timing:
        assumed = options.default_period_ns
        if assumed is not None:
            dbc.add(
                "dbc-default-period",
                f"message '{msg.name}': {why}; analysed as periodic every {format_ns(assumed)} "
                "(--default-period)",
                at,
                "warning",
            )
            return Timing({"period": format_ns(assumed)}, f"{said}, {cyc}: --default-period assumed")
        dbc.add(
            "dbc-not-analysed",
            f"message '{msg.name}' not analysed: {why}; imported as 'type: on-demand' (give it a period or "
            "min_interarrival in the spec if it is sent regularly, or assume one with --default-period)",
            at,
            "warning",
        )
        return Timing({"type": "on-demand"}, f"{said}, {cyc}: on-demand, not analysed")

    repeats = dbc.message_attribute(db, msg, "GenMsgNrOfRepetition")
    fast_name = "GenMsgCycleTimeFast" + (f" (also between the {repeats:g} repetitions)" if repeats else "")
    gaps = [(v, n) for v, n in ((delay, "GenMsgDelayTime"), (fast, fast_name)) if v]
    if kind == "cyclic":
        period = fast if "fast" in (send_type or "").lower() and fast else cycle
        if period is None:
            return on_demand(f"{said} but no GenMsgCycleTime")
        src = "GenMsgCycleTimeFast" if period is not cycle else "GenMsgCycleTime"
        return Timing({"period": ms_text(period)}, f"{said}, {src} {ms_text(period)}")
    if kind == "event" or (kind == "mixed" and cycle is None):
        if not gaps:
            return on_demand(f"{said} with no GenMsgDelayTime or GenMsgCycleTimeFast to bound its rate")
        gap, src = min(gaps)
        return Timing({"min_interarrival": ms_text(gap)}, f"{said}: sporadic, {src} {ms_text(gap)} apart")
    if kind == "mixed":
        assert cycle is not None
        if not gaps:
            dbc.add(
                "dbc-event-timing",
                f"message '{msg.name}': {said} also sends on events, but no GenMsgDelayTime or "
                f"GenMsgCycleTimeFast bounds them; analysed as periodic at {cyc} only",
                at,
                "warning",
            )
            return Timing({"period": ms_text(cycle)}, f"{said}, {cyc}: events between cycles not analysed")
        gap, src = min([*gaps, (cycle, "GenMsgCycleTime")])
        return Timing(
            {"min_interarrival": ms_text(gap)}, f"{said}, {cyc}: sporadic, at least {src} {ms_text(gap)} apart"
        )
    # none, unknown or absent send type: the cycle time decides
    if cycle is None:
        return on_demand("no GenMsgCycleTime" + (f" ({said})" if send_type is not None else ""))
    if kind != "absent":
        dbc.add(
            "dbc-send-type",
            f"message '{msg.name}': {said} is not a cyclic send type, but {cyc} is given; analysed as periodic",
            at,
            "warning",
        )
    return Timing({"period": ms_text(cycle)}, f"{said}, {cyc}")
