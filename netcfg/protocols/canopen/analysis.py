"""The analysis of a CANopen bus's SYNC cycle (CiA 301; seed 000): the synchronous TPDOs of each cycle against
the synchronous window, the master's read window and the communication cycle, the master's loop, and event timers.
The arbitration analysis of the same bus (netcfg.links.arbitration) bounds every frame, SYNC included."""

from __future__ import annotations

from typing import Any

from netcfg import model
from netcfg.bus_analysis import Analysis, error_model, us
from netcfg.diagnostics import Collector
from netcfg.spec.units import format_ns
from netcfg.timing import canopen_sync, flows


def analyze_sync(
    m: model.Model, bus: model.Bus, frame_ns: dict[str, tuple[int, int]], diags: Collector, acc: Analysis
) -> dict[str, Any]:
    """The bus's SYNC cycles: each cycle's synchronous TPDOs against its windows, the master's loop, and what the
    flows need of them (acc.canopen)."""
    co = bus.canopen
    assert co is not None
    # one release model: each message's jitter as the response-time analysis takes it (rta_frames), each TPDO's
    # queueing delay after SYNC as the flows take it
    delays = {msg.name: m.nodes[msg.producer].tx_delay_ns for msg in bus.messages}
    cycles = canopen_sync.analyse(
        bus,
        {name: worst for name, (_, worst) in frame_ns.items()},
        {msg.name: acc.jitter(msg) for msg in bus.messages},
        delays,
        error_model(bus),
    )
    sync_msg = next(msg for msg in bus.messages if msg.implicit == "SYNC")
    bus_msgs = {msg.name: msg for msg in bus.messages}
    loop = canopen_sync.master_loop(m, bus)
    acc.canopen[bus.name] = flows.SyncTimes(
        period_ns=co.sync_period_ns,
        sync=acc.chained[sync_msg.name],
        every=canopen_sync.sync_transmissions(bus),
        frame_ns={name: nominal for name, (nominal, _) in frame_ns.items()},
        completion_ns=[c.completion_ns for c in cycles],
        master=loop,
        release_delay_ns=delays,
        ahead_of_sync=frozenset(
            msg.name
            for msg in bus.messages
            if msg.producer == co.sync_producer and msg is not sync_msg and m.nodes[msg.producer].tx_queue.fifo
        ),
        every_nth_write=frozenset(
            msg.name
            for msg in bus.messages
            if msg.pdo is not None
            and msg.pdo.kind == "rpdo"
            and msg.producer == co.sync_producer
            and msg.kind == "periodic"
            and (msg.period_ns or 0) > co.sync_period_ns
        ),
    )
    check_master_loop(m, bus, loop, diags)
    check_event_timer_periods(m, bus, acc, diags)
    rows = []
    for c in cycles:
        rows.append(
            {
                "cycle": c.index,
                "tpdos": len(c.tpdos),
                "completion_us": us(c.completion_ns),
                "limit_us": us(c.limit_ns),
                "slack_us": None if c.completion_ns is None else us(c.limit_ns - c.completion_ns),
                "fits": c.completion_ns is not None and c.completion_ns <= c.limit_ns,
                "blocking_us": us(c.blocking_ns),
                **({"error_us": us(c.error_ns)} if bus.errors is not None else {}),
                "sync_us": us(c.sync_ns),
                "tpdos_us": us(c.tpdos_ns),
                **({"tx_delay_us": us(c.delay_ns)} if c.delay_ns else {}),
            }
        )
    for c in cycles:
        if c.completion_ns is None or c.completion_ns > c.limit_ns:
            how = (
                "never: the other traffic alone fills the bus"
                if c.completion_ns is None
                else f"{c.completion_ns / 1000:g} us after SYNC, {(c.completion_ns - c.limit_ns) / 1000:g} us too late"
            )
            # a drive's tx_delay that alone takes more than the overshoot is what to change
            late_by = None if c.completion_ns is None else c.completion_ns - c.limit_ns
            slow = [n for n in c.tpdos if late_by is not None and delays[n] == c.delay_ns >= late_by]
            waits = (
                f" ({bus_msgs[slow[0]].producer} queues {slow[0]} its tx_delay of "
                f"{format_ns(c.delay_ns)} after SYNC's reception)"
                if slow
                else ""
            )
            diags.add(
                "sync-cycle",
                f"SYNC cycle {c.index} of bus '{bus.name}': the last of its {len(c.tpdos)} "
                f"synchronous TPDOs completes {how} for {c.limit_name} ({c.limit_ns / 1000:g} us){waits}; lengthen "
                "the cycle, move TPDOs to other cycles (transmission type n > 1)"
                + (", shorten that tx_delay" if slow else "")
                + " or raise the bit rate",
                m.source.at((*bus.path, "canopen")),
            )
            break
    finished = [c.completion_ns for c in cycles if c.completion_ns is not None]
    worst = max(finished) if len(finished) == len(cycles) and finished else None
    # the worst cycle held against each limit the bus has (canopen_sync takes the tightest of them per cycle)
    limits = [
        {
            "name": name,
            "limit_us": us(limit),
            "fits": worst is not None and worst <= limit,
            "margin_us": None if worst is None else us(abs(limit - worst)),
        }
        for name, limit in (
            ("synchronous window (0x1007)", co.sync_window_ns),
            ("master's read window", co.read_window_ns),
            ("communication cycle (0x1006)", co.sync_period_ns),
        )
        if limit is not None
    ]
    master: dict[str, Any] = {
        "node": loop.node,
        "tasks": list(loop.tasks),
        "offset_us": us(loop.offset_ns),
        "bcet_us": us(loop.bcet_ns),
        "wcet_us": us(loop.wcet_ns),
        "jitter_us": us(loop.jitter_ns),
        # the latest its RxPDOs are queued after SYNC (None: right before the next SYNC, the paper's loop)
        "writes_done_us": None if loop.offset_ns is None else us(loop.offset_ns + loop.jitter_ns + loop.wcet_ns),
    }
    return {
        "master": master,
        "period_us": us(co.sync_period_ns),
        "window_us": us(co.sync_window_ns),
        "read_window_us": us(co.read_window_ns),
        "producer": co.sync_producer,
        "cycles_analysed": len(cycles),
        "worst_completion_us": us(worst),
        "limits": limits,
        "max_tpdos_per_cycle": max((len(c.tpdos) for c in cycles), default=0),
        "cycles": rows[:64],
    }


def check_event_timer_periods(m: model.Model, bus: model.Bus, acc: Analysis, diags: Collector) -> None:
    """An event-driven TPDO taken as periodic (cia301.tpdo_timing: application events every period, which keeps its
    event timer from running out) holds only while a late event still comes before the timer: period + release
    jitter below it. Resolve knew the spec's jitter; the sending task's spread is known here."""
    for msg in bus.messages:
        p = msg.pdo
        if p is None or p.kind != "tpdo" or p.transmission < 254 or not p.event_timer_ms or msg.kind != "periodic":
            continue
        timer, period, jitter = p.event_timer_ms * 1_000_000, msg.period_ns or 0, acc.jitter(msg)
        if period >= timer or period + jitter < timer:
            continue  # the timer alone (on-demand), or the timer is never reached
        diags.add(
            "event-timer",
            f"TPDO '{msg.name}' is written every {format_ns(period)} with up to {format_ns(jitter)} release jitter "
            f"(its sending task's response-time spread), so its {format_ns(timer)} event timer can run out before a "
            "late write, and the two sends come an inhibit time apart: lengthen the event timer beyond "
            f"{format_ns(period + jitter)}, or take the period out and let the inhibit time bound it",
            m.source.at((*msg.path, "pdo", "event_timer")),
        )


def check_master_loop(m: model.Model, bus: model.Bus, loop: canopen_sync.MasterLoop, diags: Collector) -> None:
    """The master's computation must start on complete samples and end before its next SYNC is due."""
    co = bus.canopen
    assert co is not None
    if loop.offset_ns is None:
        return
    where = m.source.at(m.task(loop.tasks[0]).path)
    names = ", ".join(f"'{t}'" for t in loop.tasks)
    if len(loop.tasks) > 1:
        diags.add(
            "master-cycle",
            f"the master has {len(loop.tasks)} SYNC tasks on bus '{bus.name}' ({names}); its loop computes once per "
            "cycle and then writes its RxPDOs: give it one SYNC task per CANopen bus",
            m.source.at(m.task(loop.tasks[1]).path),
        )
        return
    # the master collects for its read window, else the synchronous window, else the whole period (as it runs)
    window = co.read_window_ns or co.sync_window_ns or co.sync_period_ns
    if loop.offset_ns < window:
        diags.add(
            "master-cycle",
            f"the master's SYNC task {names} starts {format_ns(loop.offset_ns)} after SYNC, before the "
            f"{format_ns(window)} read window of bus '{bus.name}' ends: the master computes on the samples it "
            "collected; give it an offset of at least the read window, or a shorter read_window",
            where,
        )
    end = loop.offset_ns + loop.jitter_ns + loop.wcet_ns
    if end > co.sync_period_ns:
        diags.add(
            "master-cycle",
            f"the master's SYNC task {names} on bus '{bus.name}' ends up to {format_ns(end)} after SYNC (offset "
            f"{format_ns(loop.offset_ns)} + master_jitter {format_ns(loop.jitter_ns)} + WCET "
            f"{format_ns(loop.wcet_ns)}), after the next SYNC is due ({format_ns(co.sync_period_ns)}): the master "
            "cannot keep its period; shorten its offset or WCET, or lengthen the SYNC period",
            where,
        )
