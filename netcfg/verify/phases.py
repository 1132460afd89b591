"""The phases of a CANopen master's log: set-up, the cyclic phase, shut-down.

A log of `netcfg run` (or of any master) holds more than the cycle the analysis bounds: before it the SDO set-up
of every node, NMT start and the CiA 402 state machine; after it the safe stop and a silent bus. The analysis speaks
of the cyclic phase only, from the first SYNC to one period after the last: verify judges that, and reports what
came before and after as phases of their own (frames, SDO transfers, NMT commands, boot-ups), not as load peaks
and missing periods. A log with no NMT command (the cycle recorded alone, a simulator's log) or no SYNC of a
CANopen bus of the system (a plain CAN bus) is all one cyclic phase.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from netcfg.runtime import RuntimeConfig
from netcfg.verify.frames import ERROR, EXTENDED, Batch


@dataclass
class Phase:
    """Frames of a phase that is not judged: how many, when, and how many of them were SDO. What its CANopen
    services said (NMT commands, boot-ups) is the checker's ServiceLog's, taken for the phase's span."""

    frames: int = 0
    first_us: int | None = None
    last_us: int | None = None
    sdo_frames: int = 0

    def take(self, batch: Batch, sdo_frames: int) -> None:
        if not len(batch):
            return
        self.frames += len(batch)
        self.first_us = int(batch.t_us[0]) if self.first_us is None else self.first_us
        self.last_us = int(batch.t_us[-1])
        self.sdo_frames += sdo_frames

    def report(self, origin_us: int, services: list[dict[str, Any]]) -> dict[str, Any]:
        """`services`: the buses' CANopen service reports (times from origin_us)."""
        lo = None if self.first_us is None else self.first_us - origin_us
        hi = None if self.last_us is None else self.last_us - origin_us

        def inside(items: list[dict[str, Any]]) -> list[dict[str, Any]]:
            return [x for x in items if lo is not None and hi is not None and lo <= x["time_us"] <= hi]

        return {
            "frames": self.frames,
            "from_us": lo,
            "to_us": hi,
            "sdo_frames": self.sdo_frames,
            "nmt_commands": [x for co in services for x in inside(co["nmt_commands"])],
            "boot_ups": [x for co in services for x in inside(co["nmt_states"]) if x["state"] == "boot-up"],
        }


def sync_ids(cfg: RuntimeConfig) -> dict[int, int]:
    """SYNC identifier -> the SYNC period (us) of each CANopen bus of the system."""
    out = {}
    for bus in cfg.buses:
        if bus.canopen is None:
            continue
        sync = next((m for m in cfg.messages_on(bus.name) if m.implicit == "SYNC"), None)
        if sync is not None:
            out[sync.id] = bus.canopen.sync_period_ns // 1000
    return out


def cyclic_span(cfg: RuntimeConfig, batches: Iterable[Batch]) -> tuple[int, int] | None:
    """(first SYNC, last SYNC + its period) in log microseconds, for a log in which a master starts its nodes (an
    NMT command); None without one (a recording of the cycle alone, a simulator's log: all of it is judged) or
    without a SYNC of the system's."""
    syncs = sync_ids(cfg)
    if not syncs:
        return None
    first: int | None = None
    last = 0
    nmt = False
    for batch in batches:
        plain = (batch.flags & (ERROR | EXTENDED)) == 0
        nmt = nmt or bool((plain & (batch.can_id == 0)).any())
        hit = np.isin(batch.can_id, list(syncs)) & plain
        if hit.any():
            idx = np.flatnonzero(hit)
            first = int(batch.t_us[idx[0]]) if first is None else first
            last = max(last, int(batch.t_us[idx[-1]]) + max(syncs[int(batch.can_id[idx[-1]])], 1))
    return None if first is None or not nmt else (first, last)


def split(
    batches: Iterable[Batch],
    span: tuple[int, int],
    setup: Phase,
    shutdown: Phase,
    origin: list[int],
    outside: Callable[[Batch], int],
) -> Iterator[Batch]:
    """The frames of the cyclic phase, batch by batch; the others go to `outside` (which says how many were SDO) and
    are counted in set-up and shut-down.
    origin[0] gets the log's first frame time (the report counts times from it)."""
    start, end = span
    for batch in batches:
        if not len(batch):
            continue
        if not origin:
            origin.append(int(batch.t_us[0]))
        t = batch.t_us
        lo, hi = int(np.searchsorted(t, start, side="left")), int(np.searchsorted(t, end, side="right"))
        before, after = _rows(batch, 0, lo), _rows(batch, hi, len(batch))
        setup.take(before, outside(before))
        if hi > lo:
            yield _rows(batch, lo, hi)
        shutdown.take(after, outside(after))


def _rows(batch: Batch, lo: int, hi: int) -> Batch:
    return replace(
        batch,
        t_us=batch.t_us[lo:hi],
        channel=batch.channel[lo:hi],
        can_id=batch.can_id[lo:hi],
        flags=batch.flags[lo:hi],
        length=batch.length[lo:hi],
        data=batch.data[lo:hi],
    )
