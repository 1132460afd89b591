"""Fault phases of a CANopen master's log: what a drill (`run --reset/--kill/--emcy/--stall/--bus-off`, the same in
`simulate --fault`) or a real fault leaves in the log, recognised from CANopen's own evidence and reported as phases
(normal, fault, recovery, normal again) instead of as the gaps they cause.

Recognised, each on one CANopen bus of the configuration:
- reboot: a node's boot-up message (heartbeat COB-ID 0x700 + node id, one byte 0x00, CiA 301 7.2.8.3.2.1) after
  it had sent other frames: the node was silent from its last frame before it to the boot-up. Its recovery, when
  the master set it up again: the SDO frames to and from it after the boot-up, the NMT start the master sent it
  (CiA 301 7.2.8.3.1.1) and its first TPDO after that (it is back in the cycle); without an NMT start it stayed
  PRE-OPERATIONAL: the fault lasts to the log's end.
- lost: a node silent for longer than the master's consumer heartbeat time for it (runtime.json's
  heartbeat_timeout_ns, 0x1016: the spec's own definition of a lost node), from its last frame to its next one
  or the log's end.
- emcy: an EMCY (COB-ID 0x80 + node id) of a node; when the master then sent it (or all nodes) NMT stop or enter
  pre-operational, its PDOs stop by command: the fault lasts until an NMT start of it, or the log's end.
- no SYNC: an interval between two SYNCs more than half a period beyond the period (the rule by which the master
  reports missed SYNC instants, netcfg.runtime.supervision.sync_gap): the master sent nothing (a stalled host, a
  bus-off of its controller: a log cannot tell them apart, and a bus-off master also hears nothing, so its log
  has a hole in every message).

What is not judged inside a fault phase: the gaps (and the shortfall in frames they cause) of the messages the
fault silences: the node's own, and the master's RxPDOs to it (the master stops them); in a no-SYNC phase, every
message of the bus. Everything else is judged as before, inside the phase too.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from netcfg.runtime import RuntimeConfig
from netcfg.runtime.supervision import sync_gap
from netcfg.verify.frames import ERROR, EXTENDED, Batch

NMT_ID = 0x000
NMT_START = 0x01
NMT_STOPPING = (0x02, 0x80)  # stop, enter pre-operational: the node's PDOs stop (CiA 301 7.2.8.3.1.1)
EMCY_BASE = 0x080
TSDO_BASE = 0x580
RSDO_BASE = 0x600
HEARTBEAT_BASE = 0x700
BOOT_UP = 0x00


@dataclass
class FaultPhase:
    kind: str  # "reboot" | "lost" | "emcy" | "no-sync"
    bus: str
    node: str | None  # None: the master's (no SYNC)
    from_us: int  # log time: the fault's start (the node's last frame before it; the last SYNC)
    to_us: int  # its end: the boot-up, the node's return, the first SYNC after
    detail: str
    recovery: dict[str, Any] | None = None  # reboot: what the master did after the boot-up
    back_us: int | None = None  # when the node was in the cycle again (None: not in this log)
    silenced: list[str] = field(default_factory=list)  # the messages whose gaps the fault explains

    def excused_until(self, end_us: int) -> int:
        return self.back_us if self.back_us is not None else end_us

    def report(self, origin_us: int, end_us: int) -> dict[str, Any]:
        out: dict[str, Any] = {
            "kind": self.kind,
            "bus": self.bus,
            "node": self.node,
            "from_us": self.from_us - origin_us,
            "to_us": self.to_us - origin_us,
            "detail": self.detail,
            "back_us": None if self.back_us is None else self.back_us - origin_us,
            "silenced": sorted(self.silenced),
        }
        if self.recovery is not None:
            rec = dict(self.recovery)
            for key in ("started_us", "back_us"):
                if rec.get(key) is not None:
                    rec[key] -= origin_us
            out["recovery"] = rec
        return out


class _Bus:
    """One CANopen bus's nodes and messages, as the scan looks them up by identifier."""

    def __init__(self, cfg: RuntimeConfig, index: int, name: str) -> None:
        bus = cfg.bus(name)
        assert bus.canopen is not None
        self.index, self.name = index, name
        self.master = bus.canopen.sync_producer
        nodes = [n for n in cfg.nodes if n.name in bus.nodes and n.node_id and n.name != self.master]
        self.ids = {n.node_id: n.name for n in nodes}
        self.timeout_us = {n.name: n.heartbeat_timeout_ns // 1000 for n in nodes if n.heartbeat_timeout_ns}
        msgs = cfg.messages_on(name)
        sync = next((m for m in msgs if m.implicit == "SYNC"), None)
        self.sync_id = None if sync is None else sync.id
        self.period_s = bus.canopen.sync_period_ns / 1e9
        self.names = [n.name for n in nodes]
        self.index_of = {n.node_id: k for k, n in enumerate(nodes)}  # node id -> its index in names
        # identifier -> the node whose frames it carries (its own messages, its services), -1 for none
        self.lut = np.full(0x800, -1, np.int64)
        self.tpdo = np.zeros(0x800, bool)
        for k, n in enumerate(nodes):
            assert n.node_id is not None
            for base in (EMCY_BASE, TSDO_BASE, HEARTBEAT_BASE):
                self.lut[base + n.node_id] = k
        for m in msgs:
            if m.extended or m.producer not in self.names:
                continue
            self.lut[m.id] = self.names.index(m.producer)
            self.tpdo[m.id] = m.pdo is not None and m.pdo.kind == "tpdo"
        # what a node's fault silences: its own messages and the master's RxPDOs to it
        self.silences = {
            n: [
                m.name
                for m in msgs
                if m.producer == n or (m.producer == self.master and m.pdo is not None and n in m.consumers)
            ]
            for n in self.names
        }
        self.all_messages = [m.name for m in msgs]


class FaultScan:
    """Fed the log's batches in time order (the first of verify's two reads); finish() -> the fault phases."""

    def __init__(self, cfg: RuntimeConfig, bus_of_channel: Any) -> None:
        """`bus_of_channel(channel array) -> CAN bus index array` (the checker's own mapping, -1 unknown)."""
        can_buses = [b for b in cfg.buses if b.is_can]
        self.buses = {i: _Bus(cfg, i, b.name) for i, b in enumerate(can_buses) if b.canopen is not None}
        self.bus_of = bus_of_channel
        self.last: dict[tuple[int, int], int] = {}  # (bus, node) -> its last frame's time
        self.last_tpdo: dict[tuple[int, int], int] = {}
        self.silences: list[tuple[int, int, int, int]] = []  # (bus, node, from, to)
        self.boots: list[tuple[int, int, int | None, int]] = []  # (bus, node, last frame before, boot-up)
        self.nmt: list[tuple[int, int, int, int]] = []  # (bus, time, command, target node id)
        self.emcy: list[tuple[int, int, int, int]] = []  # (bus, node, time, code)
        self.sdo: dict[tuple[int, int], list[int]] = {}  # (bus, node) -> SDO frame times after a boot-up of it
        self.tpdo_back: dict[tuple[int, int], list[int]] = {}  # (bus, node) -> TPDOs after > 1.5 periods without
        self.last_sync: dict[int, int] = {}
        self.sync_gaps: list[tuple[int, int, int, str]] = []  # (bus, from, to, text)
        self.end_us: int | None = None
        self.start_us: int | None = None  # the log's first frame: the report's times count from it

    def take(self, batch: Batch) -> None:
        if not len(batch) or not self.buses:
            return
        plain = (batch.flags & (ERROR | EXTENDED)) == 0
        bus_idx = self.bus_of(batch.channel)
        self.end_us = int(batch.t_us[-1])
        if self.start_us is None:
            self.start_us = int(batch.t_us[0])
        for b, cb in self.buses.items():
            rows = np.flatnonzero(plain & (bus_idx == b) & (batch.can_id < 0x800))
            if not len(rows):
                continue
            t, ids = batch.t_us[rows], batch.can_id[rows]
            data = batch.data[rows]
            self._sync(b, cb, t[ids == cb.sync_id] if cb.sync_id is not None else t[:0])
            for k in np.flatnonzero(ids == NMT_ID):
                self.nmt.append((b, int(t[k]), int(data[k, 0]), int(data[k, 1])))
            # the master's SDO requests to a node count as its recovery's too
            rsdo = (ids & 0x780) == RSDO_BASE
            node = np.where(rsdo, -1, cb.lut[ids])
            for k in np.flatnonzero(rsdo):
                n = cb.index_of.get(int(ids[k]) & 0x7F)
                if n is not None and (b, n) in self.sdo:
                    self.sdo[(b, n)].append(int(t[k]))
            for n in np.unique(node[node >= 0]).tolist():
                self._node(b, cb, n, t[node == n], ids[node == n], data[node == n])

    def _sync(self, b: int, cb: _Bus, t: np.ndarray) -> None:
        if not len(t):
            return
        prev = np.concatenate([[self.last_sync[b]], t]) if b in self.last_sync else t
        self.last_sync[b] = int(t[-1])
        iv = np.diff(prev)
        for k in np.flatnonzero(iv > 1.5e6 * cb.period_s):
            self.sync_gaps.append((b, int(prev[k]), int(prev[k + 1]), ""))

    def _node(self, b: int, cb: _Bus, n: int, t: np.ndarray, ids: np.ndarray, data: np.ndarray) -> None:
        key = (b, n)
        name = cb.names[n]
        prev = np.concatenate([[self.last[key]], t]) if key in self.last else t
        timeout = cb.timeout_us.get(name)
        if timeout is not None and len(prev) > 1:
            iv = np.diff(prev)
            for k in np.flatnonzero(iv > timeout):
                self.silences.append((b, n, int(prev[k]), int(prev[k + 1])))
        boot = ((ids & 0x780) == HEARTBEAT_BASE) & (data[:, 0] == BOOT_UP)
        shift = 1 if key in self.last else 0  # frame k of the batch is prev[k + shift]
        for k in np.flatnonzero(boot):
            before = int(prev[k + shift - 1]) if k + shift > 0 else None
            self.boots.append((b, n, before, int(t[k])))
            self.sdo.setdefault(key, [])
        for k in np.flatnonzero((ids & 0x780) == EMCY_BASE):
            self.emcy.append((b, n, int(t[k]), int(data[k, 0]) | int(data[k, 1]) << 8))
        if key in self.sdo:
            self.sdo[key].extend(t[(ids & 0x780) == TSDO_BASE].tolist())
        tp = t[cb.tpdo[ids]]
        if len(tp):
            tprev = np.concatenate([[self.last_tpdo[key]], tp]) if key in self.last_tpdo else tp
            back = tprev[np.flatnonzero(np.diff(tprev) > 1.5e6 * cb.period_s) + 1].tolist()
            if key not in self.last_tpdo:
                back.insert(0, int(tp[0]))  # its first: it started
            self.tpdo_back.setdefault(key, []).extend(back)
            self.last_tpdo[key] = int(tp[-1])
        self.last[key] = int(t[-1])

    def finish(self, span: tuple[int, int] | None) -> list[FaultPhase]:
        """The fault phases inside the cyclic span (a master's set-up and shut-down are phases of their own), or
        the whole log without one, in time order."""
        end, origin = self.end_us or 0, self.start_us or 0
        lo, hi = span if span is not None else (-(1 << 62), 1 << 62)
        inside = lambda t: lo <= t <= hi  # noqa: E731
        phases: list[FaultPhase] = []
        covered: set[tuple[int, int, int]] = set()  # (bus, node, boot or silence end) already told
        for b, n, before, boot in self.boots:
            if not inside(boot) or before is None:
                continue
            phases.append(self._reboot(b, n, before, boot, end))
            covered.add((b, n, boot))
        for b, n, t0, t1 in self.silences:
            cb = self.buses[b]
            if not inside(t0) or (b, n, t1) in covered:
                continue
            name = cb.names[n]
            phases.append(
                FaultPhase(
                    "lost", cb.name, name, t0, t1,
                    f"{name} silent for {(t1 - t0) / 1000:.1f} ms, beyond the master's consumer heartbeat time "
                    f"{cb.timeout_us[name] / 1000:g} ms: lost, then heard again",
                    back_us=t1, silenced=cb.silences[name],
                )
            )
        for b, n in self.last:  # a node silent to the end
            cb, t0 = self.buses[b], self.last[(b, n)]
            name = cb.names[n]
            timeout = cb.timeout_us.get(name)
            if timeout is not None and end - t0 > timeout and inside(t0):
                phases.append(
                    FaultPhase(
                        "lost", cb.name, name, t0, end,
                        f"{name} silent from {(t0 - origin) / 1e6:.6f} s to the end of the log, beyond the master's "
                        f"consumer heartbeat time {timeout / 1000:g} ms: lost",
                        silenced=cb.silences[name],
                    )
                )
        for b, n, t, code in self.emcy:
            if inside(t):
                phases.append(self._emcy(b, n, t, code, end))
        for b, t0, t1, _ in self.sync_gaps:
            cb = self.buses[b]
            found = sync_gap((t0 - origin) / 1e6, (t1 - origin) / 1e6, cb.period_s, 0.0)
            if found is None:
                continue
            text = found[1]
            if inside(t0) and t1 <= hi:
                phases.append(
                    FaultPhase(
                        "no-sync", cb.name, None, t0, t1,
                        f"{text.split(';')[0]}: the master sent nothing, its loop held up (a host that ran late "
                        "or stalled) or its controller bus-off; a log cannot tell which",
                        back_us=t1, silenced=cb.all_messages,
                    )
                )
        # times in the details count from the log's start: the caller shifts them (report)
        return sorted(phases, key=lambda p: (p.from_us, p.kind))

    def _reboot(self, b: int, n: int, before: int, boot: int, end: int) -> FaultPhase:
        cb = self.buses[b]
        name = cb.names[n]
        node_id = next(i for i, x in cb.ids.items() if x == name)
        start = next((t for bb, t, cmd, target in self.nmt if bb == b and t > boot and cmd == NMT_START
                      and target in (0, node_id)), None)
        back = None if start is None else next((t for t in self.tpdo_back.get((b, n), []) if t > start), None)
        sdo = [t for t in self.sdo.get((b, n), []) if t > boot and (back is None or t <= back)]
        if start is None:
            recovery = {"result": "left stopped (PRE-OPERATIONAL): no NMT start after the boot-up",
                        "sdo_frames": len(sdo), "started_us": None, "back_us": None, "took_ms": None}
        else:
            took = None if back is None else round((back - boot) / 1000, 3)
            recovery = {
                "result": "re-configured, started and back in the cycle" if back is not None
                else "re-configured and started; no TPDO of it after that in this log",
                "sdo_frames": len(sdo), "started_us": start, "back_us": back, "took_ms": took,
            }
        return FaultPhase(
            "reboot", cb.name, name, before, boot,
            f"{name} silent for {(boot - before) / 1000:.1f} ms, then its boot-up message: it rebooted",
            recovery=recovery, back_us=back, silenced=cb.silences[name],
        )

    def _emcy(self, b: int, n: int, t: int, code: int, end: int) -> FaultPhase:
        cb = self.buses[b]
        name = cb.names[n]
        node_id = next(i for i, x in cb.ids.items() if x == name)
        stop = next((x for bb, x, cmd, target in self.nmt if bb == b and x >= t and cmd in NMT_STOPPING
                     and target in (0, node_id)), None)
        if stop is None:
            return FaultPhase("emcy", cb.name, name, t, t, f"{name} sent EMCY 0x{code:04X}; the master did not stop it",
                              back_us=t)
        start = next((x for bb, x, cmd, target in self.nmt if bb == b and x > stop and cmd == NMT_START
                      and target in (0, node_id)), None)
        return FaultPhase(
            "emcy", cb.name, name, t, stop,
            f"{name} sent EMCY 0x{code:04X}; the master stopped it {(stop - t) / 1000:.1f} ms later (NMT)"
            + ("" if start is None else ", and started it again"),
            back_us=start, silenced=cb.silences[name],
        )


def excused_spans(phases: Iterable[FaultPhase], end_us: int) -> dict[str, list[tuple[int, int]]]:
    """Message -> the log spans in which its absence is a fault phase's doing."""
    out: dict[str, list[tuple[int, int]]] = {}
    for p in phases:
        for name in p.silenced:
            out.setdefault(name, []).append((p.from_us, p.excused_until(end_us)))
    return out


def sequence(
    phases: list[FaultPhase], span: tuple[int, int] | None, start_us: int, end_us: int
) -> list[dict[str, Any]]:
    """The log as phases in time order (log times; the caller shifts them): set-up, normal operation, each fault
    and its recovery, normal again, shut-down."""
    out: list[dict[str, Any]] = []
    lo, hi = span if span is not None else (start_us, end_us)
    if span is not None:
        out.append({"phase": "set-up", "from_us": start_us, "to_us": lo})
    at = lo
    for p in phases:
        if p.from_us > at:
            out.append({"phase": "normal", "from_us": at, "to_us": p.from_us})
        what = p.node or "the master"
        out.append({"phase": "fault", "kind": p.kind, "node": p.node, "from_us": p.from_us, "to_us": p.to_us,
                    "detail": p.detail})
        if p.recovery is not None or (p.back_us is not None and p.back_us > p.to_us):
            left = p.recovery is not None and p.recovery.get("started_us") is None
            rec: dict[str, Any] = {"phase": "stopped" if left else "recovery", "node": p.node, "from_us": p.to_us,
                                   "to_us": p.back_us if p.back_us is not None else hi}
            rec["detail"] = _recovery_text(p) if p.recovery is not None else f"{what} back at the end of the phase"
            out.append(rec)
        at = max(at, p.back_us if p.back_us is not None else hi, p.to_us)
    if at < hi:
        out.append({"phase": "normal", "from_us": at, "to_us": hi})
    if span is not None:
        out.append({"phase": "shut-down", "from_us": hi, "to_us": end_us})
    return out


def _recovery_text(p: FaultPhase) -> str:
    rec = p.recovery or {}
    if rec.get("started_us") is None:
        return f"{p.node} {rec.get('result')}"
    took = "" if rec.get("took_ms") is None else f" in {rec['took_ms']:g} ms after its boot-up"
    return f"{p.node} {rec['result']}{took} ({rec['sdo_frames']} SDO frames, NMT start)"


def add_fault_phases(
    report: dict[str, Any], faults: list[FaultPhase], span: tuple[int, int] | None, origin_us: int, end_us: int
) -> None:
    """Into verify's report: `fault_phases` (each fault, report times), `phase_sequence` (the log as phases),
    `fault_count`; a log with a fault is not ok (the system did not run as specified), its gaps inside the fault
    phases are not violations."""
    report["fault_phases"] = [p.report(origin_us, end_us) for p in faults]
    start = origin_us if span is None else min(origin_us, span[0])
    seq = sequence(faults, span, start, max(end_us, span[1] if span is not None else end_us))
    for item in seq:
        item["from_us"] -= origin_us
        item["to_us"] -= origin_us
    report["phase_sequence"] = seq
    report["fault_count"] = len(faults)
    report["ok"] = report["ok"] and not faults
