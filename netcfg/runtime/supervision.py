"""Supervision of a CANopen network by its master: heartbeat consumer and EMCY consumer, driven by runtime.json.

A `Supervisor` is fed every frame the master cycle does not take itself (`feed(frame, t)`) and asked, once per
cycle or more often, whether a node has gone quiet (`check(t)`). Frames go to the `canopen` package's own consumers
(canopen.nmt.NmtMaster.on_heartbeat for the heartbeat and NMT state, canopen.emcy.EmcyConsumer.on_emcy to decode an
emergency: error code, error register, manufacturer bytes), called directly with the master clock's time instead of
from a Notifier thread, so supervision runs in the master's own loop, in real or virtual time alike.

What is supervised comes from runtime.json: a node with `heartbeat_timeout_ns` (its consumer heartbeat time, 0x1016
in the master's DCF) is lost when no heartbeat arrived for that long, counted from the supervision's start or its
last heartbeat; `on_loss` and `on_emcy` say what the master does then (`stop_all`, `stop_node`, `continue`). A
lost node is reported once; a heartbeat after that is reported as its return. A boot-up message (the heartbeat
COB-ID with one byte 0x00, CiA 301) is no return: the node reset and lost its configuration; it is reported as a
"boot-up" event with the node's `on_reboot` (`recover`, `stop_node`, `stop_all`), lost or not before.
Detection happens when check() runs:
a master that checks once per SYNC period T reports a loss between the consumer time and the consumer time + T
after the last heartbeat.

An event-driven TxPDO (transmission type 254/255) with an event timer must come at least once per event timer
(CiA 301 7.3.3: the timer sends it when nothing else has); counted from the supervision's start or its last frame,
the master allows the timer plus the analysed worst-case response time (runtime.json's wcrt_ns: the frame queued at
the expiry may wait that long for the bus) and reports a TPDO silent beyond that once, as a "tpdo-silent" event
(action "continue": the master cannot tell a drive's stale data from a quiet one, it says so). A node found lost or
stopped is not reported again for its TPDOs.

It imports only the standard library, python-can (types), canopen and netcfg.runtime.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import can
from canopen.emcy import EMCY_STRUCT, EmcyConsumer, EmcyError
from canopen.nmt import NmtMaster

from netcfg import cia301
from netcfg.runtime import Bus, RuntimeConfig

__all__ = ["ACTIONS", "REBOOT_ACTIONS", "EmcyRecord", "Event", "Supervisor", "bus_back", "sync_gap"]

BUS_OFF_TEXT = "the master's CAN controller is bus-off: it stops sending and waits for the bus"

ACTIONS = ("stop_all", "stop_node", "continue")
REBOOT_ACTIONS = ("recover", "stop_node", "stop_all")
BOOT_UP = 0x00  # CiA 301 7.2.8.3.2.1: the boot-up message is the heartbeat COB-ID with the one byte 0


@dataclass(frozen=True)
class EmcyRecord:
    """One emergency as received, decoded by canopen's EmcyError."""

    time: float  # master clock, seconds
    code: int
    register: int
    vendor: bytes
    description: str  # CiA 301's error code class ("Current", "Monitoring", ...)

    def __str__(self) -> str:
        desc = f" ({self.description})" if self.description else ""
        return (
            f"EMCY 0x{self.code:04X}{desc}, error register 0x{self.register:02X}, vendor bytes {self.vendor.hex(' ')}"
        )

    def as_json(self) -> dict[str, object]:
        return {
            "code": self.code,
            "register": self.register,
            "vendor": self.vendor.hex(),
            "description": self.description,
        }


@dataclass(frozen=True)
class Event:
    """Something the master must react to: a node lost or back, or an EMCY; `action` is the spec's reaction."""

    time: float
    node: str
    kind: str  # "lost" | "back" | "emcy" | "tpdo-silent" | "boot-up", and the master's own (netcfg.runtime.operate)
    action: str  # stop_all | stop_node | continue | recover
    text: str


@dataclass
class _Watched:
    name: str
    node_id: int
    timeout_s: float | None
    on_loss: str
    on_emcy: str
    on_reboot: str
    nmt: NmtMaster
    emcy: EmcyConsumer
    last_heartbeat: float | None = None
    lost_at: float | None = None
    silent_for_s: float | None = None  # at the loss: time since the last heartbeat (or since supervision began)
    emcys: list[EmcyRecord] = field(default_factory=list)


@dataclass
class _Timed:
    """An event-driven TxPDO with an event timer: due within `limit_s` of its last frame."""

    name: str
    node: str
    limit_s: float
    timer_ms: int
    last: float | None = None
    silent: bool = False  # reported, not yet heard again


class Supervisor:
    def __init__(self, cfg: RuntimeConfig, bus: Bus, nodes: list[str] | None = None) -> None:
        self.bus = bus
        self.watched: dict[str, _Watched] = {}
        self.timed: dict[tuple[int, bool], _Timed] = {}  # (CAN id, extended) -> an event-timer TxPDO
        self.quiet: set[str] = set()  # nodes the master stopped: their TPDOs are not expected
        self._by_id: dict[int, _Watched] = {}
        self.started: float | None = None
        self.events: list[Event] = []
        self.bad_emcy = 0  # EMCY frames of another length than CiA 301's 8 bytes
        for name in nodes if nodes is not None else bus.nodes:
            node = cfg.node(name)
            if node.role == "master" or node.node_id is None:
                continue
            for action in (node.on_loss, node.on_emcy):
                if action not in ACTIONS:
                    raise ValueError(f"node '{name}': '{action}' is no action; write one of {', '.join(ACTIONS)}")
            if node.on_reboot not in REBOOT_ACTIONS:
                choices = ", ".join(REBOOT_ACTIONS)
                raise ValueError(f"node '{name}': on_reboot '{node.on_reboot}' is no action; write one of {choices}")
            timeout = None if node.heartbeat_timeout_ns is None else node.heartbeat_timeout_ns / 1e9
            w = _Watched(
                name,
                node.node_id,
                timeout,
                node.on_loss,
                node.on_emcy,
                node.on_reboot,
                NmtMaster(node.node_id),
                EmcyConsumer(),
            )
            self.watched[name] = w
            self._by_id[node.node_id] = w
        for m in cfg.messages_on(bus.name):
            p = m.pdo
            if p is None or p.kind != "tpdo" or p.transmission < 254 or not p.event_timer_ms:
                continue
            if p.node in self.watched and any(cfg.node(c).role == "master" for c in m.consumers):
                limit_ns = p.event_timer_ms * 1_000_000 + (m.wcrt_ns or 0)
                self.timed[(m.id, m.extended)] = _Timed(m.name, p.node, limit_ns / 1e9, p.event_timer_ms)

    def start(self, t: float) -> None:
        """Supervision begins: every supervised node must send a heartbeat within its consumer time from now."""
        self.started = t

    def resume(self, t: float) -> None:
        """The master could hear nothing for a while (its controller was bus-off): every clock restarts at t, as at
        the start, for nodes not already lost."""
        for w in self.watched.values():
            if w.lost_at is None:
                w.last_heartbeat = None
        for timed in self.timed.values():
            timed.last = None
        self.started = t

    def feed(self, frame: can.Message, t: float) -> bool:
        """Hand one frame to the consumers; True when it was a heartbeat or an EMCY of a supervised node or an
        event-timer TxPDO."""
        if frame.is_error_frame or frame.is_remote_frame:
            return False
        timed = self.timed.get((frame.arbitration_id, bool(frame.is_extended_id)))
        if timed is not None:
            timed.last, timed.silent = t, False
            return True
        if frame.is_extended_id:
            return False
        can_id, data = frame.arbitration_id, bytes(frame.data)
        if cia301.HEARTBEAT_BASE < can_id <= cia301.HEARTBEAT_BASE + 127 and len(data) >= 1:
            w = self._by_id.get(can_id - cia301.HEARTBEAT_BASE)
            if w is None:
                return False
            w.nmt.on_heartbeat(can_id, data, t)
            w.last_heartbeat = t
            if data[0] == BOOT_UP:  # it rebooted: whatever the master configured is gone
                w.lost_at = None
                self.events.append(
                    Event(
                        t,
                        w.name,
                        "boot-up",
                        w.on_reboot,
                        f"{w.name} (node {w.node_id}) rebooted: boot-up message, its configuration is gone",
                    )
                )
                return True
            if w.lost_at is not None:
                w.lost_at = None
                self.events.append(
                    Event(t, w.name, "back", "continue", f"{w.name}: heartbeat again ({self.state(w.name)})")
                )
            return True
        if cia301.EMCY_BASE < can_id <= cia301.EMCY_BASE + 127:
            w = self._by_id.get(can_id - cia301.EMCY_BASE)
            if w is None:
                return False
            if len(data) != EMCY_STRUCT.size:
                self.bad_emcy += 1
                return True
            got: list[EmcyError] = []
            w.emcy.callbacks = [got.append]
            w.emcy.on_emcy(can_id, data, t)
            for err in got:
                record = EmcyRecord(t, err.code, err.register, bytes(err.data), err.get_desc())
                w.emcys.append(record)
                if err.code & 0xFF00 == 0:
                    text = f"{w.name}: error reset (EMCY 0x{err.code:04X})"
                    self.events.append(Event(t, w.name, "emcy", "continue", text))
                else:
                    self.events.append(Event(t, w.name, "emcy", w.on_emcy, f"{w.name}: {record}"))
            return True
        return False

    def check(self, t: float) -> list[Event]:
        """Nodes whose heartbeat is overdue at time t, reported once each (also appended to `events`)."""
        found = []
        for w in self.watched.values():
            if w.timeout_s is None or w.lost_at is not None:
                continue
            since = w.last_heartbeat if w.last_heartbeat is not None else self.started
            # compared in whole nanoseconds: 0.4 - 0.1 s in floats is a hair over 0.3 s
            if since is None or round((t - since) * 1e9) <= round(w.timeout_s * 1e9):
                continue
            w.lost_at, w.silent_for_s = t, t - since
            what = "no heartbeat" if w.last_heartbeat is not None else "no heartbeat since supervision began"
            event = Event(
                t,
                w.name,
                "lost",
                w.on_loss,
                f"{w.name} (node {w.node_id}) lost: {what} for {1e3 * (t - since):.1f} ms "
                f"(consumer heartbeat time {1e3 * w.timeout_s:.0f} ms)",
            )
            found.append(event)
        for timed in self.timed.values():
            since = timed.last if timed.last is not None else self.started
            if timed.silent or since is None or timed.node in self.quiet or self.watched[timed.node].lost_at:
                continue
            if round((t - since) * 1e9) <= round(timed.limit_s * 1e9):
                continue
            timed.silent = True
            found.append(
                Event(
                    t,
                    timed.node,
                    "tpdo-silent",
                    "continue",
                    f"{timed.name} ({timed.node}) silent for {1e3 * (t - since):.1f} ms, beyond its event timer of "
                    f"{timed.timer_ms} ms and its worst-case response time ({1e3 * timed.limit_s:.1f} ms in all)",
                )
            )
        self.events += found
        return found

    def state(self, name: str) -> str:
        """The NMT state the node's last heartbeat announced (canopen's names), 'LOST' or 'UNKNOWN'."""
        w = self.watched[name]
        if w.lost_at is not None:
            return "LOST"
        if w.nmt.timestamp is None:
            return "UNKNOWN"
        return w.nmt.state

    def lost(self, name: str) -> bool:
        return self.watched[name].lost_at is not None


def sync_gap(last_s: float, sync_s: float, period_s: float, first_s: float) -> tuple[dict[str, object], str] | None:
    """SYNC instants that passed without a SYNC between two SYNCs sent at last_s and sync_s: a SYNC more than half
    a period after its instant means the master's loop was held (a stalled host, a bus-off). -> (the JSON record
    of `sync_gaps`, the event's text), times from first_s; None when no instant was missed."""
    gap = sync_s - last_s
    missed = round(gap / period_s) - 1
    if missed < 1:
        return None
    instants = [round(last_s - first_s + k * period_s, 6) for k in range(1, missed + 1)]
    from_s, to_s = last_s - first_s, sync_s - first_s
    record: dict[str, object] = {
        "from_s": round(from_s, 6), "to_s": round(to_s, 6), "missed": missed, "instants_s": instants
    }
    text = (
        f"no SYNC for {1e3 * gap:.1f} ms ({from_s:.3f} s to {to_s:.3f} s): {missed} SYNC instants of the "
        f"{1e3 * period_s:g} ms period missed; the cycle resumed"
    )
    return record, text


def bus_back(detected_s: float, back_s: float, sync_s: float, first_s: float) -> tuple[dict[str, object], str]:
    """A bus-off the master rode out, detected at detected_s, the bus back at back_s, the first SYNC after it at
    sync_s: (the JSON record of `bus_offs`, the "bus-on" event's text), times from first_s."""
    off_ms, recovery_ms = 1e3 * (back_s - detected_s), 1e3 * (sync_s - back_s)
    record: dict[str, object] = {
        "detected_s": round(detected_s - first_s, 6),
        "back_s": round(back_s - first_s, 6),
        "first_sync_s": round(sync_s - first_s, 6),
        "off_ms": round(off_ms, 3),
        "recovery_ms": round(recovery_ms, 3),
    }
    text = (
        f"the bus is back after {off_ms:.1f} ms off (detected at {detected_s - first_s:.3f} s); the first SYNC "
        f"went out {recovery_ms:.1f} ms after its return"
    )
    return record, text
