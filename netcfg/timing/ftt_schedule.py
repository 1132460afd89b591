"""What FTT-CAN's analysis builds of a bus (netcfg.timing.ftt): the Synchronous Requirements Table's entries, each
elementary cycle's slot, and the schedule of one macro-cycle with the windows' layout. Plain records that import
nothing of the model, so the model can name the schedule it keeps (model.Bus.ftt_schedule) without an import cycle."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SrtEntry:
    ftt_id: int
    name: str
    kind: str  # "message" | "trigger"
    producer: str | None
    targets: tuple[str, ...]  # consumers of a message, node.task activated by a trigger
    size: int
    can_id: int | None
    extended: bool
    c_bits: int
    c_ns: int
    period_ec: int
    fastest_period_ec: int
    init_ec: int  # first EC in which it is due (Table 2's "init time")
    deadline_ns: int | None
    slowest_period_ec: int = 0  # period_range's slowest period; 0: the nominal period (no range)

    def due(self, ec: int, period: int | None = None) -> bool:
        p = period or self.period_ec
        return (ec - self.init_ec) % p == 0

    @property
    def admissible_periods(self) -> range:
        """Every period the master may give it: the whole period_range, in ECs."""
        return range(self.fastest_period_ec, max(self.slowest_period_ec, self.period_ec) + 1)


@dataclass(frozen=True)
class EcSlot:
    index: int
    messages: tuple[str, ...]  # synchronous messages in window order (CAN arbitration: lowest id first)
    triggers: tuple[str, ...]
    ids: tuple[int, ...]  # FTT ids announced by the TM
    sync_ns: int  # synchronous window length (worst-case frames)
    async_ns: int  # what is left for the asynchronous window
    allowance_ns: int = 0  # the synchronous window's bit-error allowance (0 on an error-free bus)


@dataclass(frozen=True)
class Schedule:
    ec_ns: int
    tm_ns: int
    lsw_ns: int
    entries: tuple[SrtEntry, ...]
    slots: tuple[EcSlot, ...]  # one per EC of the macro-cycle
    sync_first: bool = False  # the synchronous window right after the TM, the asynchronous one closing the EC
    tm_delay_ns: int = 0  # how much later than tm_ns the TM may end, sent again after bit errors
    tm_early_ns: int = 0  # how much earlier than tm_ns the TM may end: fewer stuff bits than its worst case

    @property
    def macro_cycle(self) -> int:
        return len(self.slots)

    def window_start(self, ec: int) -> int:
        """Start of EC ec's synchronous window, from the EC start."""
        if self.sync_first:
            return self.tm_ns
        slot = self.slots[ec % self.macro_cycle]
        return self.ec_ns - slot.sync_ns - slot.allowance_ns

    def window_delay(self, ec: int) -> int:
        """How much later than window_start EC ec's synchronous frames may be queued: a TM resent after bit errors
        that ends after the window's start holds them back until it ends (netcfg.protocols.ftt.sim queues them then)."""
        return max(0, self.tm_ns + self.tm_delay_ns - self.window_start(ec))

    def async_start(self, ec: int) -> int:
        """Start of EC ec's asynchronous window, from the EC start: after the TM, or after the synchronous window."""
        slot = self.slots[ec % self.macro_cycle]
        return self.tm_ns + (slot.sync_ns + slot.allowance_ns if self.sync_first else 0)

    def completion(self, name: str, ec: int, frame_ns: dict[str, tuple[int, int]]) -> tuple[int, int]:
        """(best, worst) end of message `name`'s frame in EC ec, from the EC start. frame_ns gives each
        message's (nominal, worst-case) frame time; the window's frames go out in identifier order."""
        slot = self.slots[ec % self.macro_cycle]
        best = worst = self.window_start(ec)
        for other in slot.messages:
            best += frame_ns[other][0]
            worst += frame_ns[other][1]
            if other == name:
                return best, worst
        raise KeyError(name)
