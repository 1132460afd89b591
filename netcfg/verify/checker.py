"""The checker: CAN frames, in time order, held against a runtime configuration and its analysed bounds.

One implementation for every source of frames: `netcfg verify` (a recorded log), `netcfg simulate --log` (the
simulator's own trace) and a live master. Feed it Batches (netcfg.verify.frames) or python-can Messages as they
come; `finish()` gives the JSON document of `netcfg verify --format json`. Memory is bounded by the configuration,
not the log: per message a few running figures and fixed-bin histograms, per bus one number per load window, and
at most MAX_VIOLATIONS violations in detail (all of them counted).

What is a violation (each names the message, the log time and by how much):
- `gap`: a periodic message skipped periods: an interval nearer to k >= 2 periods than to k - 1 and longer than
  the analysis allows for k - 1 (a log cannot tell a frame later than half a period from a missing one); also at
  the end of the log.
- `rate`: a periodic message came fewer times over its span than its period needs (less the clock tolerance), beyond
  what the gaps explain: a sender running at a longer period.
- `late`: a response the log can measure exceeds the analysed worst case. On a CANopen bus a synchronous TPDO's
  response is measured from the SYNC before it (the analysis' reference for it, netcfg.timing.canopen_sync), on
  FTT-CAN a synchronous message's from the start of its elementary cycle (the trigger message's end less its
  shortest transmission time), an actuator's reply from its command's frame before it (netcfg.runtime.actuator_plan).
- `early`: a sporadic message came sooner after the previous one than its minimum inter-arrival time allows (less
  the jitter the analysis grants it): the analysed load assumed no more.
- `unknown_id`: an identifier the configuration does not have (one per identifier, with its count); CANopen service
  identifiers (NMT, SYNC, TIME, EMCY, SDO, heartbeat, LSS) of the bus's nodes are known (netcfg.verify.canopen).
- `never_seen`: a periodic or sporadic message with no frame in the log.
- `size`: a frame whose payload length is not the message's size (or a CAN FD or remote frame on its identifier).
- `range`: a decoded signal outside the limits the spec gives it (one per signal, with the count and worst value).
- `load`: a load window carried more bits than the analysis allows in any window of that length.
- `error_frames`: a bus's error frames came faster than its error model allows (n + ceil(t / T_err) in any window
  t, netcfg.timing.can_errors), or at all on a bus that states none: the analysis then does not bound the log.

A periodic message's interval is compared with its period +- (worst-case response - its best transmission time)
as well: the analysed response counts from the nominal release and holds the release jitter (for a message a task
sends, that task's spread), and the CANopen master's SYNC jitter is added for the SYNC. Being outside is a warning,
not a violation, unless `strict`: a log does not show when a frame was queued, so a long interval is either a late
frame or release jitter the spec does not declare.

This module routes the frames to their messages and buses and checks what spans messages (load, error frames,
unknown identifiers); each message's own checks and figures are netcfg.verify.message_checks'.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from netcfg import protocols
from netcfg.cia301 import sync_every
from netcfg.runtime import Bus, Message, RuntimeConfig
from netcfg.runtime.actuator_plan import reply_commands
from netcfg.timing.can_errors import first_breach
from netcfg.timing.frames import CAN_MAX_PAYLOAD, CANFD_MAX_PAYLOAD, frame_bits
from netcfg.timing.load import exact_rate, frame_timing, rate_hz
from netcfg.verify.canopen import ServiceLog
from netcfg.verify.frames import BRS, ERROR, EXTENDED, FD, REMOTE, Batch, ChannelTable, batch_from_messages
from netcfg.verify.message_checks import HIST_BINS, MAX_VIOLATIONS, MessageState, id_text

if TYPE_CHECKING:
    import can

    from netcfg.verify.host_clock import HostFinding

__all__ = ["MAX_VIOLATIONS", "Checker", "VerifyError"]

DEFAULT_WINDOW_US = 100_000

class VerifyError(ValueError):
    """The configuration and the log cannot be matched (e.g. which bus a channel is); a usage problem."""



class Checker:
    """Feed Batches (or python-can Messages, feed_messages) in time order; then finish().

    `channels` is the reader's channel-name list (it grows as the reader meets new ones); without it the checker
    keeps its own, for feed_messages. A channel whose name is a bus name belongs to that bus; `bus` maps other
    channel names to buses ({"1": "motion"}), or names the one bus every other channel belongs to; a system with
    one CAN bus needs neither."""

    def __init__(
        self,
        cfg: RuntimeConfig,
        channels: list[str] | None = None,
        bus: str | Mapping[str, str] | None = None,
        window_us: int = DEFAULT_WINDOW_US,
        strict: bool = False,
        clock_tolerance_ppm: float | None = None,
    ) -> None:
        self.cfg = cfg
        self.clock_tolerance_ppm = clock_tolerance_ppm  # None: each bus's, as the analysis took it
        self._table = ChannelTable()
        self.channels = channels if channels is not None else self._table.names
        self.strict = strict
        self.window_us = window_us
        self.buses: list[Bus] = [b for b in cfg.buses if b.is_can]
        if not self.buses:
            raise VerifyError(f"{cfg.system} has no CAN bus; verify checks CAN logs")
        self.forced_bus: int | None = None
        self.channel_map: dict[str, int] = {}
        for channel, name in ({"": bus} if isinstance(bus, str) else dict(bus or {})).items():
            cfg.bus(name)  # names close matches when unknown
            if not cfg.bus(name).is_can:
                raise VerifyError(f"bus '{name}' is {cfg.bus(name).protocol}; verify checks CAN buses")
            index = [b.name for b in self.buses].index(name)
            if channel:
                self.channel_map[channel] = index
            else:
                self.forced_bus = index
        self._channel_bus: list[int] = []
        self.states: list[MessageState] = []
        keys: list[int] = []
        own_frames = [f for b in self.buses for f in protocols.of(b).log_frames(b)]
        for m in [*cfg.messages, *own_frames]:
            if not m.is_can:
                continue
            b = [x.name for x in self.buses].index(m.bus)
            self.states.append(self._state(m, b))
            keys.append(_key(b, m.id, m.extended) | (REMOTE_KEY if m.remote else 0))
        # an actuator's reply answers its command: its response is measured from the command's frame before it,
        # the reference keyed past the buses' own (its command's state index + the number of buses)
        by_name, answers = {st.msg.name: i for i, st in enumerate(self.states)}, reply_commands(cfg)
        self._ref_state: dict[int, int] = {}
        for st in self.states:
            cmd = by_name.get(answers.get(st.msg.name, ""))
            if cmd is not None and self.states[cmd].bus == st.bus:
                st.response_ref, st.ref_key = "command", len(self.buses) + cmd
                self._ref_state[st.ref_key] = cmd
                st.responses.edges = np.linspace(0.0, 2.0 * (st.wcrt_us or 1.0), HIST_BINS + 1)
        order = np.argsort(np.array(keys, np.int64), kind="stable")
        self._keys = np.array(keys, np.int64)[order]
        self._key_state = order
        self._any_remote = any(k & REMOTE_KEY for k in keys)
        # per bus the message a response is measured from (CANopen's SYNC, FTT-CAN's trigger message), and what is
        # added back to its logged end to reach the analysis' reference (Protocol.response_reference)
        self._ref_offset: dict[int, int] = {}
        for b, bus_ in enumerate(self.buses):
            ref_id, self._ref_offset[b] = protocols.of(bus_).response_reference(bus_) or (None, 0)
            for i, st in enumerate(self.states):
                if st.bus == b and st.msg.id == ref_id and not st.msg.extended:
                    self._ref_state[b] = i
        self._last_ref: dict[int, int] = {}
        self.frames = 0
        self.unjudged = 0  # frames of a master's set-up and shut-down (note_services)
        self.error_frames = 0
        self.error_ns: list[list[int]] = [[] for _ in self.buses]  # per bus: its error frames' instants
        self.unplaced_error_ns: list[int] = []  # error frames without a channel: held against every bus
        self.first_t: int | None = None  # the first judged frame's time (load windows count from it)
        self.origin_t: int | None = None  # the log's first frame's: report times count from it
        self.last_t: int | None = None
        self.window_ns: list[NDArray[np.int64]] = [np.zeros(0, np.int64) for _ in self.buses]  # busy time per window
        self.unknown: dict[tuple[int, int, bool], list[int]] = {}  # (bus, id, extended) -> [count, first_t]
        self.services = {
            b: ServiceLog({n.node_id: n.name for n in cfg.nodes if n.name in bus_.nodes and n.node_id})
            for b, bus_ in enumerate(self.buses)
            if bus_.canopen is not None
        }
        self.violations: list[dict[str, Any]] = []
        self.violation_count: dict[str, int] = {}
        self.warnings: list[dict[str, Any]] = []
        self.warning_count = 0
        self._frame_ns: dict[int, int] = {}  # kind of frame (_frames_ns) -> its worst-case time
        self.host_clock: HostFinding | None = None  # a host stamped the log: what its lateness is called

    def excuse(self, spans: Mapping[str, list[tuple[int, int]]]) -> None:
        """Message -> log spans of fault phases that silence it: its gaps there are the fault's, not violations."""
        for st in self.states:
            st.excused = list(spans.get(st.msg.name, ()))

    def _state(self, m: Message, bus: int) -> MessageState:
        timing = frame_timing(m, self.buses[bus].bitrate, self.buses[bus].data_bitrate)
        best_tx_us = timing.nominal_ns / 1000
        wcrt_us = None if m.wcrt_ns is None else m.wcrt_ns / 1000
        # the analysed response counts from the nominal release and includes the queuing jitter (Davis et al.
        # 2007, eq. 13: R = J + w + C), so frames lie within [C_best, R] after their nominal instants
        slack = self._unanalysed_jitter_ns(m, bus) / 1000 + max(0.0, (wcrt_us or m.jitter_ns / 1000) - best_tx_us)
        period = None
        min_gap = None
        if m.kind == "periodic" and m.period_ns:
            exact = exact_rate(m)  # the configured period (an FTT-CAN period_range's faster rates are jitter here)
            period = 1e6 / float(exact) if exact is not None else m.period_ns / 1000
        elif m.min_gap_ns:
            min_gap = m.min_gap_ns / 1000
        pdo = m.pdo
        co = self.buses[bus].canopen
        ftt = self.buses[bus].ftt
        ref = None
        if co is not None and pdo is not None and pdo.kind == "tpdo" and sync_every(pdo.transmission) is not None:
            ref = "sync"  # a synchronous TPDO answers the SYNC (netcfg.timing.canopen_sync)
            # its frames follow the SYNC's receptions, which move by the SYNC's own spread: the master's jitter in
            # queueing it and its response from there (up to its analysed worst case)
            sync = next((x for x in self.cfg.messages_on(self.buses[bus].name) if x.implicit == "SYNC"), None)
            if sync is not None and sync.wcrt_ns is not None:
                slack += (co.master_jitter_ns + sync.wcrt_ns) / 1000
        elif ftt is not None and m.window == "sync":
            ref = "tm"  # a synchronous FTT-CAN message goes in the EC its trigger message opens (netcfg.timing.ftt)
        st = MessageState(m, bus, timing, period, min_gap, slack, wcrt_us, ref)
        if ref == "sync":
            st.ref_delay_us = self.cfg.node(m.producer).tx_delay_ns / 1000
        if period is not None:
            st.intervals.edges = np.linspace(0.0, 2.0 * period, HIST_BINS + 1)
        elif min_gap is not None:
            st.intervals.edges = np.linspace(0.0, 4.0 * min_gap, HIST_BINS + 1)
        if st.response_ref is not None and wcrt_us is not None:
            top = 2.0 * wcrt_us  # the analysed worst case in the middle; later responses fall in the overflow bin
            st.responses.edges = np.linspace(0.0, top, HIST_BINS + 1)
        return st

    def _unanalysed_jitter_ns(self, m: Message, bus: int) -> int:
        """Release jitter the message's analysed response does not hold: the CANopen master's SYNC jitter for the
        SYNC it produces (its response is analysed from a strictly periodic release)."""
        co = self.buses[bus].canopen
        if co is not None and m.id == co.sync_id and not m.extended:
            return co.master_jitter_ns
        return 0

    def buses_of(self, channel: NDArray[np.int32]) -> NDArray[np.int64]:
        """Each frame's bus index (-1: a channel of no bus), from the reader's channel numbers."""
        while len(self._channel_bus) < len(self.channels):
            name = self.channels[len(self._channel_bus)]
            self._channel_bus.append(self._bus_of_channel(name))
        return np.array(self._channel_bus, np.int64)[channel] if len(channel) else np.empty(0, np.int64)

    def _bus_of_channel(self, name: str) -> int:
        if name in self.channel_map:
            return self.channel_map[name]
        if self.forced_bus is not None:
            return self.forced_bus
        names = [b.name for b in self.buses]
        if name in names:
            return names.index(name)
        if len(self.buses) == 1:
            return 0
        if not name:
            return -1  # no channel (python-can's error frames): fine unless a data frame has none either
        raise VerifyError(
            f"the log's channel {name!r} is none of the buses {', '.join(names)}; say which with "
            f"--bus {name or 'CHANNEL'}=BUS"
        )

    # --- feeding ------------------------------------------------------------------------------------------------

    def feed_messages(self, messages: Iterable[can.Message]) -> None:
        """python-can Messages (a live bus, a reader): needs the checker's own channel list (no `channels`)."""
        self.feed(batch_from_messages(messages, self._table))

    def feed(self, batch: Batch) -> None:
        n = len(batch)
        if not n:
            return
        t = batch.t_us
        if self.first_t is None:
            self.first_t = int(t[0])
        if self.origin_t is None:
            self.origin_t = int(t[0])
        back = np.flatnonzero(np.diff(t) < 0)
        if (self.last_t is not None and int(t[0]) < self.last_t) or len(back):
            at = int(t[0]) if not len(back) else int(t[back[0] + 1])
            raise VerifyError(
                f"the log goes back in time at {at / 1e6:.6f} s (log time); verify needs frames in time order"
            )
        self.last_t = int(t[-1])
        self.frames += n
        err = (batch.flags & ERROR) != 0
        keep = ~err
        bus = self.buses_of(batch.channel)
        if err.any():
            self.error_frames += int(err.sum())
            for ti, b in zip(t[err].tolist(), bus[err].tolist()):
                (self.error_ns[b] if b >= 0 else self.unplaced_error_ns).append(ti * 1000)
        if (bus[keep] < 0).any():
            raise VerifyError(
                f"the log's frames name no channel and the system has {len(self.buses)} CAN buses; say which "
                "with --bus BUS"
            )
        ext = (batch.flags & EXTENDED) != 0
        self._load(t[keep], bus[keep], batch.flags[keep], batch.length[keep])
        fd_or_remote = (batch.flags & (FD | REMOTE)) != 0
        key = _key_array(bus, batch.can_id, ext)
        # a remote frame belongs to the remote message of its identifier, where the configuration has one; else it
        # is an odd frame of the data message (a size violation)
        known, state_idx = self._lookup(key, keep)
        if self._any_remote:
            remote = keep & ((batch.flags & REMOTE) != 0)
            known_remote, state_remote = self._lookup(key | REMOTE_KEY, remote)
            known |= known_remote
            state_idx = np.where(known_remote, state_remote, state_idx)
        # SYNC (TM) times first: a synchronous message's response is measured from the one before it
        ref_times = {b: t[state_idx == s] for b, s in self._ref_state.items()}
        unknown = keep & ~known
        if unknown.any():
            self._unknown(t[unknown], bus[unknown], batch.can_id[unknown], ext[unknown], batch.data[unknown])
        order = np.argsort(state_idx, kind="stable")
        sorted_idx = state_idx[order]
        bounds = np.searchsorted(sorted_idx, np.arange(-1, len(self.states) + 1))
        for s in np.flatnonzero(np.diff(bounds[1:])):
            rows = order[bounds[s + 1] : bounds[s + 2]]
            st = self.states[s]
            self._message(st, t[rows], batch.length[rows], batch.data[rows], fd_or_remote[rows], ref_times)
        for b, times in ref_times.items():
            if len(times):
                self._last_ref[b] = int(times[-1])

    def _lookup(self, key: NDArray[np.int64], keep: NDArray[np.bool_]) -> tuple[NDArray[np.bool_], NDArray[np.int64]]:
        """Which frames' keys are a configured message's, and that message's state index (-1: none)."""
        if not len(self._keys):
            return np.zeros(len(key), bool), np.full(len(key), -1, np.int64)
        pos_c = np.minimum(np.searchsorted(self._keys, key), len(self._keys) - 1)
        known = keep & (self._keys[pos_c] == key)
        return known, np.where(known, self._key_state[pos_c], -1)

    def note_services(self, batch: Batch) -> int:
        """Frames outside the judged span (a master's set-up and shut-down, netcfg.verify.phases): their CANopen
        services (NMT, heartbeats, EMCY, SDO) are noted, nothing is held against the analysis. -> how many of
        them were SDO frames."""
        if not len(batch):
            return 0
        sdo_before = sum(services.sdo for services in self.services.values())
        if self.origin_t is None:
            self.origin_t = int(batch.t_us[0])
        self.unjudged += len(batch)
        keep = (batch.flags & (ERROR | EXTENDED)) == 0
        bus = self.buses_of(batch.channel)
        for b, services in self.services.items():
            on_bus = np.flatnonzero((bus == b) & keep)
            if len(on_bus):
                services.take(batch.t_us[on_bus], batch.can_id[on_bus], batch.data[on_bus])
        return sum(services.sdo for services in self.services.values()) - sdo_before

    def _load(self, t: NDArray[np.int64], bus: NDArray[np.int64], flags: NDArray[np.uint8], length: Any) -> None:
        if not len(t) or self.first_t is None:
            return
        dur = self._frames_ns(bus, flags, length)
        window = (t - self.first_t) // self.window_us
        for b in range(len(self.buses)):
            sel = bus == b
            if not sel.any():
                continue
            counts = np.bincount(window[sel], weights=dur[sel]).astype(np.int64)
            acc = self.window_ns[b]
            if len(counts) > len(acc):
                acc = np.concatenate([acc, np.zeros(len(counts) - len(acc), np.int64)])
            acc[: len(counts)] += counts
            self.window_ns[b] = acc

    def _frames_ns(self, bus: NDArray[np.int64], flags: NDArray[np.uint8], length: Any) -> NDArray[np.int64]:
        """Each frame's worst-case time on the wire as check times it (netcfg.timing.frames.frame_bits): from its
        format (extended, CAN FD, bit-rate switch) and payload length, once per kind of frame."""
        kinds = (bus.astype(np.int64) << 16) | (flags.astype(np.int64) & (EXTENDED | FD | BRS | REMOTE)) << 8
        kinds |= np.asarray(length, np.int64) & 0xFF
        unique, inverse = np.unique(kinds, return_inverse=True)
        durations = np.empty(len(unique), np.int64)
        for k, kind in enumerate(unique.tolist()):
            got = self._frame_ns.get(kind)
            if got is None:
                b, f, n = kind >> 16, kind >> 8 & 0xFF, kind & 0xFF
                fd = bool(f & FD)
                # a remote frame has no data field (ISO 11898-1): its DLC, the length it asks for, adds no bits
                size = 0 if f & REMOTE else min(n, CANFD_MAX_PAYLOAD if fd else CAN_MAX_PAYLOAD)
                bits = frame_bits(size, bool(f & EXTENDED), fd, bool(f & BRS))
                got = self._frame_ns[kind] = bits.ns(self.buses[b].bitrate, self.buses[b].data_bitrate)
            durations[k] = got
        return durations[inverse.ravel()]

    def _message(
        self,
        st: MessageState,
        t: NDArray[np.int64],
        length: NDArray[np.int16],
        data: NDArray[np.uint8],
        odd: NDArray[np.bool_],
        ref_times: dict[int, NDArray[np.int64]],
    ) -> None:
        m = st.msg
        refs = None  # the frames its responses are measured from: SYNC (TM), the last before this batch first
        key = st.bus if st.ref_key is None else st.ref_key
        if st.response_ref is not None and key in self._ref_state:
            syncs = ref_times.get(key, np.empty(0, np.int64))
            last = self._last_ref.get(key)
            refs = np.concatenate([[last], syncs]) if last is not None else syncs
        st.take(t, length, data, odd, refs, self._ref_offset.get(key, 0), self._violation)
        if m.implicit == "heartbeat" and st.bus in self.services and not m.extended:
            for k in np.flatnonzero(length > 0):  # the NMT state each heartbeat carries
                self.services[st.bus].note(m.id, int(t[k]), data[k])

    def _unknown(self, t: Any, bus: Any, can_id: Any, ext: Any, data: NDArray[np.uint8]) -> None:
        """Frames of no configured message: CANopen services of the bus's nodes are noted (SDO and the like
        counted at once, heartbeats, NMT and EMCY one by one: they are few); the rest counted per identifier."""
        rest = np.ones(len(t), bool)
        for b, services in self.services.items():
            on_bus = np.flatnonzero((bus == b) & ~ext)
            if len(on_bus):
                rest[on_bus[services.take(t[on_bus], can_id[on_bus], data[on_bus])]] = False
        if not rest.any():
            return
        keys = _key_array(bus[rest], can_id[rest], ext[rest])
        unique, first, counts = np.unique(keys, return_index=True, return_counts=True)
        times = t[rest]
        for key, at, count in zip(unique.tolist(), first.tolist(), counts.tolist()):
            b, x, i = key >> 31, bool(key >> 30 & 1), key & ((1 << 30) - 1)
            rec = self.unknown.get((b, i, x))
            if rec is None:
                self.unknown[(b, i, x)] = [count, int(times[at])]
            else:
                rec[0] += count

    def _error_check(self, bus: Bus, times_ns: list[int]) -> None:
        """A bus's error frames against its error model (none stated: no error at all)."""
        model = bus.errors
        breach = first_breach(times_ns, model.burst if model else None, model.interval_ns if model else 1)
        if breach is None:
            return
        if model is None:
            detail = (
                f"{len(times_ns)} error frame(s) on bus {bus.name}: it states no error model, so the analysis "
                "assumes none (retransmissions are not in it)"
            )
        else:
            allowed = model.burst + (breach.last_ns - breach.first_ns) // model.interval_ns + 1
            detail = (
                f"{breach.count} error frames on bus {bus.name} within {(breach.last_ns - breach.first_ns) / 1e6:g} "
                f"ms, where its error model allows {allowed}: the analysis does not bound this log"
            )
        self._violation("error_frames", None, breach.first_ns // 1000, detail)

    def _violation(self, kind: str, st: MessageState | None, t: int, detail: str) -> None:
        if self.host_clock is not None:  # a host stamped the log: its lateness is named (netcfg.verify.host_clock)
            kind, detail, warn = self.host_clock(kind, st, detail)
            if warn:
                return self._warning(kind, st, t, detail)
        self.violation_count[kind] = self.violation_count.get(kind, 0) + 1
        if st is not None:
            st.violations += 1
        _keep(self.violations, kind, st, t, detail)

    def _warning(self, kind: str, st: MessageState | None, t: int, detail: str) -> None:
        self.warning_count += 1
        if st is not None:
            st.warnings += 1
        _keep(self.warnings, kind, st, t, detail)

    # --- the result ---------------------------------------------------------------------------------------------

    def finish(self) -> dict[str, Any]:
        """End of the log: trailing gaps, messages never seen, aggregated findings; -> the report document."""
        end = self.last_t
        span = 0 if end is None or self.first_t is None else end - self.first_t
        jitter = self._violation if self.strict else self._warning
        for st in self.states:
            ppm = self.clock_tolerance_ppm
            if ppm is None:
                ppm = self.buses[st.bus].clock_tolerance_ppm
            st.close(end, span, ppm, self._since, self._violation, jitter)
        for b, bus_ in enumerate(self.buses):
            self._error_check(bus_, sorted(self.error_ns[b] + self.unplaced_error_ns))
        for (b, i, x), (count, first) in sorted(self.unknown.items(), key=lambda kv: (kv[1][1], kv[0])):
            self._violation(
                "unknown_id",
                None,
                first,
                f"id {id_text(i, x)} on bus {self.buses[b].name} is not in the configuration ({count} frame(s))",
            )
        buses = [self._bus_report(b) for b in range(len(self.buses))]
        # times count from the log's first frame: formats differ in their origin (ASC starts at its first frame)
        for item in [*self.violations, *self.warnings]:
            item["time_us"] = self._since(item["time_us"])
        for services in self.services.values():
            services.shift_times(self.origin_t or 0)
        self.violations.sort(key=lambda v: (v["time_us"], v["kind"], v["message"] or ""))
        messages = [st.report() for st in self.states]
        return {
            "system": self.cfg.system,
            "frames": self.frames + self.unjudged,
            "error_frames": self.error_frames,
            "start_us": self.origin_t,
            "duration_us": 0 if self.first_t is None or end is None else end - self.first_t,
            "window_us": self.window_us,
            "messages": messages,
            "buses": buses,
            "unknown_ids": [
                {"bus": self.buses[b].name, "id": i, "extended": x, "count": c, "first_us": self._since(f)}
                for (b, i, x), (c, f) in sorted(self.unknown.items())
            ],
            "never_seen": [st.msg.name for st in self.states if st.count == 0],
            "violations": self.violations,
            "violation_count": sum(self.violation_count.values()),
            "violations_by_kind": dict(sorted(self.violation_count.items())),
            "warnings": self.warnings,
            "warning_count": self.warning_count,
            "ok": not self.violation_count,
        }

    def _since(self, t: int) -> int:
        return t - (self.origin_t or 0)

    def _bus_report(self, b: int) -> dict[str, Any]:
        bus = self.buses[b]
        window_ns = self.window_us * 1000
        load = np.round(self.window_ns[b] / window_ns, 6).tolist()
        bound = self.window_bound(b)
        analysed = self._utilization(b)
        over = np.flatnonzero(np.array(load[:-1]) > bound)  # the last window is cut short by the log's end
        if len(over) > MAX_VIOLATIONS:
            self.violation_count["load"] = self.violation_count.get("load", 0) + len(over) - MAX_VIOLATIONS
        for w in over[:MAX_VIOLATIONS]:
            assert self.first_t is not None
            self._violation(
                "load",
                None,
                self.first_t + (int(w) + 1) * self.window_us,
                f"bus {bus.name}: load {load[w]:.1%} in the {self.window_us / 1000:g} ms window ending here; the "
                f"analysis allows at most {bound:.1%} in any such window (utilisation {analysed:.1%})",
            )
        full = load[:-1] if len(load) > 1 else load
        out: dict[str, Any] = {
            "name": bus.name,
            "protocol": bus.protocol,
            "bitrate": bus.bitrate,
            "utilization_analysed": round(analysed, 6),
            "window_bound": round(bound, 6),
            "load": {"min": min(full), "mean": round(sum(full) / len(full), 6), "max": max(full)} if full else None,
            "load_per_window": load,
        }
        if bus.canopen is not None:
            out["canopen"] = self._canopen_report(b)
        return out

    def _utilization(self, b: int) -> float:
        """The bus's worst-case utilisation as the analysis computes it (netcfg.timing: worst-case stuffing, each
        message at its fastest admissible rate), over every frame the log can show: FTT-CAN's trigger message
        included (the analysis reports it apart, as the TM overhead)."""
        return sum(
            st.timing.tx_ns * rate_hz(st.msg) / 1e9
            for st in self.states
            if st.bus == b and st.msg.kind != "on-demand"
        )

    def window_bound(self, b: int) -> float:
        """The most a window of window_us can carry by the analysis: every periodic or sporadic message as often
        as its period, jitter and response allow (ceil((W + slack) / T) frames), on-demand messages once."""
        total_ns = 0
        for st in self.states:
            if st.bus != b:
                continue
            tx = st.timing.tx_ns
            fastest = st.msg.interval_ns  # a periodic message's fastest admissible period, a sporadic one's minimum
            gap = fastest / 1000 if fastest and st.msg.kind != "on-demand" else None
            frames = 1 if not gap else int(np.ceil((self.window_us + st.slack_us) / gap))
            total_ns += frames * tx
        return total_ns / (self.window_us * 1000)

    def _canopen_report(self, b: int) -> dict[str, Any]:
        sync = None
        if b in self._ref_state:
            st = self.states[self._ref_state[b]]
            sync = {"count": st.count, "period_us": st.report()["period_us"], "jitter_us": st.dev_max}
        co = self.buses[b].canopen
        assert co is not None
        window = co.sync_window_ns
        in_window = [
            {
                "name": st.msg.name,
                "response_max_us": st.responses.largest,
                "inside_window": (
                    None if window is None or st.responses.largest is None else st.responses.largest * 1000 <= window
                ),
            }
            for st in self.states
            if st.bus == b and st.response_ref == "sync"
        ]
        return {
            "sync": sync,
            "sync_window_us": None if window is None else window / 1000,
            "synchronous_pdos": in_window,
            **self.services[b].report(),
        }


def _keep(found: list[dict[str, Any]], kind: str, st: MessageState | None, t: int, detail: str) -> None:
    """A finding kept in detail, up to MAX_VIOLATIONS of each list (all of them are counted)."""
    if len(found) < MAX_VIOLATIONS:
        found.append({"kind": kind, "message": None if st is None else st.msg.name, "time_us": t, "detail": detail})


REMOTE_KEY = 1 << 29  # above every identifier (29 bits), below the extended flag: a remote message's key


def _key(bus: int, can_id: int, extended: bool) -> int:
    return (bus << 31) | (int(extended) << 30) | can_id


def _key_array(bus: NDArray[np.int64], can_id: NDArray[np.int64], ext: NDArray[np.bool_]) -> NDArray[np.int64]:
    return (bus.astype(np.int64) << 31) | (ext.astype(np.int64) << 30) | can_id


