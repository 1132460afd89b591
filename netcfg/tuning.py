"""Identifiers and offsets that make a CAN or CAN FD bus schedulable with the most slack: the search `netcfg tune`
(netcfg.commands.tune) runs, and the tuned spec it writes.

Identifiers: Audsley's optimal priority assignment (Audsley 1991; shown to be optimal for CAN's revised
response-time analysis by Davis and Burns 2009, "Robust priority assignment for messages on Controller Area
Network (CAN)", Real-Time Systems 43(2)). From the lowest priority up, each level takes a message that meets its
deadline with every message still unassigned above it; the response time of a message depends only on which
messages are above and below it, not on their order, so if any assignment exists this finds one. The levels are the
identifiers the bus's free messages already use (so the set of identifiers does not change), plus the pinned ones.
Among the messages that fit a level, the plain variant takes the one with the longest deadline; the robust variant
(Davis and Burns 2009, RPA) takes the one that tolerates the most error frames at that level, which maximises the
number of errors the whole bus tolerates.

Offsets: then, per sender, the periodic messages it releases from its own clock are spread over their hyperperiod,
each placed where its releases are farthest from the releases already placed (the heuristic of Grenier, Havet and
Navet 2008, "Pushing the limits of CAN"), and the result is kept only when, by the offset-aware analysis
(netcfg.timing.can_offsets), it shortens some message's bound and lengthens none.

What changes: nothing on a bus where nothing is judged (no message has a deadline); on a bus whose messages all
meet their deadlines the identifiers stay (any other order lengthens some bound; `--robust` reorders them anyway,
for the error frames survived), so tuning an accepted spec lengthens no bound. What is kept: every message's
producer, size, period, deadline and jitter; identifiers pinned with `tune: {id: fixed}`, offsets pinned with
`tune: {offset: fixed}`; a node's `id_range`; every bus whose identifiers are not free priorities
(Protocol.identifiers_fixed says why: CANopen, FTT-CAN, Ethernet). CAN and CAN FD buses are re-identified alike:
they arbitrate the same way, their frame times come from the bus's frame timing.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from math import gcd, lcm
from pathlib import Path
from typing import Any

import numpy as np

from netcfg import model, protocols
from netcfg.analyze import analysis_jitter
from netcfg.bus_analysis import error_model
from netcfg.diagnostics import Collector
from netcfg.importers import ImportOptions
from netcfg.links.arbitration import frame_priority, rta_frames
from netcfg.protocols import release_offsets
from netcfg.spec.schema import Spec
from netcfg.timing import can_errors, can_offsets, can_rta, clocks, flows, load
from netcfg.timing.can_errors import ErrorModel
from netcfg.timing.frames import bits_to_ns

MAX_ERRORS = 64
MAX_STEPS = 20_000


@dataclass
class Item:
    """A message as the search sees it."""

    name: str
    c_ns: int
    t_ns: int  # can_rta.ONE_SHOT for an on-demand message
    j_ns: int
    d_ns: int | None
    extended: bool
    id: int
    producer: str
    pinned: bool
    id_range: tuple[int, int] | None
    remote: bool = False  # a remote frame: pinned (an actuator profile's), one level below its identifier's data frame


@dataclass
class BusPlan:
    bus: str
    ids: dict[str, int] = field(default_factory=dict)  # message -> new identifier
    offsets: dict[str, int] = field(default_factory=dict)  # message -> new offset (ns)
    errors_tolerated: int | None = None  # robust variant: error frames every message survives
    notes: list[str] = field(default_factory=list)


class NoAssignment(Exception):
    """No identifier assignment meets every deadline; the message says where the search stopped."""


def response_time(
    item: Item,
    blocking: int,
    hp_c: np.ndarray,
    hp_t: np.ndarray,
    hp_j: np.ndarray,
    tau: int,
    extra: int = 0,
    ppm: int = 0,
) -> int | None:
    """Davis et al. 2007 (eqs. 10-14) for one message above `blocking` and below the hp arrays, with `extra` ns of
    error recovery added to the busy period and every queuing delay, and senders' clocks within +-ppm as
    can_rta counts them. None: unbounded or too long to follow."""
    periodic = hp_t < can_rta.ONE_SHOT
    load_ = float((hp_c[periodic] / hp_t[periodic]).sum()) + (
        item.c_ns / item.t_ns if item.t_ns < can_rta.ONE_SHOT else 0
    )
    if load_ * clocks.PPM / (clocks.PPM - ppm) >= 1.0:
        return None

    def local(x: int) -> int:
        return clocks.longest_local(x, ppm)

    def demand(x: int) -> int:
        return int(((-(-clocks.longest_local(x + hp_j, ppm) // hp_t)) * hp_c).sum()) if hp_c.size else 0

    base = blocking + extra
    busy, steps = base + item.c_ns + int(hp_c.sum()), 0
    while True:
        nxt = base + demand(busy) + -(-local(busy + item.j_ns) // item.t_ns) * item.c_ns
        steps += 1
        if nxt <= busy:
            break
        if steps > MAX_STEPS:
            return None
        busy = nxt
    worst, w = 0, 0
    for q in range(max(1, -(-local(busy + item.j_ns) // item.t_ns))):
        w = max(w, base + q * item.c_ns)
        while True:
            nxt = base + q * item.c_ns + demand(w + tau)
            steps += 1
            if nxt <= w:
                break
            if steps > MAX_STEPS:
                return None
            w = nxt
        worst = max(worst, item.j_ns + w - clocks.shortest_real(q * item.t_ns, ppm) + item.c_ns)
    return worst


def meets(item: Item, r: int | None) -> bool:
    return r is not None and (item.d_ns is None or r <= item.d_ns)


def audsley(
    items: Sequence[Item], tau: int, robust: bool = False, ppm: int = 0
) -> tuple[dict[str, int], int | None]:
    """-> (message -> identifier, error frames tolerated by all (robust) or None). Raises NoAssignment."""
    # a level per identifier, and one below it for a remote frame of that identifier (frame_priority: the RTR bit)
    levels = sorted({(frame_priority(it.id, it.extended, it.remote), it.id, it.extended, it.remote) for it in items})
    pinned_at = {(it.id, it.extended, it.remote): it for it in items if it.pinned}
    c = np.array([it.c_ns for it in items], dtype=np.int64)
    t = np.array([it.t_ns for it in items], dtype=np.int64)
    j = np.array([it.j_ns for it in items], dtype=np.int64)
    index = {it.name: i for i, it in enumerate(items)}
    waiting = np.ones(len(items), dtype=bool)
    # a free message tried at a level: longest deadline (or period) first, as deadline-monotonic would place it
    free = sorted((it for it in items if not it.pinned), key=lambda it: (-(it.d_ns or it.t_ns), -it.t_ns, it.name))
    blocking = 0
    out: dict[str, int] = {}
    tolerated: int | None = None

    def fits(it: Item, extra: int = 0) -> int | None:
        mask = waiting.copy()
        mask[index[it.name]] = False
        return response_time(it, blocking, c[mask], t[mask], j[mask], tau, extra, ppm)

    def errors_survived(it: Item) -> int:
        mask = waiting.copy()
        recovery = can_errors.ERROR_FRAME_BITS * tau + int(max(c[mask].max(initial=0), it.c_ns))
        lo, hi = 0, MAX_ERRORS
        while lo < hi:  # the most error frames (each with its retransmission) it survives
            mid = (lo + hi + 1) // 2
            if meets(it, fits(it, mid * recovery)):
                lo = mid
            else:
                hi = mid - 1
        return lo

    for _, ident, extended, remote in reversed(levels):
        chosen: Item | None = None
        if (ident, extended, remote) in pinned_at:
            it = pinned_at[(ident, extended, remote)]
            if not meets(it, fits(it)):
                raise NoAssignment(_refusal(it, ident, fits(it), pinned=True))
            chosen = it
        else:
            tried: list[tuple[Item, int | None]] = []
            best = -1
            for it in free:
                if not waiting[index[it.name]] or it.extended != extended:
                    continue
                if it.id_range is not None and not it.id_range[0] <= ident <= it.id_range[1]:
                    continue
                r = fits(it)
                tried.append((it, r))
                if not meets(it, r):
                    continue
                if not robust:
                    chosen = it
                    break
                survived = errors_survived(it)
                if survived > best:
                    chosen, best = it, survived
            if chosen is None:
                raise NoAssignment(_none_fits(ident, tried, int(waiting.sum())))
            if robust:
                tolerated = best if tolerated is None else min(tolerated, best)
        if robust and chosen.pinned:
            survived = errors_survived(chosen)
            tolerated = survived if tolerated is None else min(tolerated, survived)
        out[chosen.name] = ident
        waiting[index[chosen.name]] = False
        blocking = max(blocking, chosen.c_ns)
    return out, tolerated


def _refusal(it: Item, ident: int, r: int | None, pinned: bool) -> str:
    took = "no bounded response" if r is None else f"{r / 1000:g} us"
    return (
        f"'{it.name}' is pinned to identifier 0x{ident:03X} (tune: {{id: fixed}}) and misses its deadline of "
        f"{(it.d_ns or 0) / 1000:g} us there ({took}) whatever the order above it; unpin it or give it a smaller id"
    )


def _none_fits(ident: int, tried: list[tuple[Item, int | None]], above: int) -> str:
    if not tried:
        return (
            f"no message may take identifier 0x{ident:03X}: the id_range of every remaining sender excludes it; "
            "widen a node's id_range"
        )
    more = ", ..." if len(tried) > 4 else ""
    shown = ", ".join(
        f"'{it.name}' {('unbounded' if r is None else f'{r / 1000:g} us')} > {(it.d_ns or 0) / 1000:g} us"
        for it, r in tried[:4]
    )
    return (
        f"no identifier assignment meets every deadline: at identifier 0x{ident:03X}, with {above - 1} messages "
        f"still above it, none of the remaining messages meets its deadline ({shown}{more}); "
        "lower the load (slower periods, shorter payloads), relax a deadline or raise the bit rate"
    )


# -- offsets ----------------------------------------------------------------------------------------------------
def spread_offsets(periods: dict[str, int], fixed: dict[str, int], step_ns: int = 1000) -> dict[str, int] | None:
    """Offsets for one sender's messages (name -> period): each, shortest period first, where its releases are
    farthest from those already placed over the hyperperiod. `fixed` offsets are placed first and kept.
    None when the hyperperiod unrolls into more than can_offsets.MAX_JOBS releases."""
    every = {**periods, **{n: periods.get(n, 0) for n in fixed}}
    hyper = lcm(*every.values())
    if sum(hyper // p for p in every.values()) > can_offsets.MAX_JOBS:
        return None
    placed = np.array(
        sorted((o + k * periods[n]) % hyper for n, o in fixed.items() for k in range(hyper // periods[n])),
        dtype=np.int64,
    )
    out = {}
    for name in sorted((n for n in periods if n not in fixed), key=lambda n: (periods[n], n)):
        period = periods[name]
        step = round_step(max(gcd(*periods.values()) // (2 * len(periods)), period // 256), step_ns)
        cands = np.arange(0, period, step, dtype=np.int64)
        if placed.size == 0:
            best = 0
        else:
            rel = (cands[:, None] + np.arange(hyper // period, dtype=np.int64)[None, :] * period) % hyper
            pos = np.searchsorted(placed, rel)
            after = placed[pos % placed.size] + np.where(pos == placed.size, hyper, 0)
            before = placed[(pos - 1) % placed.size] - np.where(pos == 0, hyper, 0)
            gap = np.minimum(after - rel, rel - before).min(axis=1)
            best = int(cands[int(np.argmax(gap))])
        out[name] = best
        placed = np.sort(np.concatenate([placed, (best + np.arange(hyper // period) * period) % hyper]))
    return out


def round_step(ns: int, least: int) -> int:
    """The largest 1, 2 or 5 times `least` times a power of ten not above ns (offsets a person reads easily)."""
    best, scale = least, least
    while scale <= ns:
        best = max([best] + [k * scale for k in (1, 2, 5) if k * scale <= ns])
        scale *= 10
    return best


def bounds(
    frames: list[can_rta.CanFrame],
    tau: int,
    offsets: dict[str, tuple[str, int]],
    ppm: int = 0,
    errors: ErrorModel | None = None,
) -> dict[str, int | None]:
    """Every message's bound by the offset-aware analysis check uses (None: unbounded)."""
    return {name: r.wcrt_ns for name, r in can_offsets.analyse(frames, tau, offsets, ppm, errors).items()}


def no_longer(after: dict[str, int | None], before: dict[str, int | None]) -> bool:
    """No bound in `after` is longer than in `before` (an unbounded one only where it was unbounded already)."""
    return all(b is None or (a is not None and a <= b) for a, b in ((after[n], before[n]) for n in before))


# -- the whole spec ---------------------------------------------------------------------------------------------
def plan_bus(
    m: model.Model, spec: Spec, bus: model.Bus, robust: bool, rows: list[dict[str, Any]] | None = None
) -> BusPlan:
    """What tune changes on one bus; `rows` are check's messages of the bus before (their verdicts). Nothing
    changes where nothing is judged (no message has a deadline), and a bus whose messages all meet their deadlines
    keeps its identifiers (unless robust): reordering them lengthens some bound, and tune makes none longer there."""
    plan = BusPlan(bus.name)
    if (why := protocols.of(bus).identifiers_fixed(bus)) is not None:
        plan.notes.append(f"bus '{bus.name}' ({bus.protocol}): identifiers and offsets kept: {why}")
        return plan
    verdicts = [row["schedulable"] for row in rows or ()]
    if rows is not None and all(v is None for v in verdicts):
        plan.notes.append(
            f"bus '{bus.name}': nothing analysed (none of its {len(bus.messages)} messages has a deadline, a period "
            "or a minimum inter-arrival time), so nothing changed; give them periods (a DBC's GenMsgCycleTime, or "
            "--default-period T)"
        )
        return plan
    pins = {msg.name: msg.tune for msg in spec.messages if msg.tune is not None}
    ranges = {n.name: n.id_range for n in spec.nodes}
    timings, _, _ = load.can_bus_load(bus)
    tau = bits_to_ns(1, bus.bitrate)
    acc = analysis_jitter(m)  # the release jitter check uses, a sending task's spread included
    items = [
        Item(
            msg.name,
            timings[msg.name].tx_ns,
            msg.interval_ns or can_rta.ONE_SHOT,
            acc.jitter(msg),
            msg.deadline_ns,
            msg.extended,
            msg.id,
            msg.producer,
            (msg.name in pins and pins[msg.name].id == "fixed") or msg.fixed_by is not None,  # type: ignore[union-attr]
            ranges.get(msg.producer),
            msg.remote,
        )
        for msg in bus.messages
    ]
    if robust or False in verdicts:
        ids, plan.errors_tolerated = audsley(items, tau, robust, bus.clock_tolerance_ppm)
        plan.ids = {name: ident for name, ident in ids.items() if ident != m.messages[name].id}
    else:
        ids = {msg.name: msg.id for msg in bus.messages}
        plan.notes.append(
            f"bus '{bus.name}': identifiers kept (every message meets its deadline; reordering would lengthen some "
            "bound; --robust reorders them for the most error frames survived)"
        )
    # offsets, on the new identifiers
    new = [replace(f, id=ids[f.name]) for f in rta_frames(bus.messages, timings, acc)]  # each keeps its RTR bit
    before = release_offsets(m, bus)
    after = dict(before)
    by_node: dict[str, dict[str, int]] = {}
    fixed: dict[str, dict[str, int]] = {}
    for msg in bus.messages:
        free = msg.kind == "periodic" and msg.period_ns and msg.period_ns == msg.interval_ns
        if not free or flows.sending_tasks(m, msg) or msg.fixed_by is not None:
            continue
        if msg.name in pins and pins[msg.name].offset == "fixed":  # type: ignore[union-attr]
            if msg.offset_ns is not None:
                fixed.setdefault(msg.producer, {})[msg.name] = msg.offset_ns
            continue
        by_node.setdefault(msg.producer, {})[msg.name] = msg.period_ns  # type: ignore[assignment]
    too_long: list[str] = []
    for node, periods in sorted(by_node.items()):
        if len(periods) + len(fixed.get(node, {})) < 2:
            continue
        chosen = spread_offsets(periods, fixed.get(node, {}))
        if chosen is None:
            too_long.append(node)
            continue
        after.update({name: (node, o) for name, o in chosen.items()})
    if too_long:
        more = ", ..." if len(too_long) > 5 else ""
        plan.notes.append(
            f"offsets of {len(too_long)} node(s) kept ({', '.join(too_long[:5])}{more}): their "
            f"periods' hyperperiod unrolls into more than {can_offsets.MAX_JOBS} releases"
        )
    if after != before:
        ppm, errors = bus.clock_tolerance_ppm, error_model(bus)
        was, now = bounds(new, tau, before, ppm, errors), bounds(new, tau, after, ppm, errors)
        if now != was and no_longer(now, was):
            plan.offsets = {name: o for name, (_, o) in after.items() if before.get(name, (None, None))[1] != o}
        else:
            plan.notes.append(f"bus '{bus.name}': offsets kept (spreading them would shorten no bound or lengthen one)")
    return plan


def plan(
    m: model.Model, spec: Spec, robust: bool = False, report: dict[str, Any] | None = None
) -> list[BusPlan]:
    """Every bus's plan; `report` is check's analysis of the spec as it is (its verdicts decide what may change)."""
    rows = {b["name"]: b["messages"] for b in report["buses"]} if report is not None else {}
    return [plan_bus(m, spec, bus, robust, rows.get(bus.name)) for bus in m.buses.values()]


def summary_rows(report: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """bus -> {load, worst slack (us), misses} from a check report."""
    out = {}
    for b in report["buses"]:
        slack = [x["slack_us"] for x in b["messages"] if x.get("slack_us") is not None]
        unbounded = any(x["schedulable"] is False and x["wcrt_us"] is None for x in b["messages"])
        out[b["name"]] = {
            "load": b["utilization"],
            "worst_slack_us": None if unbounded else min(slack, default=None),
            "misses": sum(1 for x in b["messages"] if x["schedulable"] is False),
        }
    return out


# -- the tuned spec and the result -------------------------------------------------------------------------------------
def _id_text(ident: int, extended: bool) -> str:
    return f"0x{ident:08X}" if extended else f"0x{ident:03X}"


def _duration_text(ns: int) -> str:
    for unit, scale in (("ms", 1_000_000), ("us", 1_000)):
        if ns % scale == 0:
            return f"{ns // scale} {unit}"
    return f"{ns} ns"


def _read_dbc(path: Path, diags: Collector, options: ImportOptions) -> tuple[Spec | None, model.Model | None]:
    """The spec `netcfg import dbc` would write for this DBC (with check's DBC options), and its model."""
    from pydantic import ValidationError

    from netcfg.check import load_dbc
    from netcfg.importers.dbc import import_dbc

    imported = import_dbc(path, options, Collector())
    if imported is None:
        return None, load_dbc(path, diags, options)
    try:
        spec = Spec.model_validate(imported[0])
    except ValidationError:
        spec = None
    return spec, load_dbc(path, diags, options)


def _dbc_ids(m: model.Model, plans: list[BusPlan]) -> dict[int, int]:
    """Old -> new identifier as a DBC writes it (bit 31 set on extended frames)."""
    out = {}
    for p in plans:
        for name, ident in p.ids.items():
            flag = 0x80000000 if m.messages[name].extended else 0
            out[m.messages[name].id | flag] = ident | flag
    return out


# every DBC statement that names a message by its identifier (Vector's DBC format: BO_, BO_TX_BU_, CM_, BA_, VAL_,
# SIG_VALTYPE_, SIG_GROUP_, SG_MUL_VAL_, EV_DATA_)
_DBC_ID = re.compile(
    r'^(\s*(?:BO_|BO_TX_BU_|VAL_|SG_MUL_VAL_|SIG_VALTYPE_|SIG_GROUP_|EV_DATA_|CM_\s+(?:BO_|SG_)|BA_\s+"[^"]*"\s+(?:BO_|SG_))\s+)(\d+)',
    re.M,
)


def edit_dbc_ids(text: str, ids: dict[int, int]) -> str:
    """Renumber messages in a DBC's own text (all at once, so swapped identifiers do not collide)."""
    return _DBC_ID.sub(lambda mt: mt.group(1) + str(ids.get(int(mt.group(2)), int(mt.group(2)))), text)


def load_source(
    source: Path, diags: Collector, options: ImportOptions
) -> tuple[Spec | None, model.Model | None]:
    """The spec and model tune starts from: a spec as check reads it, a DBC as `netcfg import dbc` would write it
    (with check's DBC options). Either is None (with errors in diags) when it is not usable. OSError propagates."""
    from netcfg.resolve import resolve
    from netcfg.spec.load import read_spec

    if source.suffix.lower() == ".dbc":
        return _read_dbc(source, diags, options)
    spec, smap = read_spec(source, diags)
    return spec, resolve(spec, smap, diags, source.parent) if spec is not None else None


def tuned_source(source: Path, m: model.Model, plans: list[BusPlan]) -> bytes:
    """The source's own text with the plans' identifiers and offsets written in (the rest as it was). A DBC is
    renumbered only: its plans' offsets are dropped, with a note saying so."""
    from netcfg.spec.edit import set_message_values

    is_dbc = source.suffix.lower() == ".dbc"
    values: dict[str, dict[str, str]] = {}
    for p in plans:
        for name, ident in p.ids.items():
            values.setdefault(name, {})["id"] = _id_text(ident, m.messages[name].extended)
        for name, ns in p.offsets.items():
            values.setdefault(name, {})["offset"] = _duration_text(ns)
        if is_dbc and p.offsets:  # the DBC is edited in its own text, where only identifiers are renumbered
            p.offsets = {}
            p.notes.append("offsets not written: in a DBC tune changes identifiers only")
    if is_dbc:
        return edit_dbc_ids(source.read_bytes().decode("latin-1"), _dbc_ids(m, plans)).encode("latin-1")
    return set_message_values(source.read_text(encoding="utf-8"), values).encode("utf-8")


def _us(ns: int | None) -> float | None:
    return None if ns is None else ns / 1000


def result_document(
    m: model.Model, plans: list[BusPlan], before: dict[str, Any], after: dict[str, Any], output: Path
) -> dict[str, Any]:
    was, now = summary_rows(before), summary_rows(after)
    return {
        "output": str(output),
        "ok_before": before["ok"],
        "ok": after["ok"],
        "buses": [
            {
                "name": p.bus,
                "before": was.get(p.bus),
                "after": now.get(p.bus),
                "ids": [{"name": n, "from": m.messages[n].id, "to": i} for n, i in sorted(p.ids.items())],
                "offsets": [
                    {
                        "name": n,
                        "from_us": _us(m.messages[n].offset_ns),
                        "to_us": o / 1000,
                    }
                    for n, o in sorted(p.offsets.items())
                ],
                "errors_tolerated": p.errors_tolerated,
                "notes": p.notes,
            }
            for p in plans
        ],
    }


def result_text(doc: dict[str, Any]) -> str:
    lines = [
        f"wrote {doc['output']} (check: {'accepted' if doc['ok'] else 'refused'}; "
        f"the original: {'accepted' if doc['ok_before'] else 'refused'})"
    ]
    for b in doc["buses"]:
        lines.append(f"\nbus {b['name']}:")
        w, n = b["before"], b["after"]
        if w and n:

            def slack(x: float | None) -> str:
                return "unbounded" if x is None else f"{x:g} us"

            lines.append(f"  {'':22} {'before':>14} {'after':>14}")
            lines.append(f"  {'load':22} {w['load']:>14.1%} {n['load']:>14.1%}")
            lines.append(f"  {'worst slack':22} {slack(w['worst_slack_us']):>14} {slack(n['worst_slack_us']):>14}")
            lines.append(f"  {'deadline misses':22} {w['misses']:>14} {n['misses']:>14}")
        for x in b["ids"]:
            lines.append(f"  id      {x['name']:20} 0x{x['from']:03X} -> 0x{x['to']:03X}")
        for x in b["offsets"]:
            was = "none" if x["from_us"] is None else f"{x['from_us']:g} us"
            lines.append(f"  offset  {x['name']:20} {was} -> {x['to_us']:g} us")
        if b["errors_tolerated"] is not None:
            lines.append(f"  every message survives {b['errors_tolerated']} error frames in its busy period (robust)")
        if not b["ids"] and not b["offsets"]:
            lines.append("  nothing changed")
        lines += [f"  note: {t}" for t in b["notes"]]
    return "\n".join(lines)
