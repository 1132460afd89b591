"""runtime.json's section of an FTT-CAN bus (`ftt`): the master's trigger message, the SRT and the EC-schedules of
one macro-cycle, as the analysis built them (model.Bus.ftt_schedule, netcfg.timing.ftt); nothing here recomputes
timing. The simulator's master (netcfg.protocols.ftt.sim) and a live FTT master run from it."""

from __future__ import annotations

from typing import Any

from netcfg import model
from netcfg.timing import ftt


def runtime_section(b: model.Bus) -> dict[str, Any]:
    assert b.ftt is not None  # an FTT-CAN bus: the resolver filled its section
    sched = b.ftt_schedule
    assert sched is not None  # the analysis built it; a spec whose macro-cycle is too long never gets here
    return {
        "ec_ns": b.ftt.ec_ns,
        "tm_size": b.ftt.tm_size,
        "tm_id": b.ftt.tm_id,
        "tm_ns": sched.tm_ns,
        "lsw_ns": sched.lsw_ns,  # the default (EC - TM) filled in, as the analysis used it
        "master": b.ftt.master,
        "macro_cycle_ec": sched.macro_cycle,
        "windows": "sync-first" if sched.sync_first else "async-first",
        "srt": [
            {
                "ftt_id": e.ftt_id,
                "name": e.name,
                "kind": e.kind,
                "targets": list(e.targets),
                "period_ec": e.period_ec,
                "fastest_period_ec": e.fastest_period_ec,
                "init_ec": e.init_ec,
            }
            for e in sched.entries
        ],
        "schedule": [
            {
                "ec": s.index,
                "ids": list(s.ids),
                "messages": list(s.messages),
                "triggers": list(s.triggers),
                "mask": ftt.ec_schedule_mask(s),
                "sync_ns": s.sync_ns,
                "async_ns": s.async_ns,
                **({"allowance_ns": s.allowance_ns} if s.allowance_ns else {}),
            }
            for s in sched.slots
        ],
    }
