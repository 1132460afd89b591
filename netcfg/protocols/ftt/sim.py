"""The FTT-CAN master and its elementary cycles (seed 002, section 3; Almeida, Pedreiras, Fonseca 2002).

Every EC starts with the trigger message (TM), which carries that EC's schedule. Its reception starts the
triggered tasks of the EC; the EC's synchronous messages are queued at the start of the synchronous window (after
the TM, or at the end of the EC with the asynchronous window first: netcfg.timing.ftt's layout), or at the TM's
end if a TM resent after bit errors ends later, and go out in identifier order; asynchronous messages
arbitrate normally but may start only if they end before that window (netcfg.sim.can_bus's gate).

The master may fail (a `master-fail` fault). A backup master that misses the TM for longer than a timeout sends
it itself, late, and keeps the EC grid from then on (the CAMBADA robots replicate the master). An EC whose TM is
lost has no synchronous traffic and starts no triggered task; what should have been sent is counted as lost.

The scenario builds it through the bus's protocol (Ftt.sim_driver) and it sees the run only through
netcfg.sim.run.SimRun; like every simulator driver it reads runtime.json, never the model.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from netcfg.protocols.ftt.tm import TM_EXTENDED, tm_fd
from netcfg.runtime import Bus, EcSlot, Task
from netcfg.sim.can_bus import CanBus
from netcfg.sim.engine import NEVER, PPB

if TYPE_CHECKING:
    from netcfg.sim.run import SimRun


class FttMaster:
    def __init__(self, sc: SimRun, bus: Bus, can: CanBus) -> None:
        assert bus.ftt is not None
        self.sc = sc
        self.can = can
        self.ftt = ftt = bus.ftt
        self.master = ftt.master
        self.clock = sc.clock[ftt.master]
        self._phase, self._drift, self._ec_ns = self.clock.phase_ns, self.clock.drift_ppb, ftt.ec_ns
        self.tm_name = f"{bus.name}_TM"
        fd = tm_fd(bus.link)  # the trigger message's frame format on this link, as the analysis timed it
        self.tm = can.add_source(self.tm_name, ftt.tm_id, TM_EXTENDED, ftt.tm_size, ftt.master, fd=fd, brs=fd)
        sc.msg_source[self.tm_name] = (can, self.tm)
        self.owned = {m for slot in ftt.schedule for m in slot.messages}
        self.fail_at = NEVER
        self.backup: str | None = None
        self.takeover_ns: int | None = None  # when the backup sent its first TM
        self.tm_timeout_ns = 2 * ftt.tm_ns  # the backup waits this long past an EC start for the TM
        self.ecs = 0
        self.lost_ecs = 0
        self._got_tm = -1  # the last EC whose TM arrived
        # per slot of the macro-cycle, what its trigger message starts: the tasks its triggers activate, grouped
        # by how long after the TM's reception they start (the receiving node's rx_delay); worked out at first use
        self._slot_tasks: dict[int, list[tuple[int, list[Task]]]] = {}
        self._tm_payloads: dict[int, bytes] = {}  # slot of the macro-cycle -> its TM's payload
        can.listen(self.tm, self._on_tm)
        can.gate = self.gate

    def fail(self, at_ns: int, backup: str | None) -> None:
        self.fail_at = at_ns
        names = [n.name for n in self.sc.cfg.nodes if n.name != self.master]
        if backup is None:
            backup = next((n for n in names if "backup" in n), None)
        elif backup not in names:
            raise ValueError(f"no node named '{backup}' to take over as FTT-CAN master")
        self.backup = backup

    # -- EC grid ----------------------------------------------------------------------------------------
    def ec_start(self, k: int) -> int:
        # the master's clock's to_global, inline (engine.drift_ns, as a call 1.4 % of CAMBADA's instructions):
        # asked several times per EC; Python integers do not overflow
        local = k * self._ec_ns
        return self._phase + local + local * self._drift // PPB

    def ec_of(self, t: int) -> int:
        local = (t - self.clock.phase_ns) * PPB // (PPB + self.clock.drift_ppb)
        k = max(0, local // self.ftt.ec_ns)
        while k > 0 and self.ec_start(k) > t:
            k -= 1
        while self.ec_start(k + 1) <= t:
            k += 1
        return k

    def gate(self, t: int, dur: int, opens_after: int = 0) -> int:
        """Earliest start >= t at which an asynchronous frame of this duration ends before a synchronous window
        (and starts no earlier than `opens_after` into the EC)."""
        k = self.ec_of(t)
        for _ in range(2 * self.ftt.macro_cycle_ec + 2):
            opens, closes = self.ftt.async_window(k)
            start = self.ec_start(k)
            s = max(t, start + max(opens, opens_after))
            if s + dur <= start + closes:
                return s
            k += 1
        return NEVER  # never fits: longer than every asynchronous window

    # -- the cycle --------------------------------------------------------------------------------------
    def start(self) -> None:
        self.sc.sim.at(self.ec_start(0), self._ec, 0)

    def _ec(self, k: int) -> None:
        sim = self.sc.sim
        if k > 0 and self._got_tm < k - 1:
            self._count_lost(k - 1)
        self.ecs += 1
        sender = self._tm_sender()
        if sender == self.master or (sender is not None and self.takeover_ns is not None):
            self._send_tm(k)  # the backup, once in charge, keeps the EC grid
        elif sender is not None:
            sim.at(sim.now + self.tm_timeout_ns, self._backup_tm, k)  # it notices the missing TM first
        sim.at(self.ec_start(k + 1), self._ec, k + 1)

    def _tm_sender(self) -> str | None:
        now = self.sc.sim.now
        if now < self.fail_at and self.sc.alive(self.master):
            return self.master
        if self.backup is not None and self.sc.alive(self.backup):
            return self.backup
        return None

    def _backup_tm(self, k: int) -> None:
        if self.takeover_ns is None:
            self.takeover_ns = self.sc.sim.now
            self.can.sources[self.tm].producer = self.backup or self.master
        self._send_tm(k)

    def _send_tm(self, k: int) -> None:
        self.can.submit(self.tm, self.tm_payload(k % self.ftt.macro_cycle_ec))

    def tm_payload(self, i: int) -> bytes:
        """The TM of slot i of the macro-cycle: that EC's schedule as it carries it (worked out once per slot)."""
        payload = self._tm_payloads.get(i)
        if payload is None:
            mask, size = self.ftt.slot(i).mask, self.ftt.tm_size
            payload = self._tm_payloads[i] = (mask & ((1 << 8 * size) - 1)).to_bytes(size, "little")
        return payload

    def _on_tm(self, end: int, _src: int, release: int, data: bytes | None) -> None:
        # the EC the TM was sent for: it is queued in that EC (at its start, or the backup's timeout later), but a
        # TM resent after bit errors may end past that EC's synchronous window's start, or even in the next EC
        k = self.ec_of(release)
        self._got_tm = k
        slot = self.ftt.slot(k)
        groups = self._slot_tasks.get(k % self.ftt.macro_cycle_ec)
        if groups is None:
            groups = self._slot_tasks[k % self.ftt.macro_cycle_ec] = self._triggered(slot)
        sim = self.sc.sim
        for after, tasks in groups:  # tasks that start together: one event, in the order they were listed
            if after > 0:
                sim.at(end + after, self._start_tasks, tasks)
            else:
                self._start_tasks(tasks)
        if slot.messages:
            window = self.ec_start(k) + self.ftt.window_start(k)
            sim.at(max(window, end), self._sync_window, slot.messages)

    def _triggered(self, slot: EcSlot) -> list[tuple[int, list[Task]]]:
        """The tasks the slot's triggers activate, in order, in runs of the same rx_delay of their node (a task
        that starts at once may schedule something, so runs are not merged across it)."""
        groups: list[tuple[int, list[Task]]] = []
        for trig in slot.triggers:
            for task in self.sc.tasks_on_trigger(trig):
                after = self.sc.cfg.node(task.node).rx_delay_ns
                if groups and groups[-1][0] == after:
                    groups[-1][1].append(task)
                else:
                    groups.append((after, [task]))
        return groups

    def _start_tasks(self, tasks: list[Task]) -> None:
        for task in tasks:
            self.sc.run_task(task)

    def _sync_window(self, messages: tuple[str, ...]) -> None:
        for name in messages:
            self.sc.submit(name)

    def _count_lost(self, k: int) -> None:
        self.lost_ecs += 1
        for name in self.ftt.slot(k).messages:
            bus, src = self.sc.msg_source[name]
            bus.drop(src)

    def report(self) -> dict[str, object]:
        return {
            "ecs": self.ecs,
            "ecs_without_tm": self.lost_ecs,
            "master_failed_at_us": None if self.fail_at == NEVER else self.fail_at / 1000,
            "backup": self.backup,
            "takeover_at_us": None if self.takeover_ns is None else self.takeover_ns / 1000,
        }
