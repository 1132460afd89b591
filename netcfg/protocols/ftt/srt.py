"""ftt/<bus>_srt.{h,c,csv,md} for every FTT-CAN bus: the master's Synchronous Requirements Table and the
EC-schedules of one macro-cycle.

The table and the schedule are the ones the analysis built with netcfg.timing.ftt (model.Bus.ftt_schedule);
nothing here recomputes timing. The C files give the master a const table and
a const array of the EC-schedule bit masks its trigger message carries, EC by EC; the CSV and Markdown files
lay the table out as the CAMBADA paper's Table 2 (seed 002): FTT ID, Source, Destination, Period and Init
time in ECs, Short description; messages, then triggers, by FTT id.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from netcfg import model
from netcfg.records import same_named
from netcfg.templating import render
from netcfg.timing import ftt


@dataclass(frozen=True)
class EntryView:
    ftt_id: int
    name: str
    kind: str  # "message" | "trigger"
    producer: str | None
    destination: tuple[str, ...]  # consumers of a message; nodes whose tasks a trigger activates
    targets: tuple[str, ...]  # consumers, or node.task
    size: int
    can_id: int | None
    c_bits: int
    period_ec: int
    fastest_period_ec: int
    init_ec: int
    deadline_us: int | None  # rounded down: a master that checks against it is never late by rounding
    description: str


@dataclass(frozen=True)
class EcView:
    index: int
    ids: tuple[int, ...]
    mask: int
    sync_ns: int  # worst-case length of the synchronous window
    sync_us: str


@dataclass(frozen=True)
class SrtView:
    system: str
    bus: str
    bitrate: int
    ec_ns: int
    ec_us: str
    tm_id: int
    tm_extended: bool
    tm_size: int
    tm_bits: int  # 8 * tm_size: one EC-schedule bit per FTT id
    mask_width: int  # smallest uintN_t holding tm_bits
    lsw_ns: int
    lsw_us: str
    master: str
    entries: tuple[EntryView, ...]
    ecs: tuple[EcView, ...]


def us(ns: int) -> str:
    """Exact microseconds for the text tables: 1900, 66.667."""
    return str(ns // 1000) if ns % 1000 == 0 else f"{ns / 1000:.3f}".rstrip("0")


def _description(obj: model.Described | None) -> str:
    # free text from the spec on one line; the templates escape it for each format
    return " ".join(obj.description.split()) if obj is not None and obj.description else ""


def _entry(m: model.Model, e: ftt.SrtEntry) -> EntryView:
    if e.kind == "message":
        destination = e.targets
        description = _description(m.messages.get(e.name))
    else:
        destination = tuple(dict.fromkeys(t.split(".", 1)[0] for t in e.targets))
        description = _description(m.triggers.get(e.name)) or "activates " + ", ".join(e.targets)
    return EntryView(
        **same_named(e, "ftt_id name kind producer targets size can_id c_bits period_ec fastest_period_ec init_ec"),
        destination=destination,
        deadline_us=None if e.deadline_ns is None else e.deadline_ns // 1000,
        description=description,
    )


def srt_view(m: model.Model, bus: model.Bus) -> SrtView:
    assert bus.ftt is not None
    sched = bus.ftt_schedule
    assert sched is not None  # the analysis built it; a spec whose macro-cycle is too long never gets here
    tm_bits = 8 * bus.ftt.tm_size
    # Table 2's order: messages, then triggers, each by FTT id
    ordered = sorted(sched.entries, key=lambda e: (e.kind != "message", e.ftt_id))
    return SrtView(
        system=m.system,
        bus=bus.name,
        bitrate=bus.bitrate,
        ec_ns=sched.ec_ns,
        ec_us=us(sched.ec_ns),
        tm_id=bus.ftt.tm_id,
        tm_extended=bus.ftt.tm_extended,
        tm_size=bus.ftt.tm_size,
        tm_bits=tm_bits,
        mask_width=next(w for w in (8, 16, 32, 64) if w >= tm_bits),
        lsw_ns=sched.lsw_ns,
        lsw_us=us(sched.lsw_ns),
        master=bus.ftt.master,
        entries=tuple(_entry(m, e) for e in ordered),
        ecs=tuple(EcView(s.index, s.ids, ftt.ec_schedule_mask(s), s.sync_ns, us(s.sync_ns)) for s in sched.slots),
    )


def emit(m: model.Model, report: dict[str, Any]) -> dict[str, bytes]:
    files = {}
    for bus in m.buses.values():
        if bus.ftt is None:
            continue
        view = srt_view(m, bus)
        for ext in ("h", "c", "csv", "md"):
            files[f"ftt/{bus.name}_srt.{ext}"] = render(f"srt.{ext}.j2", srt=view)
    return files
