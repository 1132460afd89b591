"""netcfg.runtime.udp: live UDP endpoints for Ethernet/UDP systems (seed 001), driven only by a runtime.json.

A datagram's payload is one byte of message id, then the message's data (seed 001, Table 6.1). Each node binds
the ports the config gives it: the destination port of every message it consumes and the source port of every
message it produces; the seed's "send port of the MCU is the receive port for ROS and vice versa" makes these one
socket per side in the NTUA systems. A message is sent from the socket bound to its source port, to each consumer's
address at its destination port, so a receiver can tell same-id messages apart by their ports.

    cfg = netcfg.runtime.load("generated/ntua_sahr/runtime.json")
    with PcEndpoint(cfg) as pc:
        pc.send("hip_pwm", hip_pwm_raw=0x80)
        got = pc.recv(timeout=0.01)          # Received("hip_encoder", {"hip_encoder_raw": ...}, t_recv_ns) or None

On one machine, `loopback_hosts(cfg)` gives every node its own 127.0.0.x address (Linux routes all of 127.0.0.0/8
to the loopback interface), so two MCUs can both bind the configured port 5001; where only 127.0.0.1 exists,
`port_offset` moves every port instead. A node binds the address host_map gives it, else its configured ip; a PC
that should listen on every interface maps itself to "0.0.0.0".

Only the standard library and netcfg.runtime: a live master must not need the compiler.
"""

from __future__ import annotations

import contextlib
import math
import selectors
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import TracebackType
from typing import NamedTuple

from netcfg.runtime import CodecError, Message, Node, RuntimeConfig
from netcfg.runtime.codec import Number

__all__ = [
    "Counters",
    "ExchangeResult",
    "Pair",
    "PcEndpoint",
    "Received",
    "RttStats",
    "StandInMcu",
    "UdpEndpoint",
    "echo_reply",
    "exchange",
    "loopback_hosts",
    "rtt_stats",
    "unpack_echo",
]

UDP = "ethernet-udp"
MAX_DATAGRAM = 2048  # the largest Ethernet payload is 1500 bytes; anything longer is malformed anyway
RCVBUF = 1 << 20  # room for bursts of 15 kHz streams while a Python reader is descheduled (the kernel may cap it)

Values = Mapping[str, Number | bytes]
ReplyFn = Callable[[Message, Mapping[str, Number], int], Values]
SampleFn = Callable[[Message, int], Values]


class Received(NamedTuple):
    message: str
    values: dict[str, Number]
    t_recv_ns: int  # time.monotonic_ns() right after the datagram was read


@dataclass
class Counters:
    sent: int = 0  # datagrams sent (one per consumer of a message)
    received: int = 0  # datagrams decoded and returned by recv()
    unknown: int = 0  # no message for this node has that id on these ports
    malformed: int = 0  # empty, or the data length is not the message's size
    last_error: str | None = None


# --- addresses ----------------------------------------------------------------------------------------------------


def loopback_hosts(cfg: RuntimeConfig, net: str = "127.0.0") -> dict[str, str]:
    """A distinct loopback address for every node: `net`.<last octet of its configured ip> where that is free,
    otherwise the next free host number. Keeps every configured port as it is."""
    parts = net.split(".")
    if len(parts) != 3 or parts[0] != "127" or not all(p.isdigit() and int(p) < 256 for p in parts):
        raise ValueError(f"net {net!r} is not the first three octets of a 127.0.0.0/8 address")
    taken: set[int] = set()
    wanted: dict[str, int | None] = {}
    for node in cfg.nodes:
        octet = int(node.ip.rsplit(".", 1)[1]) if node.ip and node.ip.count(".") == 3 else None
        if octet is not None and 1 <= octet <= 254 and octet not in taken:
            taken.add(octet)
            wanted[node.name] = octet
        else:
            wanted[node.name] = None
    free = (n for n in range(1, 255) if n not in taken)
    hosts: dict[str, str] = {}
    for name, octet in wanted.items():
        if octet is None:
            octet = next(free, None)
            if octet is None:
                raise ValueError(f"more than 254 nodes do not fit {net}.0/24")
        hosts[name] = f"{net}.{octet}"
    return hosts


# --- one node's sockets -------------------------------------------------------------------------------------------


class UdpEndpoint:
    """The sockets of one node on one Ethernet/UDP bus: sends what the node produces, receives what it consumes."""

    default_node: str | None = None  # the node a subclass stands for when none is named

    def __init__(
        self,
        cfg: RuntimeConfig,
        node: str | None = None,
        host_map: Mapping[str, str] | None = None,
        *,
        port_offset: int = 0,
        bus: str | None = None,
    ) -> None:
        name = node if node is not None else self.default_node
        if name is None:
            raise ValueError("name the node whose sockets these are")
        self.cfg = cfg
        self.node: Node = cfg.node(name)
        self.bus = bus if bus is not None else self._only_udp_bus()
        if not cfg.bus(self.bus).is_udp:
            raise ValueError(f"bus '{self.bus}' is {cfg.bus(self.bus).protocol}, not {UDP}")
        self.host_map = dict(host_map or {})
        self.port_offset = port_offset
        self.counters = Counters()
        on_bus = cfg.messages_on(self.bus)
        self.produces = tuple(m for m in on_bus if m.producer == name)
        self.consumes = tuple(m for m in on_bus if name in m.consumers)
        for m in self.produces + self.consumes:
            if m.udp is None:
                raise ValueError(f"message '{m.name}' on bus '{self.bus}' has no UDP ports in {cfg.source}")
        local = sorted(
            {m.udp.dst_port for m in self.consumes if m.udp} | {m.udp.src_port for m in self.produces if m.udp}
        )
        self.host = self.address(name)
        # select() rather than epoll: epoll waits in whole milliseconds, too coarse to pace a 1 kHz loop
        self._selector = selectors.SelectSelector()
        self._sockets: dict[int, socket.socket] = {}
        self._closed = False
        self._wake_r, self._wake_w = socket.socketpair()  # lets another thread end a blocked recv()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._selector.register(self._wake_r, selectors.EVENT_READ, None)
        try:
            for port in local:
                self._bind(port)
        except BaseException:
            self.close()
            raise

    def _only_udp_bus(self) -> str:
        buses = [b for b in self.node.buses if self.cfg.bus(b).is_udp]
        if len(buses) != 1:
            raise ValueError(f"node '{self.node.name}' is on {len(buses)} {UDP} buses {buses}; say which with bus=")
        return buses[0]

    def _bind(self, port: int) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RCVBUF)
            sock.bind((self.host, self._wire_port(port)))
        except OSError as exc:
            sock.close()
            raise OSError(
                exc.errno, f"node '{self.node.name}' cannot bind {self.host}:{self._wire_port(port)}: {exc.strerror}"
            ) from exc
        sock.setblocking(False)
        self._sockets[port] = sock
        self._selector.register(sock, selectors.EVENT_READ, port)

    def _wire_port(self, port: int) -> int:
        wire = port + self.port_offset
        if not 1 <= wire <= 65535:
            raise ValueError(f"port {port} + offset {self.port_offset} is outside 1..65535")
        return wire

    def address(self, node: str) -> str:
        """Where a node is reached: host_map first, then its configured ip."""
        host = self.host_map.get(node) or self.cfg.node(node).ip
        if not host:
            raise ValueError(f"node '{node}' has no ip in {self.cfg.source} and none in host_map")
        return host

    @property
    def ports(self) -> tuple[int, ...]:
        """The configured ports this node listens on (before port_offset)."""
        return tuple(self._sockets)

    def local_address(self, port: int) -> tuple[str, int]:
        """The (host, port) on the wire of the socket for a configured port."""
        host, wire = self._sockets[port].getsockname()
        return host, wire

    @property
    def closed(self) -> bool:
        return self._closed

    def send(self, message_name: str, **values: Number | bytes) -> int:
        """Encode and send one message to every consumer; returns time.monotonic_ns() taken just before sending."""
        msg = self.cfg.message(message_name)
        if msg.bus != self.bus or msg.producer != self.node.name:
            raise ValueError(f"node '{self.node.name}' does not send '{message_name}' on bus '{self.bus}'")
        datagram = msg.encode_udp(**values)
        assert msg.udp is not None  # checked in __init__
        sock = self._sockets[msg.udp.src_port]
        targets = [(self.address(c), self._wire_port(msg.udp.dst_port)) for c in msg.consumers]
        t_send = time.monotonic_ns()
        for target in targets:
            sock.sendto(datagram, target)
        self.counters.sent += len(targets)
        return t_send

    def recv(self, timeout: float | None = None) -> Received | None:
        """The next datagram for this node, decoded; None when `timeout` seconds pass or wakeup() is called.
        Datagrams that do not decode are counted (Counters.unknown / malformed) and skipped."""
        deadline = None if timeout is None else time.monotonic() + max(0.0, timeout)
        while True:
            remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
            for key, _ in self._selector.select(remaining):
                if key.data is None:  # wakeup()
                    self._drain_wake()
                    return None
                got = self._read(self._sockets[key.data], key.data)
                if got is not None:
                    return got
            if deadline is not None and time.monotonic() >= deadline:
                return None

    def _read(self, sock: socket.socket, port: int) -> Received | None:
        try:
            data, (_, src) = sock.recvfrom(MAX_DATAGRAM)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError as exc:  # e.g. an ICMP error queued on the socket: report it, keep listening
            self._reject("malformed", f"port {port}: {exc}")
            return None
        t_recv = time.monotonic_ns()
        try:
            msg, values = self.cfg.decode_udp(self.bus, data, src_port=src - self.port_offset, dst_port=port)
        except CodecError as exc:
            self._reject("malformed", str(exc))
            return None
        except LookupError as exc:  # UnknownNameError, or an id that the ports do not single out
            self._reject("unknown", str(exc))
            return None
        if self.node.name not in msg.consumers:
            self._reject("unknown", f"'{msg.name}' arrived at port {port} but is not for '{self.node.name}'")
            return None
        self.counters.received += 1
        return Received(msg.name, values, t_recv)

    def _reject(self, kind: str, why: str) -> None:
        setattr(self.counters, kind, getattr(self.counters, kind) + 1)
        self.counters.last_error = why

    def wakeup(self) -> None:
        """Make a recv() blocked in another thread return None now."""
        with contextlib.suppress(OSError):  # closed, or already full of wake-ups: either way recv() returns
            self._wake_w.send(b"\0")

    def _drain_wake(self) -> None:
        with contextlib.suppress(OSError):  # BlockingIOError once empty
            while self._wake_r.recv(64):
                pass

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._selector.close()
        for sock in (*self._sockets.values(), self._wake_r, self._wake_w):
            sock.close()

    def __enter__(self) -> UdpEndpoint:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


class PcEndpoint(UdpEndpoint):
    """The PC (ROS computer) side: sends the 0x31 commands, receives the 0x42 encoder frames."""

    default_node = "pc"

    def __enter__(self) -> PcEndpoint:
        return self


# --- the echo that pairs a command with its answer ----------------------------------------------------------------


def _payload(msg: Message, values: Values) -> bytes:
    return msg.encode(**values)


def echo_reply(command: Message, answer: Message, values: Values, seq: int) -> dict[str, Number]:
    """The answer's values that echo a command: its payload is the command's payload, then `seq` (the count of
    commands received, from 0) little-endian in the remaining bytes, modulo their range."""
    room = answer.size - command.size
    if room <= 0:
        raise ValueError(f"'{answer.name}' ({answer.size} B) has no room to echo '{command.name}' ({command.size} B)")
    tail = (seq % (1 << (8 * room))).to_bytes(room, "little")
    return answer.decode(_payload(command, values) + tail)


def unpack_echo(command: Message, answer: Message, values: Values) -> tuple[int, dict[str, Number]]:
    """(seq, the command's values) from an answer made by echo_reply."""
    payload = _payload(answer, values)
    return int.from_bytes(payload[command.size :], "little"), command.decode(payload[: command.size])


def _counter_sample(msg: Message, k: int) -> dict[str, Number]:
    """The k-th periodic frame when nothing better is given: k as a little-endian counter filling the payload."""
    return msg.decode((k % (1 << (8 * msg.size))).to_bytes(msg.size, "little"))


# --- a stand-in microcontroller -----------------------------------------------------------------------------------


class StandInMcu:
    """An MCU node on a thread: answers every command it consumes with `answer` (by default echo_reply, so the PC
    can pair them), and with periodic=True also sends each message it produces at the configured period."""

    MAX_CATCH_UP = 100  # periods a late periodic sender makes up at once; beyond that the slots are dropped

    def __init__(
        self,
        cfg: RuntimeConfig,
        node: str = "mcu_hip",
        host_map: Mapping[str, str] | None = None,
        *,
        port_offset: int = 0,
        bus: str | None = None,
        answer: str | None = None,
        reply: ReplyFn | None = None,
        periodic: bool = False,
        sample: SampleFn | None = None,
        periodic_limit: int | None = None,
    ) -> None:
        self.endpoint = UdpEndpoint(cfg, node, host_map, port_offset=port_offset, bus=bus)
        try:
            self.answer = self._pick_answer(answer) if self.endpoint.consumes else None
            if self.answer is not None and reply is None:
                for command in self.endpoint.consumes:
                    echo_reply(command, self.answer, _counter_sample(command, 0), 0)  # fails now if it cannot echo
        except BaseException:
            self.endpoint.close()
            raise
        self._reply = reply
        self._periodic = [m for m in self.endpoint.produces if m.period_ns] if periodic else []
        self._sample = sample or _counter_sample
        self._limit = periodic_limit
        self.commands = 0  # commands received
        self.answers = 0  # answers sent
        self.periodic_sent: Counter[str] = Counter()
        self.missed_slots = 0  # periodic slots dropped after a stall longer than MAX_CATCH_UP periods
        self._stop = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name=f"netcfg-udp-{node}", daemon=True)

    def _pick_answer(self, answer: str | None) -> Message | None:
        if answer is not None:
            msg = self.endpoint.cfg.message(answer)
            if msg not in self.endpoint.produces:
                raise ValueError(f"node '{self.endpoint.node.name}' does not send '{answer}'")
            return msg
        if len(self.endpoint.produces) == 1:
            return self.endpoint.produces[0]
        if not self.endpoint.produces:
            return None  # a pure actuator: takes commands, answers nothing
        names = ", ".join(m.name for m in self.endpoint.produces)
        raise ValueError(f"node '{self.endpoint.node.name}' sends {names}; say which answers commands with answer=")

    @property
    def counters(self) -> Counters:
        return self.endpoint.counters

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def start(self) -> StandInMcu:
        self._thread.start()
        return self

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the thread and close the sockets; re-raises what made the thread fail, if anything did."""
        self._stop.set()
        self.endpoint.wakeup()
        if self._thread.is_alive():
            self._thread.join(timeout)
            if self._thread.is_alive():
                raise RuntimeError(f"{self._thread.name} did not stop within {timeout} s")
        self.endpoint.close()
        if self._error is not None:
            raise RuntimeError(f"{self._thread.name} failed: {self._error!r}") from self._error

    def __enter__(self) -> StandInMcu:
        return self.start()

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as exc:  # handed to stop(), which the owner calls
            self._error = exc

    def _loop(self) -> None:
        start = time.monotonic_ns()
        due = {m.name: start + (m.offset_ns or 0) for m in self._periodic}
        sent = {m.name: 0 for m in self._periodic}
        while not self._stop.is_set():
            now = time.monotonic_ns()
            for m in self._periodic:
                assert m.period_ns is not None
                if now - due[m.name] > self.MAX_CATCH_UP * m.period_ns:  # a long stall: drop, do not burst
                    skipped = (now - due[m.name]) // m.period_ns
                    self.missed_slots += skipped
                    due[m.name] += skipped * m.period_ns
                # catch up the slots a late wake-up missed, so the average rate is the configured one
                while due[m.name] <= now and (self._limit is None or sent[m.name] < self._limit):
                    self.endpoint.send(m.name, **self._sample(m, sent[m.name]))
                    sent[m.name] += 1
                    self.periodic_sent[m.name] += 1
                    due[m.name] += m.period_ns
            pending = [due[m.name] for m in self._periodic if self._limit is None or sent[m.name] < self._limit]
            timeout = None if not pending else max(0, min(pending) - time.monotonic_ns()) / 1e9
            got = self.endpoint.recv(timeout)
            if got is None:
                continue
            command = self.endpoint.cfg.message(got.message)
            seq = self.commands
            self.commands += 1
            if self.answer is None:
                continue
            if self._reply is not None:
                values = self._reply(command, got.values, seq)
            else:
                values = echo_reply(command, self.answer, got.values, seq)
            self.endpoint.send(self.answer.name, **values)
            self.answers += 1


# --- pairing commands with answers, and their round-trip times ----------------------------------------------------


@dataclass(frozen=True)
class RttStats:
    count: int
    min_us: float
    mean_us: float
    p50_us: float
    p99_us: float
    max_us: float

    def __str__(self) -> str:
        return (
            f"n={self.count} min {self.min_us:.1f} mean {self.mean_us:.1f} p50 {self.p50_us:.1f} "
            f"p99 {self.p99_us:.1f} max {self.max_us:.1f} us"
        )


def rtt_stats(samples_ns: Iterable[int]) -> RttStats:
    """min/mean/p50/p99/max in microseconds; percentiles by nearest rank (the ceil(p*n)-th smallest sample), the
    definition the simulator's reports use (netcfg.sim.stats: numpy's inverted_cdf), written out here because the
    runtime does without numpy."""
    xs = sorted(samples_ns)
    if not xs:
        raise ValueError("no round-trip samples")
    n = len(xs)

    def rank(p: float) -> float:
        return xs[max(1, math.ceil(p * n)) - 1] / 1e3

    return RttStats(n, xs[0] / 1e3, sum(xs) / n / 1e3, rank(0.50), rank(0.99), xs[-1] / 1e3)


@dataclass
class Pair:
    seq: int
    sent: dict[str, Number]  # the command's values as sent
    t_send_ns: int
    modulus: int  # the answer carries seq modulo this (its bytes left after the echoed command)
    answer_seq: int | None = None  # the seq the answer carried
    echoed: dict[str, Number] | None = None  # the command's values as the MCU decoded and echoed them
    t_recv_ns: int | None = None

    @property
    def matched(self) -> bool:
        return self.answer_seq == self.seq % self.modulus and self.echoed == self.sent

    @property
    def rtt_ns(self) -> int | None:
        return None if self.t_recv_ns is None else self.t_recv_ns - self.t_send_ns


@dataclass
class ExchangeResult:
    pairs: list[Pair]
    elapsed_ns: int  # first send to last answer (or the end of the drain)
    unmatched: int = 0  # answers whose seq names no command sent
    duplicates: int = 0  # second answers to one command
    others: Counter[str] = field(default_factory=Counter)  # other messages received meanwhile, by name

    @property
    def answered(self) -> int:
        return sum(p.t_recv_ns is not None for p in self.pairs)

    def rtt(self) -> RttStats:
        return rtt_stats(p.rtt_ns for p in self.pairs if p.rtt_ns is not None)


def exchange(
    pc: UdpEndpoint,
    command: str,
    answer: str,
    count: int,
    *,
    period_ns: int | None = None,
    values: Callable[[int], Values] | None = None,
    on_other: Callable[[Received], None] | None = None,
    drain_s: float = 1.0,
) -> ExchangeResult:
    """Send `count` commands paced at `period_ns` (default: the command's configured period), as the PC's control
    loop would, and pair every answer made by echo_reply with its command by sequence number."""
    cmd, ans = pc.cfg.message(command), pc.cfg.message(answer)
    period = period_ns if period_ns is not None else cmd.period_ns
    if not period or period <= 0:
        raise ValueError(f"'{command}' has no configured period; give period_ns")
    modulus = 1 << (8 * (ans.size - cmd.size))
    make = values or (lambda i: _counter_sample(cmd, i))
    pairs: list[Pair] = []
    waiting: dict[int, Pair] = {}
    result = ExchangeResult(pairs, 0)
    t0 = next_send = time.monotonic_ns()
    drain_end: int | None = None
    while True:
        now = time.monotonic_ns()
        if len(pairs) < count and now >= next_send:
            sent = dict(cmd.decode(cmd.encode(**make(len(pairs)))))  # as the codec gives them back
            pair = Pair(len(pairs), sent, pc.send(command, **sent), modulus)
            pairs.append(pair)
            waiting[pair.seq % modulus] = pair
            # keep the grid; after a stall longer than a period, restart it rather than burst
            next_send = next_send + period if now - next_send < period else now + period
            continue
        if len(pairs) == count:
            if not waiting:
                break
            drain_end = drain_end or now + int(drain_s * 1e9)
            if now >= drain_end:
                break
        wait_until = next_send if len(pairs) < count else (drain_end or now)
        got = pc.recv(max(0, wait_until - now) / 1e9)
        if got is None:
            continue
        if got.message != answer:
            result.others[got.message] += 1
            if on_other is not None:
                on_other(got)
            continue
        seq, echoed = unpack_echo(cmd, ans, got.values)
        matched_pair = waiting.pop(seq, None)
        if matched_pair is None:
            if any(p.answer_seq is not None and p.seq % modulus == seq for p in pairs[-modulus:]):
                result.duplicates += 1
            else:
                result.unmatched += 1
            continue
        matched_pair.answer_seq, matched_pair.echoed, matched_pair.t_recv_ns = seq, echoed, got.t_recv_ns
    answered = [p.t_recv_ns for p in pairs if p.t_recv_ns is not None]
    end = time.monotonic_ns() if waiting or not answered else max(answered)
    result.elapsed_ns = end - t0
    return result
