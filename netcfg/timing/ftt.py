"""FTT-CAN: the Synchronous Requirements Table, the master's per-EC schedule, and the windows' analysis.

Following Almeida, Pedreiras and Fonseca, "The FTT-CAN protocol: why and how", IEEE Transactions on
Industrial Electronics 49(6), 2002, and the CAMBADA paper (seed 002, section 5.1): the master starts every
elementary cycle (EC) with the trigger message (TM), whose EC-schedule has one bit per synchronous id due in
that EC (messages and task triggers). The asynchronous window follows the TM; the synchronous window closes
the EC, its length the worst-case transmission time of the messages due, bounded by LSW (the bus field
`windows: sync-first` swaps them: the synchronous window right after the TM, the asynchronous one closing the
EC). An asynchronous frame is started only if it can finish before the next window, so up to one maximum
asynchronous frame of inserted idle time precedes it (Almeida and Fonseca, "Analysis of a simple model for
non-preemptive blocking-free scheduling", ECRTS 2001).

Asynchronous messages are analysed as in Pedreiras and Almeida, "Combining event-triggered and time-triggered
traffic in FTT-CAN: analysis of the asynchronous messaging system", WFCS 2000: a message released just after
the last instant an asynchronous frame could start in some EC waits for the windows that follow; its response
is the time at which the asynchronous service, window by window, has carried its level-m workload
W(t) = C_m + max lower-priority C + sum over hp of ceil((t + J_k) / T_k) * C_k.

Bit errors (netcfg.timing.can_errors; the FTT-CAN treatment of Pedreiras and Almeida, "Fault tolerance in
FTT-CAN", keeps retransmissions inside the window that needs them): each EC's synchronous window gets an error
allowance A, the least fixed point of A = (n + ceil((S + A + e) / T_err)) * (e + largest frame of the window),
with S its frames, e the error frame (an asynchronous frame hit just before the window may push its error frame
into it; in the sync-first layout the TM, which opens the window, is one of its frames). The window opens A
earlier (or the asynchronous window after it starts A later), so the window with its retransmissions still ends
where the error-free one did, and it must fit the LSW with its allowance. Asynchronous messages add E(t), the
errors' cost with the largest frame at or above their priority (or the TM, whose retransmission eats into the
asynchronous window), to the workload their windows must serve.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from math import lcm

from netcfg import model
from netcfg.timing.can_errors import ErrorModel
from netcfg.timing.clocks import PPM, longest_local, shortest_real
from netcfg.timing.frames import FdFrameBits, Stuffing, arbitration_key, frame_bits
from netcfg.timing.ftt_schedule import EcSlot, Schedule, SrtEntry
from netcfg.timing.load import frame_timing

MAX_MACRO_CYCLE = 20_000  # ECs: beyond this the periods are not harmonic enough for a static table


class MacroCycleTooLong(Exception):
    def __init__(self, ecs: int) -> None:
        self.ecs = ecs


def macro_cycle(periods: list[int]) -> int:
    """The macro-cycle in ECs: the least common multiple of the periods."""
    return lcm(*periods) if periods else 1


def tm_bits(tm_size: int, extended: bool, fd: bool = False, stuffing: Stuffing = "worst") -> FdFrameBits:
    """The trigger message's bits at each rate (worst-case stuffing unless told): a data frame of tm_size bytes,
    classical, or CAN FD with bit-rate switch (fd; netcfg.protocols.ftt.tm says when)."""
    return frame_bits(tm_size, extended, fd, fd, stuffing)


def tm_time_ns(
    tm_size: int, extended: bool, bitrate: int, fd: bool = False, data_bitrate: int | None = None,
    stuffing: Stuffing = "worst",
) -> int:
    """Transmission time of the trigger message (tm_bits) at the bus's rates: its worst case unless told."""
    return tm_bits(tm_size, extended, fd, stuffing).ns(bitrate, data_bitrate)


def srt(bus: model.Bus, ftt: model.FttBus, triggers: list[model.Trigger]) -> list[SrtEntry]:
    """The Synchronous Requirements Table: every synchronous message and trigger, by FTT id (`ftt`: the bus's
    section)."""
    ec = ftt.ec_ns
    out = []
    for m in bus.messages:
        if m.window != "sync" or m.ftt_id is None or m.period_ns is None:
            continue
        timing = frame_timing(m, bus.bitrate, bus.data_bitrate)
        out.append(
            SrtEntry(
                ftt_id=m.ftt_id,
                name=m.name,
                kind="message",
                producer=m.producer,
                targets=m.consumers,
                size=m.size,
                can_id=m.id,
                extended=m.extended,
                c_bits=timing.bits_worst,
                c_ns=timing.tx_ns,
                period_ec=m.period_ns // ec,
                fastest_period_ec=(m.interval_ns or m.period_ns) // ec,
                init_ec=(m.offset_ns or 0) // ec,
                deadline_ns=m.deadline_ns,
                slowest_period_ec=(m.slowest_ns or 0) // ec,
            )
        )
    for t in triggers:
        out.append(
            SrtEntry(
                ftt_id=t.ftt_id,
                name=t.name,
                kind="trigger",
                producer=None,
                targets=t.tasks,
                size=0,
                can_id=None,
                extended=False,
                c_bits=0,
                c_ns=0,
                period_ec=t.period_ns // ec,
                fastest_period_ec=t.interval_ns // ec,
                init_ec=(t.offset_ns or 0) // ec,
                deadline_ns=None,
                slowest_period_ec=(t.slowest_ns or 0) // ec,
            )
        )
    return sorted(out, key=lambda e: e.ftt_id)


def window_allowance(errors: ErrorModel | None, frames_ns: list[int], tm_ns: int, sync_first: bool) -> int:
    """A synchronous window's bit-error allowance (the module's A); 0 for an empty window or an error-free bus."""
    if errors is None or not frames_ns:
        return 0
    span = sum(frames_ns) + (tm_ns if sync_first else 0)
    largest = max(*frames_ns, tm_ns if sync_first else 0)
    allowance = errors.overhead(span + errors.error_frame_ns, largest)
    if errors.error_frame_ns + largest >= errors.interval_ns:
        return allowance  # one recovery outlasts the interval: no fixed point, and check refuses the model
    for _ in range(MAX_ASYNC_STEPS):  # the allowance lengthens the window, which may then hold one more error
        nxt = errors.overhead(span + allowance + errors.error_frame_ns, largest)
        if nxt == allowance:
            break
        allowance = nxt
    # no fixed point when one recovery outlasts the error interval: check refuses that model (error-model)
    return allowance


def tm_delay(errors: ErrorModel | None, tm_ns: int) -> int:
    """How late bit errors may make the trigger message end: the least D with D = E(TM + D), each error costing an
    error frame and the TM again (the EC starts with the bus free: the previous window ends by then, errors
    included)."""
    if errors is None:
        return 0
    delay = errors.overhead(tm_ns, tm_ns)
    if errors.error_frame_ns + tm_ns >= errors.interval_ns:
        return delay  # as in window_allowance
    for _ in range(MAX_ASYNC_STEPS):  # as window_allowance: bounded, check refuses a model without a fixed point
        nxt = errors.overhead(tm_ns + delay, tm_ns)
        if nxt == delay:
            break
        delay = nxt
    return delay


def _slot(
    k: int, msgs: list[SrtEntry], trigs: list[SrtEntry], ec: int, tm: int, sync_first: bool, errors: ErrorModel | None
) -> EcSlot:
    sync = sum(e.c_ns for e in msgs)
    due = sorted(e.ftt_id for e in (*msgs, *trigs))
    extra = window_allowance(errors, [e.c_ns for e in msgs], tm, sync_first)
    return EcSlot(
        k, tuple(e.name for e in msgs), tuple(e.name for e in trigs), tuple(due), sync, ec - tm - sync - extra, extra
    )


def build_schedule(
    bus: model.Bus,
    ftt: model.FttBus,
    entries: list[SrtEntry],
    fastest: bool = False,
    errors: ErrorModel | None = None,
) -> Schedule:
    """The EC-schedules of one macro-cycle (the LCM of the periods, in ECs); `ftt`: the bus's section, `errors`:
    its error model."""
    periods = [e.fastest_period_ec if fastest else e.period_ec for e in entries]
    macro = macro_cycle(periods)
    if macro > MAX_MACRO_CYCLE:
        raise MacroCycleTooLong(macro)

    def due(e: SrtEntry, k: int) -> bool:
        return e.due(k, e.fastest_period_ec if fastest else None)

    return _schedule(bus, ftt, entries, macro, due, errors)


def envelope_schedule(
    bus: model.Bus, ftt: model.FttBus, entries: list[SrtEntry], errors: ErrorModel | None = None
) -> Schedule:
    """Every message that may be due in an EC at some admissible periods: each message of a period_range may run
    at any period of it (the master keeps its init EC), so EC k may carry it if some admissible period divides
    k - init. Its slots bound the synchronous window (LSW check) and the asynchronous supply of any EC whatever
    periods the master picks; without ranges it is the nominal schedule. When the pattern's length exceeds
    MAX_MACRO_CYCLE, a message with a range is taken as due in every EC (sound, more pessimistic)."""
    lengths = [lcm(*e.admissible_periods) for e in entries]
    horizon = macro_cycle(lengths)
    coarse = horizon > MAX_MACRO_CYCLE
    if coarse:
        horizon = macro_cycle([e.period_ec for e in entries if len(e.admissible_periods) == 1])
        if horizon > MAX_MACRO_CYCLE:
            raise MacroCycleTooLong(horizon)

    def may_be_due(e: SrtEntry, k: int) -> bool:
        periods = e.admissible_periods
        if coarse and len(periods) > 1:
            return True
        return any((k - e.init_ec) % p == 0 for p in periods)

    return _schedule(bus, ftt, entries, horizon, may_be_due, errors)


def _schedule(
    bus: model.Bus,
    ftt: model.FttBus,
    entries: list[SrtEntry],
    ecs: int,
    due: Callable[[SrtEntry, int], bool],
    errors: ErrorModel | None,
) -> Schedule:
    """The schedule of `ecs` ECs, EC k carrying what is `due` in it: the synchronous messages in identifier order
    (CAN arbitration), the triggers by FTT id."""
    ec = ftt.ec_ns
    tm = tm_time_ns(ftt.tm_size, ftt.tm_extended, bus.bitrate, ftt.tm_fd, bus.data_bitrate)
    by_can_id = sorted(
        (e for e in entries if e.kind == "message"), key=lambda e: arbitration_key(e.can_id or 0, e.extended)
    )
    slots = []
    for k in range(ecs):
        msgs = [e for e in by_can_id if due(e, k)]
        trigs = [e for e in entries if e.kind == "trigger" and due(e, k)]
        slots.append(_slot(k, msgs, trigs, ec, tm, ftt.sync_first, errors))
    # a TM with fewer stuff bits than its worst case ends earlier, and so do the starts it triggers
    shortest = tm_time_ns(ftt.tm_size, ftt.tm_extended, bus.bitrate, ftt.tm_fd, bus.data_bitrate, "nominal")
    return Schedule(
        ec, tm, ftt.lsw_ns, tuple(entries), tuple(slots), ftt.sync_first, tm_delay(errors, tm), tm - shortest
    )


def ec_schedule_mask(slot: EcSlot) -> int:
    """The TM's EC-schedule as an integer: bit i set when FTT id i is due."""
    mask = 0
    for i in slot.ids:
        mask |= 1 << i
    return mask


@dataclass(frozen=True)
class AsyncFrame:
    name: str
    can_id: int
    c_ns: int
    t_ns: int | None
    j_ns: int = 0
    extended: bool = False


MAX_ASYNC_STEPS = 20_000  # fixed-point steps per asynchronous message before it is reported unbounded


def async_response_times(
    sched: Schedule,
    frames: list[AsyncFrame],
    limited: set[str] | None = None,
    tolerance_ppm: int = 0,
    errors: ErrorModel | None = None,
) -> dict[str, int | None]:
    """Worst-case response of each asynchronous message over all ECs of the (envelope) schedule; None when
    unbounded: the level-m load, the message's own included, reaches the asynchronous supply, or the bound needs
    more than MAX_ASYNC_STEPS steps. As on plain CAN (Davis et al. 2007), every instance q of m in the level-m busy
    period is examined: w(q) = serve(B + (q + 1) C_m + sum over hp of ceil((w + J_k) / T_k) C_k),
    R(q) = J_m + w(q) - q T_m, with E(w) added to the demand under a bit-error model. Asynchronous messages run on
    their senders' clocks, within +-tolerance_ppm of the master's (clocks): windows of real time are counted as
    longest_local, q T_m as shortest_real. Messages stopped by the step limit are added to `limited`."""
    if not frames:
        return {}
    idle = max(f.c_ns for f in frames)  # inserted idle time before each synchronous window
    supply = [max(0, s.async_ns - idle) for s in sched.slots]
    cycle_supply = sum(supply)
    if cycle_supply == 0:
        return {f.name: None for f in frames}
    cycle_ns = sched.ec_ns * sched.macro_cycle
    ordered = sorted(frames, key=lambda f: arbitration_key(f.can_id, f.extended))
    out: dict[str, int | None] = {}
    fastest = Fraction(PPM, PPM - tolerance_ppm)  # the fastest sender clocks release this much more often
    level_demand = Fraction(0)  # exact, kept as a running sum over the messages so far (the level-m set)
    # the messages so far by (period, jitter), with their C summed: they are released alike in any window
    classes: dict[tuple[int | None, int], int] = {}
    for i, f in enumerate(ordered):
        hp = list(classes.items())
        classes[f.t_ns, f.j_ns] = classes.get((f.t_ns, f.j_ns), 0) + f.c_ns
        level = ordered[: i + 1]
        blocking = max((g.c_ns for g in ordered[i + 1 :]), default=0)
        largest = max(sched.tm_ns, *(g.c_ns for g in level))  # what an error can make the window resend
        # exact: the level-m demand per macro-cycle against what the windows serve in one
        if f.t_ns:
            level_demand += Fraction(f.c_ns * cycle_ns, f.t_ns) * fastest
        demand = level_demand
        if errors is not None:  # one recovery per T_err (real time)
            demand += Fraction((errors.error_frame_ns + largest) * cycle_ns, errors.interval_ns)
        if demand >= cycle_supply:
            out[f.name] = None
            continue

        def lost(t: int, largest: int = largest) -> int:
            return errors.overhead(t, largest) if errors else 0

        out[f.name] = _async_worst(sched, supply, f, hp, blocking, tolerance_ppm, lost)
        if out[f.name] is None and limited is not None:
            limited.add(f.name)  # the load fits: only the step limit stopped the analysis
    return out


def _async_worst(
    sched: Schedule,
    supply: list[int],
    f: AsyncFrame,
    hp: list[tuple[tuple[int | None, int], int]],
    blocking: int,
    ppm: int,
    lost: Callable[[int], int] = lambda _: 0,
) -> int | None:
    demand_at: dict[int, int] = {}  # every start of the macro-cycle revisits the same windows

    def hp_demand(t: int) -> int:
        """Higher-priority work released in a window of length t, and what bit errors take in it (`hp`: the
        higher-priority messages as ((period, jitter), their C summed))."""
        if (known := demand_at.get(t)) is None:
            known = demand_at[t] = sum(
                c * (-(-longest_local(t + j, ppm) // period) if period else 1) for (period, j), c in hp
            ) + lost(t)
        return known

    steps = 0
    worst = 0
    for start in range(sched.macro_cycle):
        # level-m busy period from this start: until the windows have served everything released in it
        busy = 0
        while True:
            own = f.c_ns * (-(-longest_local(busy + f.j_ns, ppm) // f.t_ns) if f.t_ns else 1)
            served = _time_to_serve(sched, supply, start, blocking + max(own, f.c_ns) + hp_demand(busy))
            steps += 1
            if served <= busy:
                break
            if steps > MAX_ASYNC_STEPS:
                return None
            busy = served
        instances = max(1, -(-longest_local(busy + f.j_ns, ppm) // f.t_ns)) if f.t_ns else 1
        w = 0
        for q in range(instances):
            while True:
                served = _time_to_serve(sched, supply, start, blocking + (q + 1) * f.c_ns + hp_demand(w))
                steps += 1
                if served <= w:
                    break
                if steps > MAX_ASYNC_STEPS:
                    return None
                w = served
            worst = max(worst, f.j_ns + w - shortest_real(q * (f.t_ns or 0), ppm))
    return worst


def _time_to_serve(sched: Schedule, supply: list[int], start: int, demand: int) -> int:
    """Time, from the end of EC start's usable asynchronous window, until `demand` ns of asynchronous
    service have been given in the following ECs' windows."""
    ec, n = sched.ec_ns, sched.macro_cycle
    origin = start * ec + sched.async_start(start) + supply[start]  # just too late to start in this EC's window
    k = start + 1
    left = demand
    while True:
        cap = supply[k % n]
        if left <= cap:
            return k * ec + sched.async_start(k) + left - origin
        left -= cap
        k += 1
