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
  shortest transmission time).
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
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from netcfg.cia301 import sync_every
from netcfg.runtime import Bus, Message, RuntimeConfig, columns
from netcfg.timing.can_errors import first_breach
from netcfg.timing.frames import CAN_MAX_PAYLOAD, CANFD_MAX_PAYLOAD, frame_bits
from netcfg.timing.load import FrameTiming, exact_rate, frame_timing, rate_hz
from netcfg.verify.canopen import ServiceLog
from netcfg.verify.frames import BRS, ERROR, EXTENDED, FD, REMOTE, Batch, ChannelTable, batch_from_messages

if TYPE_CHECKING:
    import can

__all__ = ["MAX_VIOLATIONS", "Checker", "VerifyError"]

MAX_VIOLATIONS = 1000  # kept in detail; more are counted
HIST_BINS = 60
DEFAULT_WINDOW_US = 100_000

class VerifyError(ValueError):
    """The configuration and the log cannot be matched (e.g. which bus a channel is); a usage problem."""


@dataclass
class _MessageState:
    msg: Message
    bus: int
    timing: FrameTiming  # the frame as check times it (netcfg.timing.load.frame_timing)
    period_us: float | None  # periodic: the period; sporadic: None
    min_gap_us: float | None  # sporadic: the least admissible interval
    slack_us: float  # analysed jitter + worst-case response - best transmission time
    wcrt_us: float | None
    response_ref: str | None  # "sync": response measured from the last SYNC of the bus
    ref_delay_us: float = 0.0  # a synchronous TPDO is queued its drive's tx_delay after the SYNC: its bound's start
    count: int = 0
    last_t: int | None = None
    first_t: int | None = None
    iv_min: int | None = None
    iv_max: int | None = None
    iv_sum: int = 0
    iv_n: int = 0
    dev_max: int = 0  # largest |interval - period| outside gaps
    missing: int = 0
    resp_min: int | None = None
    resp_max: int | None = None
    resp_sum: int = 0
    resp_n: int = 0
    violations: int = 0
    warnings: int = 0
    period_hist: NDArray[np.int64] = field(default_factory=lambda: np.zeros(HIST_BINS + 2, np.int64))
    resp_hist: NDArray[np.int64] = field(default_factory=lambda: np.zeros(HIST_BINS + 2, np.int64))
    period_edges: NDArray[np.float64] | None = None
    resp_edges: NDArray[np.float64] | None = None
    range_out: dict[str, list[Any]] = field(default_factory=dict)  # signal -> [count, first_t, worst value]
    bad_size: list[int] = field(default_factory=list)  # [count, first_t, length]
    jitter_out: list[Any] | None = None  # intervals outside period +- slack: [count, first_t, worst, its t, its iv]


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
        self.states: list[_MessageState] = []
        keys: list[int] = []
        trigger_messages = [_trigger_message(b) for b in self.buses if b.ftt is not None]
        for m in [*cfg.messages, *trigger_messages]:
            if not m.is_can:
                continue
            b = [x.name for x in self.buses].index(m.bus)
            self.states.append(self._state(m, b))
            keys.append(_key(b, m.id, m.extended))
        order = np.argsort(np.array(keys, np.int64), kind="stable")
        self._keys = np.array(keys, np.int64)[order]
        self._key_state = order
        # per bus the message a response is measured from: CANopen's SYNC, FTT-CAN's trigger message
        self._ref_state: dict[int, int] = {}
        for b, bus_ in enumerate(self.buses):
            ref_id = bus_.canopen.sync_id if bus_.canopen else bus_.ftt.tm_id if bus_.ftt else None
            for i, st in enumerate(self.states):
                if st.bus == b and st.msg.id == ref_id and not st.msg.extended:
                    self._ref_state[b] = i
        self._last_ref: dict[int, int] = {}
        # a log stamps a frame's end; FTT-CAN's analysis counts from the EC's start, where the trigger message
        # starts: its shortest transmission (no stuff bits) is added back, so a reported late frame is surely late
        self._ref_offset = {
            b: frame_bits(bus_.ftt.tm_size, False, stuffing="nominal").ns(bus_.bitrate) // 1000 if bus_.ftt else 0
            for b, bus_ in enumerate(self.buses)
        }
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

    # --- setup --------------------------------------------------------------------------------------------------

    def _state(self, m: Message, bus: int) -> _MessageState:
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
        st = _MessageState(m, bus, timing, period, min_gap, slack, wcrt_us, ref)
        if ref == "sync":
            st.ref_delay_us = self.cfg.node(m.producer).tx_delay_ns / 1000
        if period is not None:
            st.period_edges = np.linspace(0.0, 2.0 * period, HIST_BINS + 1)
        elif min_gap is not None:
            st.period_edges = np.linspace(0.0, 4.0 * min_gap, HIST_BINS + 1)
        if st.response_ref is not None and wcrt_us is not None:
            top = 2.0 * wcrt_us  # the analysed worst case in the middle; later responses fall in the overflow bin
            st.resp_edges = np.linspace(0.0, top, HIST_BINS + 1)
        return st

    def _unanalysed_jitter_ns(self, m: Message, bus: int) -> int:
        """Release jitter the message's analysed response does not hold: the CANopen master's SYNC jitter for the
        SYNC it produces (its response is analysed from a strictly periodic release)."""
        co = self.buses[bus].canopen
        if co is not None and m.id == co.sync_id and not m.extended:
            return co.master_jitter_ns
        return 0

    def _buses_of(self, channel: NDArray[np.int32]) -> NDArray[np.int64]:
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
        bus = self._buses_of(batch.channel)
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
        key = _key_array(bus, batch.can_id, ext)
        pos = np.searchsorted(self._keys, key)
        pos_c = np.minimum(pos, max(len(self._keys) - 1, 0))
        known = keep & (len(self._keys) > 0) & (self._keys[pos_c] == key if len(self._keys) else False)
        state_idx = np.where(known, self._key_state[pos_c] if len(self._keys) else 0, -1)
        fd_or_remote = (batch.flags & (FD | REMOTE)) != 0
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
        bus = self._buses_of(batch.channel)
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
        kinds = (bus.astype(np.int64) << 16) | (flags.astype(np.int64) & (EXTENDED | FD | BRS)) << 8
        kinds |= np.asarray(length, np.int64) & 0xFF
        unique, inverse = np.unique(kinds, return_inverse=True)
        durations = np.empty(len(unique), np.int64)
        for k, kind in enumerate(unique.tolist()):
            got = self._frame_ns.get(kind)
            if got is None:
                b, f, n = kind >> 16, kind >> 8 & 0xFF, kind & 0xFF
                fd = bool(f & FD)
                size = min(n, CANFD_MAX_PAYLOAD if fd else CAN_MAX_PAYLOAD)  # a remote frame's DLC may say more
                bits = frame_bits(size, bool(f & EXTENDED), fd, bool(f & BRS))
                got = self._frame_ns[kind] = bits.ns(self.buses[b].bitrate, self.buses[b].data_bitrate)
            durations[k] = got
        return durations[inverse.ravel()]

    def _message(
        self,
        st: _MessageState,
        t: NDArray[np.int64],
        length: NDArray[np.int16],
        data: NDArray[np.uint8],
        odd: NDArray[np.bool_],
        ref_times: dict[int, NDArray[np.int64]],
    ) -> None:
        m = st.msg
        if st.first_t is None:
            st.first_t = int(t[0])
        st.count += len(t)
        # payload length; a CAN FD message's frames carry its padded length (odd: FD or remote, as expected for it)
        wrong = (length != m.frame_size) if m.fd else (length != m.size) | odd
        if wrong.any():
            if not st.bad_size:
                st.bad_size = [0, int(t[wrong][0]), int(length[wrong][0])]
            st.bad_size[0] += int(wrong.sum())
        # intervals, the previous batch's last frame included
        prev = np.concatenate([[st.last_t], t]) if st.last_t is not None else t
        st.last_t = int(t[-1])
        iv = np.diff(prev)
        if len(iv):
            st.iv_min = int(iv.min()) if st.iv_min is None else min(st.iv_min, int(iv.min()))
            st.iv_max = int(iv.max()) if st.iv_max is None else max(st.iv_max, int(iv.max()))
            st.iv_sum += int(iv.sum())
            st.iv_n += len(iv)
            if st.period_edges is not None:
                st.period_hist += _hist(iv, st.period_edges)
            ends = prev[1:]
            if st.period_us is not None:
                self._periodic(st, iv, ends)
            elif st.min_gap_us is not None:
                early = iv < st.min_gap_us - st.slack_us
                for k in np.flatnonzero(early)[:MAX_VIOLATIONS]:
                    self._violation(
                        "early",
                        st,
                        int(ends[k]),
                        f"{iv[k] / 1000:.3f} ms after the previous frame; the analysis assumes at least "
                        f"{st.min_gap_us / 1000:.3f} ms (less {st.slack_us:.0f} us jitter), "
                        f"{(st.min_gap_us - st.slack_us - iv[k]):.0f} us sooner",
                    )
        # response from the SYNC (TM) before each frame
        if st.response_ref is not None and st.bus in self._ref_state:
            syncs = ref_times.get(st.bus, np.empty(0, np.int64))
            last = self._last_ref.get(st.bus)
            refs = np.concatenate([[last], syncs]) if last is not None else syncs
            if len(refs):
                at = np.searchsorted(refs, t, side="left") - 1
                ok = at >= 0
                resp = t[ok] - refs[at[ok]] + self._ref_offset[st.bus]
                if len(resp):
                    st.resp_min = int(resp.min()) if st.resp_min is None else min(st.resp_min, int(resp.min()))
                    st.resp_max = int(resp.max()) if st.resp_max is None else max(st.resp_max, int(resp.max()))
                    st.resp_sum += int(resp.sum())
                    st.resp_n += len(resp)
                    if st.resp_edges is not None:
                        st.resp_hist += _hist(resp, st.resp_edges)
                    if st.wcrt_us is not None:
                        when = t[ok]
                        bound = st.wcrt_us + st.ref_delay_us
                        for k in np.flatnonzero(resp > bound)[:MAX_VIOLATIONS]:
                            after = f" (its drive's tx_delay {st.ref_delay_us:.0f} + {st.wcrt_us:.0f})"
                            self._violation(
                                "late",
                                st,
                                int(when[k]),
                                f"{resp[k]:.0f} us after {st.response_ref.upper()}; the analysed worst case is "
                                f"{bound:.0f} us{after if st.ref_delay_us else ''}, {resp[k] - bound:.0f} us late",
                            )
        if m.signals and not wrong.all():
            self._ranges(st, t[~wrong], data[~wrong])
        if m.implicit == "heartbeat" and st.bus in self.services and not m.extended:
            for k in np.flatnonzero(length > 0):  # the NMT state each heartbeat carries
                self.services[st.bus].note(m.id, int(t[k]), data[k])

    def _periodic(self, st: _MessageState, iv: NDArray[np.int64], ends: NDArray[np.int64]) -> None:
        period = st.period_us
        assert period is not None
        periods = _periods_spanned(iv, period, st.slack_us)
        gaps = periods >= 2
        for k in np.flatnonzero(gaps)[:MAX_VIOLATIONS]:
            missing = int(periods[k] - 1)
            st.missing += missing
            self._violation(
                "gap",
                st,
                int(ends[k]),
                f"{missing} period{'s' if missing > 1 else ''} missing: {iv[k] / 1000:.3f} ms since the previous "
                f"frame, period {period / 1000:g} ms",
            )
        if gaps.sum() > MAX_VIOLATIONS:
            st.missing += int((periods[gaps] - 1)[MAX_VIOLATIONS:].sum())
        dev = np.abs(iv[~gaps] - period)
        if len(dev):
            st.dev_max = max(st.dev_max, int(np.ceil(dev.max())))
        if st.response_ref == "sync":  # a synchronous TPDO follows the SYNC: its response is the check
            return
        beyond = np.where(gaps, 0, np.abs(iv - period) - st.slack_us)
        outside = beyond > 0
        if outside.any():
            k = int(np.argmax(beyond))
            if st.jitter_out is None:
                st.jitter_out = [0, int(ends[outside][0]), 0.0, 0, 0]
            st.jitter_out[0] += int(outside.sum())
            if beyond[k] > st.jitter_out[2]:
                st.jitter_out[2:] = [float(beyond[k]), int(ends[k]), int(iv[k])]

    def _ranges(self, st: _MessageState, t: NDArray[np.int64], data: NDArray[np.uint8]) -> None:
        """Signals decoded as the codec decodes them (byte order, sign, float, multiplexing: netcfg.runtime.columns),
        each in the frames that carry it; a signal beyond the bytes a batch keeps (PAYLOAD_COLUMNS) is not seen."""
        signals = [s for s in st.msg.signals if columns.fits(s, data.shape[1])]
        carried = columns.present_rows(signals, data)
        for sig in signals:
            if sig.minimum is None and sig.maximum is None:
                continue
            value = columns.physical(sig, columns.take(sig, data))
            low = carried[sig.name] & (value < sig.minimum if sig.minimum is not None else False)
            high = carried[sig.name] & (value > sig.maximum if sig.maximum is not None else False)
            out = low | high
            if out.any():
                rec = st.range_out.setdefault(sig.name, [0, int(t[out][0]), None])
                rec[0] += int(out.sum())
                lo = float(value[low].min()) if low.any() else None
                hi = float(value[high].max()) if high.any() else None
                for v in (lo, hi):
                    if v is not None and (rec[2] is None or _excess(sig, v) > _excess(sig, rec[2])):
                        rec[2] = v

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

    def _violation(self, kind: str, st: _MessageState | None, t: int, detail: str) -> None:
        self.violation_count[kind] = self.violation_count.get(kind, 0) + 1
        if st is not None:
            st.violations += 1
        if len(self.violations) < MAX_VIOLATIONS:
            self.violations.append(
                {"kind": kind, "message": None if st is None else st.msg.name, "time_us": t, "detail": detail}
            )

    def _warning(self, kind: str, st: _MessageState | None, t: int, detail: str) -> None:
        self.warning_count += 1
        if st is not None:
            st.warnings += 1
        if len(self.warnings) < MAX_VIOLATIONS:
            self.warnings.append(
                {"kind": kind, "message": None if st is None else st.msg.name, "time_us": t, "detail": detail}
            )

    # --- the result ---------------------------------------------------------------------------------------------

    def finish(self) -> dict[str, Any]:
        """End of the log: trailing gaps, messages never seen, aggregated findings; -> the report document."""
        end = self.last_t
        for st in self.states:
            m = st.msg
            if st.count == 0:
                # a periodic message is due within its period and slack of the log's start; a sporadic one may
                # rightly never come (its rate is a bound, not a promise)
                span = 0 if end is None or self.first_t is None else end - self.first_t
                if m.kind == "periodic" and st.period_us is not None and span > st.period_us + st.slack_us:
                    self._violation("never_seen", st, end or 0, f"no frame with id {_id_text(m.id, m.extended)}")
                continue
            if st.period_us is not None and end is not None and st.last_t is not None:
                trailing = int(_periods_spanned(np.array([end - st.last_t]), st.period_us, st.slack_us)[0]) - 1
                if trailing >= 1:
                    st.missing += trailing
                    self._violation(
                        "gap",
                        st,
                        end,
                        f"{trailing} period{'s' if trailing > 1 else ''} missing at the end of the log: last frame "
                        f"{(end - st.last_t) / 1000:.3f} ms before it, period {st.period_us / 1000:g} ms",
                    )
            if st.period_us is not None and st.first_t is not None and st.last_t is not None:
                self._rate(st)
            if st.jitter_out is not None:
                count, first, worst, worst_t, worst_iv = st.jitter_out
                assert st.period_us is not None
                detail = (
                    f"{count} of {st.iv_n} intervals outside the analysed {st.period_us / 1000:g} ms +- "
                    f"{st.slack_us:.0f} us (jitter + worst-case response - transmission time), from "
                    f"{self._since(first) / 1e6:.6f} s; the worst {worst_iv / 1000:.3f} ms at "
                    f"{self._since(worst_t) / 1e6:.6f} s, "
                    f"{worst:.0f} us beyond"
                )
                (self._violation if self.strict else self._warning)("jitter", st, first, detail)
            if st.bad_size:
                count, first, length = st.bad_size
                self._violation(
                    "size",
                    st,
                    first,
                    f"{count} frame(s) with {length} bytes (or CAN FD / remote); the message has {m.size}",
                )
            for name, (count, first, worst) in st.range_out.items():
                sig = next(s for s in m.signals if s.name == name)
                self._violation(
                    "range",
                    st,
                    first,
                    f"signal {name} outside [{_g(sig.minimum)}, {_g(sig.maximum)}] in {count} frame(s), "
                    f"worst {worst:g}{' ' + sig.unit if sig.unit else ''}",
                )
        for b, bus_ in enumerate(self.buses):
            self._error_check(bus_, sorted(self.error_ns[b] + self.unplaced_error_ns))
        for (b, i, x), (count, first) in sorted(self.unknown.items(), key=lambda kv: (kv[1][1], kv[0])):
            self._violation(
                "unknown_id",
                None,
                first,
                f"id {_id_text(i, x)} on bus {self.buses[b].name} is not in the configuration ({count} frame(s))",
            )
        buses = [self._bus_report(b) for b in range(len(self.buses))]
        # times count from the log's first frame: formats differ in their origin (ASC starts at its first frame)
        for item in [*self.violations, *self.warnings]:
            item["time_us"] = self._since(item["time_us"])
        for services in self.services.values():
            services.shift_times(self.origin_t or 0)
        self.violations.sort(key=lambda v: (v["time_us"], v["kind"], v["message"] or ""))
        messages = [self._message_report(st) for st in self.states]
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

    def _rate(self, st: _MessageState) -> None:
        """Fewer frames than the period needs over the message's span, beyond the gaps already counted: a sender
        whose period is longer than configured. The sender's clock may run slow by the clock tolerance."""
        assert st.period_us is not None and st.first_t is not None and st.last_t is not None
        span = st.last_t - st.first_t
        ppm = self.clock_tolerance_ppm
        if ppm is None:
            ppm = self.buses[st.bus].clock_tolerance_ppm
        needed = int(np.floor((span * (1 - ppm / 1e6) - st.slack_us) / st.period_us)) + 1
        short = needed - st.count - st.missing
        if short > 0:
            self._violation(
                "rate",
                st,
                st.last_t,
                f"{st.count} frames over {span / 1e6:.6f} s; a {st.period_us / 1000:g} ms period needs at least "
                f"{needed} ({short} more than the gaps explain; mean period {span / max(st.count - 1, 1) / 1000:.3f} "
                f"ms, clock tolerance {ppm:g} ppm)",
            )

    def _since(self, t: int) -> int:
        return t - (self.origin_t or 0)

    def _message_report(self, st: _MessageState) -> dict[str, Any]:
        m = st.msg
        period = None
        if st.iv_n:
            assert st.iv_min is not None and st.iv_max is not None
            period = {"min": st.iv_min, "mean": round(st.iv_sum / st.iv_n, 3), "max": st.iv_max}
        response = None
        if st.resp_n:
            assert st.resp_min is not None and st.resp_max is not None
            response = {"min": st.resp_min, "mean": round(st.resp_sum / st.resp_n, 3), "max": st.resp_max}
        return {
            "name": m.name,
            "bus": m.bus,
            "id": m.id,
            "extended": m.extended,
            "kind": m.kind,
            "count": st.count,
            "period_us": period,
            "nominal_period_us": None if st.period_us is None else round(st.period_us, 3),
            "jitter_us": st.dev_max if period is not None and st.period_us is not None else None,
            "analysed_jitter_us": round(st.slack_us, 3) if st.period_us is not None and not st.response_ref else None,
            "response_us": response,
            "response_from": st.response_ref,
            "wcrt_us": st.wcrt_us,
            "missing": st.missing,
            "within_analysis": None if st.count == 0 and m.kind == "on-demand" else st.violations == 0,
            "warnings": st.warnings,
            "histograms": {
                "period": _hist_doc(st.period_hist, st.period_edges),
                "response": _hist_doc(st.resp_hist, st.resp_edges),
            },
        }

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
            sync = {"count": st.count, "period_us": self._message_report(st)["period_us"], "jitter_us": st.dev_max}
        co = self.buses[b].canopen
        assert co is not None
        window = co.sync_window_ns
        in_window = [
            {
                "name": st.msg.name,
                "response_max_us": st.resp_max,
                "inside_window": None if window is None or st.resp_max is None else st.resp_max * 1000 <= window,
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


def _periods_spanned(iv: NDArray[np.int64], period: float, slack: float) -> NDArray[np.int64]:
    """How many periods each interval spans, for counting missing frames: the nearest whole number (a log cannot
    tell a frame later than half a period from a missing one), but no more than the fewest the analysis allows
    (frames k periods apart are k * period +- slack apart), so a late frame within the analysed jitter is never
    counted as a missing one."""
    nearest = np.floor(iv / period + 0.5)
    fewest = np.ceil((iv - slack) / period)
    return np.maximum(np.minimum(nearest, fewest), 1).astype(np.int64)


def _trigger_message(bus: Bus) -> Message:
    """FTT-CAN's trigger message as a message of the bus: sent by the master once per elementary cycle."""
    ftt = bus.ftt
    assert ftt is not None
    return Message(
        name=f"{bus.name}_TM",
        bus=bus.name,
        protocol=bus.protocol,
        producer=ftt.master,
        consumers=(),
        id=ftt.tm_id,
        extended=False,
        size=ftt.tm_size,
        kind="periodic",
        period_ns=ftt.ec_ns,
        interval_ns=ftt.ec_ns,
        offset_ns=0,
        deadline_ns=None,
        jitter_ns=0,
        rate_hz=None,
        window=None,
        ftt_id=None,
        udp=None,
        pdo=None,
        signals=(),
        implicit="TM",
        wcrt_ns=None,
    )


def _key(bus: int, can_id: int, extended: bool) -> int:
    return (bus << 31) | (int(extended) << 30) | can_id


def _key_array(bus: NDArray[np.int64], can_id: NDArray[np.int64], ext: NDArray[np.bool_]) -> NDArray[np.int64]:
    return (bus.astype(np.int64) << 31) | (ext.astype(np.int64) << 30) | can_id


def _hist(values: NDArray[Any], edges: NDArray[np.float64]) -> NDArray[np.int64]:
    """Counts per bin, with an underflow and an overflow bin at the ends."""
    idx = np.searchsorted(edges, values, side="right")
    return np.bincount(idx, minlength=len(edges) + 1).astype(np.int64)


def _hist_doc(counts: NDArray[np.int64], edges: NDArray[np.float64] | None) -> dict[str, Any] | None:
    if edges is None or not counts.any():
        return None
    return {"edges_us": [round(float(e), 3) for e in edges], "counts": [int(c) for c in counts]}


def _excess(sig: Any, v: float) -> float:
    low = sig.minimum - v if sig.minimum is not None else 0.0
    high = v - sig.maximum if sig.maximum is not None else 0.0
    return max(low, high)


def _g(x: float | None) -> str:
    return "-" if x is None else f"{x:g}"


def _id_text(can_id: int, extended: bool) -> str:
    return f"0x{can_id:08X}" if extended else f"0x{can_id:03X}"
