"""Faults a simulation can inject, written on the command line as `--fault TEXT`:

    ber=1e-6[:BUS]              random bit errors, this probability per bit while a frame is on the wire (CAN)
    bit-error@12.5ms[:BUS]      one bit error at that instant (repeat the option for a scripted list; CAN)
    crash:NODE@2s               the node stops: it sends nothing more and its queued frames are lost
    babble:NODE@1s[..2s][=ID]   the node floods its buses with back-to-back frames of identifier ID (default 0)
    lose:MESSAGE@100ms          the first instance of MESSAGE queued at or after that instant is lost (CAN or
                                Ethernet: for Ethernet, queued = handed to the producer's NIC)
    lose:BUS@100ms              on an EtherCAT segment: the frame of the first cycle starting at or after that
                                instant is lost, which the master sees as a working-counter mismatch
    master-fail@2s[:BACKUP]     the FTT-CAN master stops; the backup master (a node named *backup*, or BACKUP)
                                notices the missing trigger message and takes over

and the fault drills of a CANopen bus, written as `netcfg run` writes them (`--fault KIND:ARG` is `run --KIND ARG`,
one grammar: netcfg.runtime.drills), played on the simulated bus's live master (netcfg.sim.canopen_drills):

    kill:NODE@T                 the node drops off the bus (the same as crash:NODE@T)
    emcy:NODE@T[=CODE]          the node sends an EMCY and faults
    reset:NODE@T+OUTAGE         the node reboots: silent for OUTAGE, then its boot-up message, PRE-OPERATIONAL
    stall:T..T2                 the master's loop pauses: no SYNC, no RxPDO
    bus-off:T..T2               the master's CAN controller is bus-off
    sdo-abort:NODE:INDEX[:SUB]  refused: it acts on the set-up over SDO, which a simulation starts after

Without :BUS a bit-error fault applies to every CAN bus. Bit errors are CAN only: the Ethernet model has no
error model (a corrupted Ethernet frame is simply dropped by the receiver's FCS check; use lose: for that).
"""

from __future__ import annotations

import contextlib
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from netcfg.runtime.drills import Drill, DrillError, parse_drill, split_drill
from netcfg.sim.engine import NEVER
from netcfg.spec.units import parse_instant_option

if TYPE_CHECKING:
    from netcfg.sim.run import SimRun

class FaultError(ValueError):
    pass


def parse_time(text: str) -> int:
    """A fault's instant in the one unit grammar of specs and command line (netcfg.spec.units)."""
    try:
        return parse_instant_option(text)
    except ValueError as exc:
        raise FaultError(f"fault time {exc}") from None


@dataclass(frozen=True)
class Fault:
    kind: str  # "ber" | "bit-error" | "crash" | "babble" | "lose" | "master-fail" | "drill"
    target: str | None = None  # node, message, bus or backup master
    at_ns: int = 0
    until_ns: int = NEVER
    value: float = 0.0  # bit error rate, or the babbler's identifier
    drill: Drill | None = None  # kind "drill": which (netcfg.runtime.drills)

    @property
    def silences(self) -> str | None:
        """The node this fault silences from at_ns on: a crash, and a reset (after its boot-up message the node is
        PRE-OPERATIONAL with its default dictionary: no PDO, and no heartbeat the configuration could say)."""
        if self.kind == "crash" or (self.drill is not None and self.drill.kind == "reset"):
            return self.target
        return None

    @staticmethod
    def parse(text: str) -> Fault:
        t = text.strip()
        drill = split_drill(t)
        if drill is not None:
            try:
                d = parse_drill(*drill)
            except DrillError as exc:
                # the same message, naming the option as written here
                said = str(exc).replace(f"--{drill[0]} {drill[1].strip()!r}", f"fault '{t}'", 1)
                raise FaultError(said) from None
            if d.kind == "kill":  # the run's name for a crash
                return Fault("crash", d.node, d.at_ns, drill=d)
            if d.kind == "sdo-abort":
                raise FaultError(
                    f"fault '{text}': an SDO abort refuses a write of the set-up, and a simulation starts with every "
                    "node set up (its run is the cyclic phase); drill it with netcfg run --simulated-drives "
                    f"--sdo-abort {drill[1]}"
                )
            return Fault("drill", d.node, d.at_ns, d.until_ns or NEVER, float(d.code), d)
        if t.startswith("ber="):
            rate, _, bus = t[4:].partition(":")
            try:
                value = float(rate)
            except ValueError:
                raise FaultError(f"'{rate}' is not a bit error rate: write e.g. ber=1e-6") from None
            if not 0 <= value < 1:
                raise FaultError(f"bit error rate {value} must be in [0, 1)")
            return Fault("ber", bus or None, value=value)
        m = re.fullmatch(r"bit-error@([^:]+)(?::(\S+))?", t)
        if m:
            return Fault("bit-error", m.group(2), parse_time(m.group(1)))
        m = re.fullmatch(r"(crash|lose):([^@]+)@(.+)", t)
        if m:
            return Fault(m.group(1), m.group(2), parse_time(m.group(3)))
        m = re.fullmatch(r"babble:([^@]+)@([^=]+?)(?:=(\S+))?", t)
        if m:
            begin, dots, end = m.group(2).partition("..")
            start = parse_time(begin)
            until = parse_time(end) if dots else NEVER
            try:
                ident = int(m.group(3), 0) if m.group(3) else 0
            except ValueError:
                raise FaultError(f"babble identifier '{m.group(3)}' is not a number: write e.g. =0x0 or =16") from None
            if not 0 <= ident <= 0x7FF:
                raise FaultError(f"babble identifier {ident:#x} is not an 11-bit CAN identifier (0x000-0x7FF)")
            if until <= start:
                raise FaultError(f"babble window '{text}' ends before it starts: write e.g. babble:NODE@1s..2s")
            return Fault("babble", m.group(1), start, until, float(ident))
        m = re.fullmatch(r"master-fail@([^:]+)(?::(\S+))?", t)
        if m:
            return Fault("master-fail", m.group(2), parse_time(m.group(1)))
        raise FaultError(
            f"cannot read fault '{text}': write one of ber=1e-6, bit-error@12ms, crash:NODE@2s, "
            "babble:NODE@1s..2s=0x0, lose:MESSAGE@100ms, master-fail@2s, or a drill as netcfg run writes it: "
            "kill:NODE@1s, emcy:NODE@1s=0x2310, reset:NODE@1s+50ms, stall:1s..1.2s, bus-off:1s..1.2s"
        )

    def install(self, sc: SimRun) -> None:
        """Set the fault up in a scenario whose buses exist but have not started."""
        errors = self.kind in ("ber", "bit-error")
        buses = [b for b in sc.can.values() if self.target in (None, b.name)] if errors else []
        if errors and not buses:
            # Ethernet: only lose and crash (bit errors are modelled on CAN buses only)
            if any(b.name == self.target and b.is_udp for b in sc.cfg.buses):
                raise FaultError(
                    f"fault '{self.kind}': bus '{self.target}' is Ethernet; bit errors are simulated on CAN buses only"
                )
            if self.target is None:
                raise FaultError(f"fault '{self.kind}': no CAN bus to apply it to (bit errors are CAN only)")
            can = [b.name for b in sc.cfg.buses if b.is_can]
            raise FaultError(f"fault '{self.kind}': no CAN bus named '{self.target}'{_hint(self.target, can)}")
        if self.kind == "ber":
            for bus in buses:
                # errors as a Poisson process in bus time; one that falls on an idle bus does nothing. On CAN FD
                # at the data phase's bit rate throughout: never fewer errors than the bits sent would see
                rate_per_ns = self.value * max(bus.bitrate, bus.data_bitrate) / 1e9
                if rate_per_ns > 0:
                    n = int(sc.opts.duration_ns * rate_per_ns * 1.5) + 10
                    gaps = sc.rng.exponential(1 / rate_per_ns, n)
                    times = np.cumsum(gaps).astype(np.int64)
                    bus.error_times = sorted(bus.error_times + times[times < sc.opts.duration_ns].tolist())
        elif self.kind == "bit-error":
            for bus in buses:
                bus.error_times = sorted([*bus.error_times, self.at_ns])
        elif self.kind == "crash":
            node = _node(sc, self.target)
            if self.drill is not None:  # kill: a crash, said as a drill where a live CANopen master plays drills
                from netcfg.sim.canopen_drills import install

                with contextlib.suppress(ValueError):
                    install(sc, self.drill)
            for bus in sc.can.values():
                sc.sim.at(self.at_ns, lambda _, b=bus: b.remove_pending(lambda s, b=b: b.sources[s].producer != node))
        elif self.kind == "babble":
            node = _node(sc, self.target)
            for bus in sc.can.values():
                if node in sc.cfg.bus(bus.name).nodes:
                    src = bus.add_source(f"{node}_babble", int(self.value), False, 8, node)
                    bus.babble = (src, self.at_ns, self.until_ns)
        elif self.kind == "lose":
            if self.target is not None and self.target in sc.eth_owner:  # Ethernet
                sc.eth_owner[self.target].lose_at(self.target, self.at_ns)
                return
            lose_cycle = getattr(sc.protocols.get(self.target or ""), "lose_cycle_at", None)
            if lose_cycle is not None:  # a bus whose cyclic frame carries its data (EtherCAT)
                lose_cycle(self.at_ns)
                return
            if self.target not in sc.msg_source:
                hint = _hint(self.target, [*sc.msg_source, *sc.eth_owner])
                raise FaultError(
                    f"fault 'lose': no CAN or Ethernet message named '{self.target}', nor an EtherCAT bus{hint}"
                )
            bus, src = sc.msg_source[self.target]
            bus.lose.setdefault(src, []).append(self.at_ns)
        elif self.kind == "drill":
            from netcfg.sim.canopen_drills import install

            assert self.drill is not None
            try:
                install(sc, self.drill)
            except ValueError as exc:
                raise FaultError(f"fault '{self.drill.text()}': {exc}") from None
        elif self.kind == "master-fail":
            masters = [d for d in sc.protocols.values() if hasattr(d, "fail")]
            if not masters:
                raise FaultError("fault 'master-fail' needs an FTT-CAN bus simulated in synchronised mode")
            for d in masters:
                d.fail(self.at_ns, self.target)  # type: ignore[attr-defined]


def _node(sc: SimRun, name: str | None) -> str:
    names = [n.name for n in sc.cfg.nodes]
    if name not in names:
        raise FaultError(f"no node named '{name}'{_hint(name, names)}; the nodes are: {', '.join(names)}")
    return name


def _hint(name: str | None, known: list[str]) -> str:
    """The shared 'did you mean' of every name lookup; imported only on this error path, which is the only place
    the simulator needs the compiler's package."""
    from netcfg.spec.suggest import did_you_mean

    return did_you_mean(name, known) if name is not None else ""
