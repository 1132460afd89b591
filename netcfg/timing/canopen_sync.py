"""The CANopen SYNC cycle (CiA 301): does every synchronous TPDO answer in time?

In cycle k the SYNC producer sends SYNC; every TPDO with transmission type n in 1..240 and k % n == 0 (and
every acyclic synchronous TPDO, type 0, in the worst case) is queued its drive's tx_delay D after its reception.
The last of them is done, at the latest, when the bus has carried: one frame already on the bus when SYNC was
queued (blocking), SYNC itself, all synchronous TPDOs of that cycle, and every other frame that can be released
meanwhile (RPDOs written by the master, event-driven PDOs, heartbeats, ...), with the bus idle at most while the
drives wait out their delays: from SYNC's reception to the last TPDO's queueing, at most the largest D of the
cycle's TPDOs (before it SYNC is pending, after it a TPDO). A message with release jitter J can have an instance
released late in one period and the next on time, so up to ceil((W + J) / T) of its instances fall inside a window
of length W (the CAN response-time analysis' interference term, Davis et al. 2007, eq. 8); J is the one that
analysis uses, a sending task's response-time variation included (analyze's holistic jitter):
    W_k = B + C_SYNC + max D + sum over TPDOs due in k of C + sum over others of ceil((W_k + J) / T) * C
It must fit the synchronous window (0x1007), the master's read window and the communication cycle (0x1006).
With a bit-error model (netcfg.timing.can_errors) W_k gains E(W_k) = (n + ceil(W_k / T_err)) * (error frame + the
largest frame on the bus): any frame in the window may be hit and sent again.

The master's own cycle (seed 000, Figure 7; MasterLoop) is modelled from the spec, as the live master
(netcfg.runtime.canopen_master.MasterCycle) runs it: SYNC k is queued within the master's jitter (its wake-up latency)
of k T; its computation, the SYNC tasks of the SYNC producer one after the other, starts within that jitter of
k T + offset, takes BCET..WCET, and sends the RxPDOs as it ends. It must end before the next SYNC is due
(offset + jitter + WCET <= T) and start after the read window (offset >= the window): the master computes on
the samples it collected, and its SYNC keeps its period.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from math import lcm

from netcfg import cia301, model
from netcfg.timing.can_errors import ErrorModel
from netcfg.timing.clocks import PPM, longest_local

MAX_CYCLES = 240 * 8


@dataclass(frozen=True)
class SyncCycle:
    index: int
    tpdos: tuple[str, ...]
    completion_ns: int | None  # from SYNC being queued to the last synchronous TPDO's end; None: never
    limit_ns: int
    limit_name: str
    blocking_ns: int = 0  # the terms of W_k: a frame already on the bus,
    sync_ns: int = 0  # SYNC itself,
    tpdos_ns: int = 0  # the cycle's synchronous TPDOs; the rest of W_k is other frames released meanwhile
    error_ns: int = 0  # E(W_k): what bit errors may take in the window
    delay_ns: int = 0  # the largest tx_delay of the cycle's TPDOs: the bus may idle that long


@dataclass(frozen=True)
class MasterLoop:
    node: str  # the SYNC producer
    tasks: tuple[str, ...]  # its SYNC tasks on this bus (node.task refs), run one after the other
    offset_ns: int | None  # when they start after SYNC; None without any: the SYNC follows the writes at once
    bcet_ns: int
    wcet_ns: int
    jitter_ns: int  # SYNC and computation start at most this late


def master_loop(m: model.Model, bus: model.Bus) -> MasterLoop:
    co = bus.canopen
    assert co is not None
    node = m.nodes[co.sync_producer]
    tasks = sorted((t for t in node.tasks.values() if t.sync_bus == bus.name), key=lambda t: (t.offset_ns, t.name))
    return MasterLoop(
        node=node.name,
        tasks=tuple(t.ref for t in tasks),
        offset_ns=tasks[0].offset_ns if tasks else None,
        bcet_ns=sum(t.bcet_ns for t in tasks),
        wcet_ns=sum(t.wcet_ns for t in tasks),
        jitter_ns=co.master_jitter_ns,
    )


def sync_transmissions(bus: model.Bus) -> dict[str, int]:
    """Synchronous TPDOs of the bus and every how many SYNCs they go out (cia301.sync_every: type 0 counts as every
    SYNC, its worst case)."""
    out = {}
    for m in bus.messages:
        every = cia301.sync_every(m.pdo.transmission) if m.pdo is not None and m.pdo.kind == "tpdo" else None
        if every is not None:
            out[m.name] = every
    return out


def analyse(
    bus: model.Bus,
    frame_ns: Mapping[str, int],
    jitter_ns: Mapping[str, int],
    delay_ns: Mapping[str, int],
    errors: ErrorModel | None = None,
) -> list[SyncCycle]:
    """Every cycle of the pattern. `frame_ns`: worst-case frame times; `jitter_ns`: each message's release jitter as
    the response-time analysis takes it; `delay_ns`: each TPDO's queueing delay after SYNC's reception."""
    co = bus.canopen
    assert co is not None
    sync_msg = next(m for m in bus.messages if m.implicit == "SYNC")
    every = sync_transmissions(bus)
    cycles = min(lcm(*every.values()) if every else 1, MAX_CYCLES)
    limits = [(co.sync_period_ns, "the SYNC period")]
    if co.sync_window_ns is not None:
        limits.append((co.sync_window_ns, "the synchronous window (0x1007)"))
    if co.read_window_ns is not None:
        limits.append((co.read_window_ns, "the master's read window"))
    limit_ns, limit_name = min(limits)
    blocking = max(frame_ns.values(), default=0)
    others = [m for m in bus.messages if m is not sync_msg and m.name not in every]  # the same in every cycle
    ppm = bus.clock_tolerance_ppm  # other messages' senders count their periods on their own clocks
    rate = sum(frame_ns[m.name] / m.interval_ns for m in others if m.interval_ns) * PPM / (PPM - ppm)
    if errors is not None:
        rate += (errors.error_frame_ns + blocking) / errors.interval_ns  # one recovery per T_err

    def lost(window: int) -> int:
        return errors.overhead(window, blocking) if errors else 0
    out = []
    for k in range(cycles):
        due = tuple(name for name, n in every.items() if k % n == 0)
        tpdos = sum(frame_ns[n] for n in due)
        delay = max((delay_ns.get(n, 0) for n in due), default=0)
        fixed = frame_ns[sync_msg.name] + tpdos + blocking + delay
        terms = {"blocking_ns": blocking, "sync_ns": frame_ns[sync_msg.name], "tpdos_ns": tpdos, "delay_ns": delay}
        if rate >= 1:
            out.append(SyncCycle(k, due, None, limit_ns, limit_name, **terms))
            continue
        w = fixed + sum(frame_ns[m.name] for m in others)
        while True:
            nxt = fixed + sum(frame_ns[m.name] * _instances(w, jitter_ns[m.name], m, ppm) for m in others) + lost(w)
            if nxt == w:
                break
            w = nxt
        out.append(SyncCycle(k, due, w, limit_ns, limit_name, **terms, error_ns=lost(w)))
    return out


def _instances(window_ns: int, jitter_ns: int, m: model.Message, ppm: int) -> int:
    """Instances of `m` released inside a window of this length: ceil((W + J) / T), W + J counted on its sender's
    clock (within +-ppm); once for an aperiodic one."""
    if not m.interval_ns:
        return 1
    return -(-longest_local(window_ns + jitter_ns, ppm) // m.interval_ns)
