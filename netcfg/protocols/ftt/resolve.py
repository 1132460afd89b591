"""FTT-CAN (Almeida, Pedreiras, Fonseca): the elementary cycle, the trigger message and the LSW of a bus, which
window each message travels in, release grids of whole ECs, synchronous triggers of tasks and the FTT ids that
the trigger message's bitmap holds (the SRT's rows)."""

from __future__ import annotations

import dataclasses
from typing import Literal

from netcfg import model
from netcfg.links.canfd import OverCanLinks
from netcfg.model import MessageKind
from netcfg.rules import Release
from netcfg.spec import schema
from netcfg.spec.source import Path
from netcfg.spec.suggest import did_you_mean, some_names
from netcfg.spec.units import Duration, format_ns
from netcfg.timing.frames import arbitration_key


class FttRules(OverCanLinks):  # over classical CAN or CAN FD (`link: can-fd`)
    name = "ftt-can"
    section = "ftt"
    explicit_ids = False  # synchronous messages take sync_id_base + their FTT id
    rate_adaptation = True
    auto_offsets = True

    def resolve_bus(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        super().resolve_bus(b, bus, path)
        self.resolve_ftt(b, bus, path)

    def cycle_ns(self, b: schema.Bus) -> int | None:
        return b.ftt.ec.to_ns(None) if b.ftt is not None else None

    def resolve_ftt(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        f: schema.FttParams | None = self.required_section(b, "FTT-CAN", "{ec: 5 ms, tm_size: 5}", path)
        if f is None:
            return
        fpath = (*path, "ftt")
        if f.ec.ns is None or f.ec.ns == 0:
            self.r.err("ec", "the elementary cycle needs a length in time units, e.g. 'ec: 5 ms'", (*fpath, "ec"))
            return
        ec = f.ec.ns
        lsw = self.r.ns(f.lsw, (*fpath, "lsw"), ec)
        # here: resolving a spec without FTT-CAN loads no FTT-CAN analysis
        from netcfg.protocols.ftt.tm import TM_EXTENDED, tm_fd
        from netcfg.timing.ftt import tm_time_ns

        fd = tm_fd(bus.link)
        if fd and bus.data_bitrate is None:
            return  # the CAN FD link's rules said the bus needs its data bit rate
        tm_ns = tm_time_ns(f.tm_size, TM_EXTENDED, b.bitrate, fd, bus.data_bitrate)
        if lsw is not None and lsw + tm_ns > ec:
            self.r.err(
                "lsw",
                f"LSW {format_ns(lsw)} plus the trigger message ({format_ns(tm_ns)}) exceeds the "
                f"EC of {format_ns(ec)}; shorten the LSW",
                (*fpath, "lsw"),
            )
        master = self.section_master(b, f.master, fpath, "master", "FTT-CAN master", "FTT-CAN", "ftt-master")
        if master is None:
            return
        bus.ftt = model.FttBus(
            ec_ns=ec,
            tm_size=f.tm_size,
            lsw_ns=ec - tm_ns if lsw is None else lsw,
            tm_id=f.tm_id,
            master=master,
            sync_first=f.windows == "sync-first",
            tm_extended=TM_EXTENDED,
            tm_fd=fd,
        )

    def resolve_items(self) -> None:
        self.resolve_triggers()

    def carries_messages(self, bus: model.Bus) -> bool:
        return bus.ftt is not None

    def release_offset(self, m: schema.Message, release: Release, path: Path, ec: int | None) -> int | None:
        kind, period, offset, offset_auto = release
        if ec and kind == "periodic" and (m.window or "sync") == "sync":
            for key, value in (("period", period), ("offset", offset)):
                if value is not None and value % ec:
                    self.r.err(
                        "ec-multiple",
                        f"{key} {format_ns(value)} is not a whole number of elementary cycles "
                        f"({format_ns(ec)}); use a multiple such as {format_ns(max(ec, value // ec * ec))}",
                        (*path, key if key != "period" or m.rate is None else "rate"),
                    )
            if offset is None and not offset_auto:
                offset = 0
        return offset

    def resolve_window(
        self, m: schema.Message, sbus: schema.Bus, kind: MessageKind, path: Path
    ) -> tuple[Literal["sync", "async"] | None, int | None]:
        ftt_id = None
        window = m.window or ("sync" if kind == "periodic" else "async")
        if window == "sync":
            if kind != "periodic":
                self.r.err(
                    "ftt-window",
                    "only periodic messages go in the synchronous window; make it 'window: async' or give it a period",
                    (*path, "window"),
                )
            ftt_id = m.ftt_id  # None -> assigned after all explicit ids are known
        elif m.ftt_id is not None:
            self.r.err("ftt-window", "ftt_id names synchronous messages; this one is asynchronous", (*path, "ftt_id"))
        if window == "async" and m.id is None:
            self.r.err(
                "id-missing",
                "asynchronous FTT-CAN messages need an explicit CAN 'id' (lower = higher "
                "priority in the asynchronous window)",
                path,
            )
        return window, ftt_id

    def reserved_ids(self, bus: model.Bus) -> dict[tuple[bool, int], str]:
        taken: dict[tuple[bool, int], str] = {}
        if bus.ftt is not None:
            taken[(bus.ftt.tm_extended, bus.ftt.tm_id)] = "the FTT-CAN trigger message"
        return taken

    def check_message_id(self, bus: model.Bus, m: model.Message) -> None:
        """The trigger message outranks every other frame: the analyses (and the FTT-CAN papers) start each EC's
        windows when it ends, so a frame that wins arbitration against it would delay every EC it is queued at.
        The TM is a standard frame on every bus (netcfg.protocols.ftt.tm), which for an extended
        bus is the stricter reading too."""
        if bus.ftt is None or arbitration_key(m.id, m.extended) > arbitration_key(bus.ftt.tm_id, bus.ftt.tm_extended):
            return
        tm = f"0x{bus.ftt.tm_id:03X}"
        if self.r.smap.has((*m.path, "id")):
            fix = f"give '{m.name}' an identifier above {tm} or the bus a smaller 'tm_id'"
        else:  # sync_id_base + its FTT id
            fix = f"raise the bus's 'sync_id_base' above {tm}, give '{m.name}' an 'id' above it, or lower 'tm_id'"
        self.r.err(
            "ftt-tm-id",
            f"identifier 0x{m.id:03X} of {m.window or 'the'} message '{m.name}' is at or above the priority of the "
            f"trigger message (tm_id {tm}): the trigger message must have the highest priority on an FTT-CAN bus, "
            f"else a frame queued at an EC's start delays the trigger message and every window after it; {fix}",
            self.r.key_or_item(m.path, "id"),
        )

    # -- triggers and FTT ids ----------------------------------------------------------------------------------
    def resolve_triggers(self) -> None:
        used: dict[tuple[str, int], str] = {}
        for m in self.r.model.messages.values():
            if m.ftt_id is not None:
                key = (m.bus, m.ftt_id)
                if key in used:
                    self.r.err(
                        "duplicate-ftt-id", f"FTT id {m.ftt_id} is already used by '{used[key]}'", (*m.path, "ftt_id")
                    )
                used[key] = m.name
        for i, t in enumerate(self.r.spec.triggers):
            path: Path = ("triggers", i)
            sbus = self.r.spec_buses.get(t.bus)
            bus = self.r.model.buses.get(t.bus)
            if sbus is None or bus is None:
                self.r.err(
                    "unknown-bus",
                    f"bus '{t.bus}' is not defined{did_you_mean(t.bus, self.r.spec_buses)}; "
                    f"known buses: {some_names(self.r.spec_buses)}",
                    (*path, "bus"),
                )
                continue
            if sbus.protocol != "ftt-can":
                self.r.err(
                    "wrong-section",
                    f"triggers are FTT-CAN synchronous triggers; bus '{t.bus}' is {sbus.protocol}",
                    (*path, "bus"),
                )
                continue
            if bus.ftt is None:
                continue
            ec = bus.ftt.ec_ns
            key = (t.bus, t.ftt_id)
            if key in used:
                self.r.err("duplicate-ftt-id", f"FTT id {t.ftt_id} is already used by '{used[key]}'", (*path, "ftt_id"))
            used[key] = t.name
            period = self.r.ns(t.period, (*path, "period"), ec) or 0
            offset = self.r.ns(t.offset, (*path, "offset"), ec) if isinstance(t.offset, Duration) else None
            interval = period
            if t.period_range is not None:
                fastest = self.r.period_range(t.period_range, period, path, ec)
                interval = period if fastest is None else fastest
            for key_name, value in (("period", period), ("offset", offset)):
                if value is not None and value % ec:
                    self.r.err(
                        "ec-multiple",
                        f"{key_name} {format_ns(value)} is not a whole number of elementary cycles ({format_ns(ec)})",
                        (*path, key_name),
                    )
            if period <= 0:
                self.r.err("period", "a trigger period must be at least one EC", (*path, "period"))
            else:
                self.r.check_offset(offset, period, path)
            for j, ref in enumerate(t.tasks):
                node_name, task_name = ref.split(".", 1)
                node = self.r.model.nodes.get(node_name)
                if node is None or task_name not in node.tasks:
                    self.r.err(
                        "unknown-task",
                        f"trigger '{t.name}' activates '{ref}', which is not a task (write node.task)"
                        f"{did_you_mean(ref, self.r.task_refs())}",
                        (*path, "tasks", j),
                    )
                    continue
                if t.bus not in node.buses:
                    self.r.err("not-on-bus", f"node '{node_name}' is not on bus '{t.bus}'", (*path, "tasks", j))
                task = node.tasks[task_name]
                if task.trigger is not None:
                    self.r.err(
                        "task-trigger",
                        f"task '{ref}' is already activated by trigger '{task.trigger}'",
                        (*path, "tasks", j),
                    )
                    continue
                if task.period_ns is not None and task.period_ns != period:
                    self.r.err(
                        "task-trigger",
                        f"task '{ref}' has period {format_ns(task.period_ns)} but its trigger "
                        f"fires every {format_ns(period)}; drop the task's period",
                        (*path, "tasks", j),
                    )
                node.tasks[task_name] = dataclasses.replace(
                    task, period_ns=period, trigger=t.name, offset_ns=offset or 0
                )
            self.r.model.triggers[t.name] = model.Trigger(
                description=t.description,
                name=t.name,
                bus=t.bus,
                ftt_id=t.ftt_id,
                period_ns=period,
                interval_ns=interval,
                slowest_ns=self.r.slowest.get(path),
                offset_ns=offset,
                offset_auto=t.offset == "auto",
                tasks=tuple(t.tasks),
                path=path,
            )
        # Synchronous messages without an explicit FTT id take the lowest free ones, in spec order.
        for bus in self.r.model.buses.values():
            if bus.ftt is None:
                continue
            free = (k for k in range(10_000) if (bus.name, k) not in used)
            for m in bus.messages:
                if m.window == "sync" and m.ftt_id is None:
                    m.ftt_id = next(free)
                    used[(bus.name, m.ftt_id)] = m.name
                if m.window == "sync" and m.id < 0:
                    m.id = self.r.spec_buses[bus.name].ftt.sync_id_base + m.ftt_id  # type: ignore[union-attr,operator]
            capacity = 8 * bus.ftt.tm_size
            for (bname, k), owner in sorted(used.items()):
                if bname == bus.name and k >= capacity:
                    item = self.r.model.messages.get(owner) or self.r.model.triggers.get(owner)
                    path = self.r.key_or_item(item.path, "ftt_id") if item else bus.path
                    self.r.err(
                        "ftt-id-range",
                        f"FTT id {k} of '{owner}' does not fit the {bus.ftt.tm_size}-byte "
                        f"trigger message (ids 0..{capacity - 1}); raise tm_size or renumber",
                        path,
                    )
