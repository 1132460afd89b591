"""What a simulation is held to before it runs: the work it would take, estimated in events from the configuration,
and bit error rates no CAN node survives (beyond ISO 11898-1's fault confinement, which the simulator does not
model). `netcfg simulate` refuses a run either says is meaningless or too long."""

from __future__ import annotations

from fractions import Fraction

from netcfg import protocols, runtime
from netcfg.sim.faults import Fault
from netcfg.spec.units import format_ns
from netcfg.timing.frames import frame_bits

# The work one run may take, in events (message releases, task jobs, SYNCs, FTT-CAN elementary cycles), estimated
# from the configuration before it runs; --max-events raises it. Measured: large_plant's 20 s (231,400 estimated
# events) took 5 s on a 2-core machine under load, about 50,000 events/s, so 20 million is minutes of work.
DEFAULT_MAX_EVENTS = 20_000_000
# ISO 11898-1 fault confinement: a transmitter's error counter rises by 8 per failed frame and falls by 1 per good
# one, so where more than one frame in 9 fails it climbs without bound to bus-off, which the simulator does not
# model; bit error rates that fail more frames than that are refused.
MAX_FRAME_ERROR_RATE = 1 / 9


def events_per_second(cfg: runtime.RuntimeConfig) -> dict[str, Fraction]:
    """What generates simulation events, and how many per simulated second: every periodic or sporadic message
    (at its period or minimum inter-arrival), every task job (at its period, or at the rate of what activates it),
    every SYNC, FTT-CAN elementary cycle and EtherCAT cycle. A sporadic source counts at its fastest rate: an upper
    bound."""
    second = 10**9
    rates: dict[str, Fraction] = {}
    msg_rate: dict[str, Fraction] = {}
    for m in cfg.messages:
        every = m.period_ns or m.interval_ns
        msg_rate[m.name] = Fraction(second, every) if every else Fraction(0)
        rates[f"message '{m.name}'"] = msg_rate[m.name]
    trig_rate = {t.name: Fraction(second, t.interval_ns or t.period_ns) for t in cfg.triggers}
    rates.update({f"trigger '{name}'": r for name, r in trig_rate.items()})
    sync_rate: dict[str, Fraction] = {}
    for b in cfg.buses:
        if b.canopen is not None:
            sync_rate[b.name] = Fraction(second, b.canopen.sync_period_ns)
        for what, period_ns in protocols.of(b).sim_events(b):  # a SYNC, an FTT-CAN elementary cycle, an EtherCAT cycle
            rates[what] = Fraction(second, period_ns)
    for n in cfg.nodes:
        for t in n.tasks:
            if t.period_ns:
                rate = Fraction(second, t.period_ns)
            elif t.trigger is not None:
                rate = trig_rate.get(t.trigger, Fraction(0))
            elif t.on_message is not None:
                rate = msg_rate.get(t.on_message, Fraction(0))
            else:
                rate = sync_rate.get(t.sync_bus or "", Fraction(0))
            rates[f"task '{t.ref}'"] = rate
    return rates


def work_problem(cfg: runtime.RuntimeConfig, duration_ns: int, max_events: int) -> str | None:
    """Why one run would take too long to simulate (more than max_events estimated events), or None."""
    rates = events_per_second(cfg)
    total = sum(rates.values(), Fraction(0)) * duration_ns / 10**9
    if total <= max_events:
        return None
    worst = max(rates, key=lambda k: rates[k])
    return (
        f"simulating {format_ns(duration_ns)} of this configuration takes about {int(total):,} events, more than "
        f"the limit of {max_events:,} (the most: {worst}, {float(rates[worst]):,.0f} per simulated second); "
        "shorten --duration, or raise --max-events if that much work is meant"
    )


def _frame_bits(m: runtime.Message) -> int:
    """Bits of one frame in the worst case (both phases of a CAN FD frame): what a bit error can hit."""
    return frame_bits(m.size, m.extended, m.fd, m.brs).total


def fault_problem(cfg: runtime.RuntimeConfig, faults: tuple[Fault, ...]) -> str | None:
    """Why a --fault would make the run meaningless (a bit error rate that sends CAN nodes bus-off), or None."""
    for f in faults:
        if f.kind != "ber" or f.value <= 0:
            continue
        frames = [_frame_bits(m) for m in cfg.messages if m.is_can and (f.target is None or m.bus == f.target)]
        if not frames:
            continue
        longest = max(frames)
        fail = 1 - (1 - f.value) ** longest
        if fail > MAX_FRAME_ERROR_RATE:
            limit = 1 - (1 - MAX_FRAME_ERROR_RATE) ** (1 / longest)
            return (
                f"--fault ber={f.value:g}: {fail:.0%} of the {longest}-bit frames would fail, and beyond 1 in 9 a "
                f"CAN transmitter goes bus-off (ISO 11898-1 fault confinement), which the simulator does not model; "
                f"give a rate of at most {limit:.2g} for these frames"
            )
    return None
