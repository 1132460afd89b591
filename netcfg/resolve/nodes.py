"""The spec's nodes and their tasks: node ids, devices, heartbeats, supervision and transmit queues, and each task's
activation (period, trigger, message or SYNC) and execution times."""

from __future__ import annotations

from typing import TYPE_CHECKING

from netcfg import cia301, model, protocols
from netcfg.protocols.canopen import resolve as canopen
from netcfg.records import same_named
from netcfg.resolve.actuators import is_actuator_device
from netcfg.spec import schema
from netcfg.spec.source import Path
from netcfg.spec.suggest import did_you_mean, some_names
from netcfg.spec.units import format_ns

if TYPE_CHECKING:
    from netcfg.resolve.core import Resolver


def resolve_nodes(r: Resolver) -> None:
    ids: dict[tuple[str, int], str] = {}
    for i, n in enumerate(r.spec.nodes):
        path: Path = ("nodes", i)
        for j, bname in enumerate(n.buses):
            if bname not in r.spec_buses:
                r.err(
                    "unknown-bus",
                    f"node '{n.name}' sits on bus '{bname}', which is not defined"
                    f"{did_you_mean(bname, r.spec_buses)}; known buses: {some_names(r.spec_buses)}",
                    (*path, "buses", j),
                )
        if len(set(n.buses)) != len(n.buses):
            r.err("duplicate-name", f"node '{n.name}' lists the same bus twice", (*path, "buses"))
        on_canopen = any(
            r.protocol(r.bus_protocol(r.spec_buses[b]).name).device_nodes for b in n.buses if b in r.spec_buses
        )
        if n.node_id is not None:
            if on_canopen and n.node_id not in cia301.NODE_IDS:
                r.err("node-id", f"CANopen node ids are 1..127; '{n.name}' has {n.node_id}", (*path, "node_id"))
            elif not 0 <= n.node_id <= 255:
                r.err("node-id", f"node ids are 0..255; '{n.name}' has {n.node_id}", (*path, "node_id"))
            for bname in n.buses:
                key = (bname, n.node_id)
                if key in ids:
                    r.shared_node_ids.update((n.name, ids[key]))
                    r.err(
                        "duplicate-node-id",
                        f"node id {n.node_id} of '{n.name}' is already used by '{ids[key]}' on bus '{bname}'",
                        (*path, "node_id"),
                    )
                ids[key] = n.name
        elif on_canopen:
            r.err("node-id", f"node '{n.name}' is on a CANopen bus and needs a node_id (1..127)", path)
        device = None if is_actuator_device(n.device) else canopen.load_device(r, n, path, on_canopen)
        # a node on a misspelt bus may well be on a CANopen one: the unknown bus is the one error
        if n.heartbeat is not None and not on_canopen and all(b in r.spec_buses for b in n.buses):
            r.err(
                "wrong-section",
                "heartbeat is a CANopen service; this node is on no CANopen bus",
                (*path, "heartbeat"),
            )
        hb = r.ns(n.heartbeat, (*path, "heartbeat"), None)
        if hb is not None and (hb % 1_000_000 or hb > 65_535_000_000):
            r.err(
                "heartbeat",
                "the heartbeat time (0x1017) is whole milliseconds, at most 65535 ms",
                (*path, "heartbeat"),
            )
        hb_timeout = r.ns(n.heartbeat_timeout, (*path, "heartbeat_timeout"), None)
        if hb_timeout is not None and (
            hb is None or hb_timeout <= hb or hb_timeout % 1_000_000 or hb_timeout > 65_535_000_000
        ):
            r.err(
                "heartbeat",
                "heartbeat_timeout (the master's consumer time, 0x1016) is whole milliseconds, at most 65535 ms, "
                "and longer than the node's heartbeat producer time; give the node a 'heartbeat' first",
                (*path, "heartbeat_timeout"),
            )
            hb_timeout = None
        whole_ms = hb is not None and not hb % 1_000_000 and hb <= 65_535_000_000
        if hb and whole_ms and not canopen.device_has_heartbeat(r, device, hb, (*path, "heartbeat")):
            hb = hb_timeout = None  # reported; no heartbeat the device cannot send
        if hb and hb_timeout is None:
            # Lely dcfgen's default heartbeat_multiplier (3.0): two heartbeats may be lost; 0x1016 holds 16 bits
            hb_timeout = min(3 * hb, 65_535_000_000)
        sdo_timeout = r.ns(n.sdo_timeout, (*path, "sdo_timeout"), None)
        if sdo_timeout is not None and not 0 < sdo_timeout <= 60_000_000_000:
            r.err(
                "sdo-timeout",
                "sdo_timeout (how long the master waits for each SDO answer) is more than 0 and at most 60 s",
                (*path, "sdo_timeout"),
            )
            sdo_timeout = None
        if sdo_timeout is None:
            sdo_timeout = 500_000_000  # what `netcfg run` waited before the key existed
        if n.ip is not None and any(int(p) > 255 for p in n.ip.split(".")):
            r.err("ip", f"'{n.ip}' is not an IPv4 address", (*path, "ip"))
        ec = r.ec_of(n.buses)
        tasks = {}
        for j, t in enumerate(n.tasks):
            tasks[t.name] = resolve_task(r, n.name, t, (*path, "tasks", j), ec)
        r.model.nodes[n.name] = model.Node(
            **same_named(n, "description name node_id role on_loss on_emcy on_reboot sdo_retries safe_stop ip"),
            buses=tuple(n.buses),
            device=device,
            heartbeat_ns=hb or None,
            heartbeat_timeout_ns=hb_timeout,
            sdo_timeout_ns=sdo_timeout,
            tasks=tasks,
            path=path,
            tx_delay_ns=r.ns(n.tx_delay, (*path, "tx_delay"), None) or 0,
            rx_delay_ns=r.ns(n.rx_delay, (*path, "rx_delay"), None) or 0,
            scheduling=n.scheduling,
            tx_queue=_tx_queue(n.tx_queue),
        )
        on_can = any(sb.name in n.buses and r.bus_protocol(sb).link.arbitrates for sb in r.spec.buses)
        if n.tx_queue.policy == "fifo" and not on_can:
            r.warn(
                "wrong-section",
                f"node '{n.name}' is on no CAN bus: its tx_queue has no effect (an Ethernet NIC's queue is its "
                "nic_queue): remove it",
                (*path, "tx_queue"),
            )

def resolve_task(r: Resolver, node: str, t: schema.Task, path: Path, ec: int | None) -> model.Task:
    period = r.ns(t.period, (*path, "period"), ec)
    offset = r.ns(t.offset, (*path, "offset"), ec) or 0
    wcet = r.ns(t.wcet, (*path, "wcet"), ec) or 0
    bcet = r.ns(t.bcet, (*path, "bcet"), ec)
    if wcet <= 0:
        r.err("wcet", f"task '{node}.{t.name}' needs a worst-case execution time above zero", (*path, "wcet"))
    if bcet is None:
        bcet = wcet
    elif bcet > wcet:
        r.err("bcet", f"best case {format_ns(bcet)} exceeds worst case {format_ns(wcet)}", (*path, "bcet"))
    if period is not None:
        if period <= 0:
            r.err("period", "a task period must be above zero", (*path, "period"))
        else:
            r.check_offset(offset, period, path)
            if wcet > period:
                r.err(
                    "wcet",
                    f"WCET {format_ns(wcet)} exceeds the period {format_ns(period)}: the task can never keep up",
                    (*path, "wcet"),
                )
    if t.on_message is not None and t.period is not None:
        r.err("task-period", "an event-driven task ('on_message') has no period", (*path, "period"))
    sync_bus, jitter = None, 0
    if t.sync:
        sync_bus, period, jitter = cycle_task(r, node, t, path, period, offset)
    return model.Task(
        **same_named(t, "description name on_message priority"),
        node=node,
        period_ns=period,
        offset_ns=offset,
        wcet_ns=wcet,
        bcet_ns=bcet,
        trigger=None,
        path=path,
        sync_bus=sync_bus,
        cycle_jitter_ns=jitter,
    )


def cycle_task(
    r: Resolver, node: str, t: schema.Task, path: Path, period: int | None, offset: int
) -> tuple[str | None, int | None, int]:
    """A task that runs on its bus's cycle (`sync: true`) takes the cycle's period from the one bus of its node that
    has a cycle for it, or the one its `sync` names (its protocol's task_cycle: a CANopen bus's SYNC, an EtherCAT
    segment's cycle on its master, a DC slave's SYNC0)."""
    cycles = [
        (name, cycle)
        for name in r.spec_nodes[node].buses
        if (bus := r.model.buses.get(name)) is not None and (cycle := protocols.of(bus).task_cycle(bus, node))
    ]
    named = t.sync if isinstance(t.sync, str) else None
    if named is not None and named in (n for n, _ in cycles):
        cycles = [c for c in cycles if c[0] == named]
    elif named is not None:
        r.err(
            "task-sync",
            f"task '{node}.{t.name}' runs on the cycle of bus '{named}', which has none for '{node}' (its buses with "
            f"one: {', '.join(repr(n) for n, _ in cycles) or 'none'}): name one of those, or drop 'sync'",
            (*path, "sync"),
        )
        return None, period, 0
    if len(cycles) != 1:
        several = len(cycles) > 1
        r.err(
            "task-sync",
            f"task '{node}.{t.name}' runs on its bus's cycle ('sync: true'), so its node must be on exactly one bus "
            f"with a cycle for it, a CANopen bus (SYNC) or an EtherCAT bus it is the master or a DC slave of (it is on "
            f"{len(cycles)}): "
            + (f"name the bus ('sync: {cycles[0][0]}')" if several else "drop 'sync' and give a period"),
            (*path, "sync"),
        )
        return None, period, 0
    name, cycle = cycles[0]
    if t.on_message is not None:
        r.err("task-sync", f"a task runs either on {cycle.name} or on a message, not both", (*path, "sync"))
    if period is not None and period != cycle.period_ns:
        r.err(
            "task-period",
            f"a task on {cycle.name} runs every {cycle.name} ({format_ns(cycle.period_ns)}); drop its period",
            (*path, "period"),
        )
    r.check_offset(offset, cycle.period_ns, path, f"the {cycle.name} period")
    return name, cycle.period_ns, cycle.jitter_ns


def _tx_queue(q: schema.TxQueue) -> model.TxQueue:
    """`tx_queue: fifo` arrives as the mapping {policy: fifo} with its defaults."""
    return model.TxQueue(policy=q.policy, depth=q.depth, on_full=q.on_full)
