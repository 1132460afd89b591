"""netcfg.runtime.udp on the loopback interface: the PC endpoint and stand-in MCUs of seed 001, from runtime.json.

Numbers come from seed 001 (Table 6.1: a UDP payload is one byte of message id, 0x31 = 1-byte PWM+DIR command,
0x42 = 4-byte encoder measurement; SAHR runs its PID at 1 kHz and each MCU transmits at 15 kHz), from
specs/ntua_sahr.yaml and specs/ntua_treadmill.yaml (ports: encoders 5001 -> 6001/6002, commands 6001 -> 5001), as
their committed generated/*/runtime.json carry them, and from the issue's acceptance test (10,000 pairs).

Every node gets its own 127.a.b.x address (Linux routes all of 127.0.0.0/8 to lo), so both SAHR MCUs bind the
configured port 5001; a.b come from the process id so two test runs on one machine do not take each other's ports.
"""

from __future__ import annotations

import json
import os
import random
import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest
from conftest import ROOT

import netcfg.runtime as rt
from netcfg.runtime.udp import (
    ExchangeResult,
    PcEndpoint,
    Received,
    StandInMcu,
    UdpEndpoint,
    echo_reply,
    exchange,
    loopback_hosts,
    rtt_stats,
    unpack_echo,
)

NET = f"127.{(os.getpid() >> 8) & 0xFF}.{os.getpid() & 0xFF}"
PAIRS = 10_000  # the acceptance test


@pytest.fixture(scope="module")
def sahr() -> rt.RuntimeConfig:
    return rt.load(ROOT / "generated" / "ntua_sahr" / "runtime.json")


@pytest.fixture(scope="module")
def treadmill() -> rt.RuntimeConfig:
    return rt.load(ROOT / "generated" / "ntua_treadmill" / "runtime.json")


@pytest.fixture(scope="module")
def hosts(sahr: rt.RuntimeConfig) -> dict[str, str]:
    return loopback_hosts(sahr, NET)


@pytest.fixture
def impostor(hosts: dict[str, str]) -> Iterator[socket.socket]:
    """A plain socket where mcu_hip would be (its address, port 5001 as ntua_sahr.yaml gives): sends raw bytes."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((hosts["mcu_hip"], 5001))
    sock.settimeout(2.0)
    yield sock
    sock.close()


def test_udp_runtime_does_not_import_the_compiler() -> None:
    """A live PC endpoint runs on netcfg.runtime and the standard library alone (DESIGN.md, runtime contract)."""
    code = (
        "import json, sys, netcfg.runtime as rt, netcfg.runtime.udp as udp\n"
        "cfg = rt.load('generated/ntua_sahr/runtime.json')\n"
        "with udp.PcEndpoint(cfg, host_map=udp.loopback_hosts(cfg, sys.argv[1])) as pc:\n"
        "    pc.send('hip_pwm', hip_pwm_raw=1)\n"
        "print(json.dumps(sorted(sys.modules)))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code, NET], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 0, proc.stderr
    loaded = json.loads(proc.stdout)
    # netcfg.cia301 is allowed: a table of the standard with no dependencies, which the runtime's CANopen parts use;
    # so is netcfg.inputs, the input guard every reader goes through (standard library only)
    allowed = ("netcfg.runtime", "netcfg.cia301", "netcfg.inputs")
    assert [m for m in loaded if m.startswith("netcfg.") and not m.startswith(allowed)] == []
    assert "netcfg.runtime.udp" in loaded and "pydantic" not in loaded and "yaml" not in loaded


def test_loopback_hosts_follow_the_configured_addresses(sahr: rt.RuntimeConfig) -> None:
    """ntua_sahr.yaml: pc 192.168.1.1, mcu_hip .11, mcu_spring .12 -> the same last octets on loopback."""
    assert loopback_hosts(sahr) == {"mcu_hip": "127.0.0.11", "mcu_spring": "127.0.0.12", "pc": "127.0.0.1"}
    with pytest.raises(ValueError, match=r"127\.0\.0\.0/8"):
        loopback_hosts(sahr, "10.0.0")


def test_endpoints_bind_the_configured_ports(sahr: rt.RuntimeConfig, hosts: dict[str, str]) -> None:
    """ntua_sahr.yaml: the PC receives hip_encoder on 6001 and spring_encoder on 6002 and sends hip_pwm from 6001;
    each MCU sends from, and mcu_hip receives on, 5001."""
    with (
        PcEndpoint(sahr, host_map=hosts) as pc,
        UdpEndpoint(sahr, "mcu_hip", hosts) as hip,
        UdpEndpoint(sahr, "mcu_spring", hosts) as spring,
    ):
        assert pc.ports == (6001, 6002)
        assert hip.ports == (5001,) and spring.ports == (5001,)
        with pytest.raises(OSError, match=f"node 'pc' cannot bind {hosts['pc']}:6001"):
            PcEndpoint(sahr, host_map=hosts)  # the first one holds it
        with pytest.raises(ValueError, match="does not send 'hip_encoder'"):
            pc.send("hip_encoder", hip_encoder_raw=1)


def test_wire_format_and_ports(sahr: rt.RuntimeConfig, hosts: dict[str, str]) -> None:
    """Table 6.1 on the wire (the id byte, then the data; the byte order is netcfg's, little-endian as its codec
    documents, since the paper does not give one): hip_encoder = 1234 is 42 d2 04 00 00, sent from
    mcu_hip's port 5001 to the PC's port 6001; hip_pwm = 0x80 is 31 80, sent from 6001 to mcu_hip's 5001."""
    pc_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    pc_sock.bind((hosts["pc"], 6001))
    pc_sock.settimeout(2.0)
    with pc_sock, UdpEndpoint(sahr, "mcu_hip", hosts) as hip:
        hip.send("hip_encoder", hip_encoder_raw=1234)
        assert pc_sock.recvfrom(64) == (bytes([0x42, 0xD2, 0x04, 0x00, 0x00]), (hosts["mcu_hip"], 5001))
        pc_sock.sendto(bytes([0x31, 0x80]), (hosts["mcu_hip"], 5001))
        got = hip.recv(2.0)
        assert got is not None and (got.message, got.values) == ("hip_pwm", {"hip_pwm_raw": 0x80})


def test_values_round_trip_exactly(sahr: rt.RuntimeConfig, hosts: dict[str, str]) -> None:
    """Every 1-byte command 0..255 reaches mcu_hip as sent; encoder values at the edges of 4 unsigned bytes
    (0, 1, 2^31, 2^32 - 1) reach the PC as sent, and the two 0x42 streams are told apart by port (6001 / 6002)."""
    with (
        PcEndpoint(sahr, host_map=hosts) as pc,
        UdpEndpoint(sahr, "mcu_hip", hosts) as hip,
        UdpEndpoint(sahr, "mcu_spring", hosts) as spring,
    ):
        for value in range(256):
            pc.send("hip_pwm", hip_pwm_raw=value)
            got = hip.recv(2.0)
            assert got is not None and (got.message, got.values) == ("hip_pwm", {"hip_pwm_raw": value})
        for value in (0, 1, 1 << 31, (1 << 32) - 1):
            hip.send("hip_encoder", hip_encoder_raw=value)
            spring.send("spring_encoder", spring_encoder_raw=value ^ 0xFFFF_FFFF)
            got = [pc.recv(2.0), pc.recv(2.0)]
            assert all(g is not None for g in got)
            assert sorted((g.message, g.values) for g in got if g is not None) == [
                ("hip_encoder", {"hip_encoder_raw": value}),
                ("spring_encoder", {"spring_encoder_raw": value ^ 0xFFFF_FFFF}),
            ]
        assert pc.counters.received == 8 and pc.counters.unknown == pc.counters.malformed == 0
        assert pc.recv(0.0) is None  # nothing else arrived


def test_bad_datagrams_are_counted_not_fatal(
    sahr: rt.RuntimeConfig, hosts: dict[str, str], impostor: socket.socket
) -> None:
    """From mcu_hip's address and port: 0x99 is no id of Table 6.1; 0x31 exists but is not sent to the PC's 6001
    (hip_pwm goes 6001 -> 5001); 0x42 with 2 data bytes is short of the encoder's 4; an empty datagram has no id.
    Two unknown, two malformed; the good frame after them still arrives."""
    with PcEndpoint(sahr, host_map=hosts) as pc:
        for junk in (b"\x99\x01\x02\x03\x04", b"\x31\x10", b"\x42\x01\x02", b""):
            impostor.sendto(junk, (hosts["pc"], 6001))
        impostor.sendto(bytes([0x42, 7, 0, 0, 0]), (hosts["pc"], 6001))
        got = pc.recv(2.0)
        assert got is not None and (got.message, got.values) == ("hip_encoder", {"hip_encoder_raw": 7})
        assert (pc.counters.unknown, pc.counters.malformed, pc.counters.received) == (2, 2, 1)
        assert pc.counters.last_error == "an empty datagram has no message id"  # the last one rejected


def test_stand_in_mcu_survives_bad_datagrams(sahr: rt.RuntimeConfig, hosts: dict[str, str]) -> None:
    """From the PC's address and port 6001 (hip_pwm's source, ntua_sahr.yaml) to mcu_hip's 5001: a 0x31 with 2 data
    bytes (it has 1) and a lone unknown id 0x77 are counted; the next command is still answered, echoing it (0x5A)
    and the count of commands received before it (0)."""
    cmd, ans = sahr.message("hip_pwm"), sahr.message("hip_encoder")
    with StandInMcu(sahr, "mcu_hip", hosts) as mcu:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as junk:  # where the PC will be, before it is
            junk.bind((hosts["pc"], 6001))
            junk.sendto(b"\x31\x01\x02", (hosts["mcu_hip"], 5001))
            junk.sendto(b"\x77", (hosts["mcu_hip"], 5001))
        with PcEndpoint(sahr, host_map=hosts) as pc:
            pc.send("hip_pwm", hip_pwm_raw=0x5A)
            got = pc.recv(2.0)
        assert got is not None and got.message == "hip_encoder"
        assert unpack_echo(cmd, ans, got.values) == (0, {"hip_pwm_raw": 0x5A})
    assert (mcu.counters.malformed, mcu.counters.unknown, mcu.commands, mcu.answers) == (1, 1, 1, 1)
    assert not mcu.running and mcu.endpoint.closed


def test_echo_layout(sahr: rt.RuntimeConfig) -> None:
    """The 4-byte encoder answer carries the 1-byte command then a 3-byte sequence number, little-endian:
    command 0xAB, seq 0x010203 -> payload ab 03 02 01 = 0x010203AB; seq wraps at 2^24."""
    cmd, ans = sahr.message("hip_pwm"), sahr.message("hip_encoder")
    assert echo_reply(cmd, ans, {"hip_pwm_raw": 0xAB}, 0x010203) == {"hip_encoder_raw": 0x010203AB}
    assert unpack_echo(cmd, ans, {"hip_encoder_raw": 0x010203AB}) == (0x010203, {"hip_pwm_raw": 0xAB})
    assert echo_reply(cmd, ans, {"hip_pwm_raw": 1}, (1 << 24) + 5) == {"hip_encoder_raw": 0x0501}
    with pytest.raises(ValueError, match="no room"):
        echo_reply(ans, cmd, {"hip_encoder_raw": 1}, 0)


def test_rtt_stats_by_hand() -> None:
    """Samples 1, 2, ..., 100 us: mean 50.5; nearest rank p50 = the 50th = 50, p99 = the 99th = 99."""
    stats = rtt_stats(i * 1000 for i in range(100, 0, -1))
    assert (stats.count, stats.min_us, stats.mean_us, stats.p50_us, stats.p99_us, stats.max_us) == (
        100,
        1.0,
        50.5,
        50.0,
        99.0,
        100.0,
    )
    one = rtt_stats([7_500])  # one sample is every statistic
    assert (one.min_us, one.p50_us, one.p99_us, one.max_us) == (7.5, 7.5, 7.5, 7.5)
    with pytest.raises(ValueError):
        rtt_stats([])


def test_periodic_stream_in_order(sahr: rt.RuntimeConfig, hosts: dict[str, str]) -> None:
    """mcu_spring sends spring_encoder at its configured period (66,667 ns = 15 kHz, runtime.json), here limited
    to 100 frames; the frame counter runs 0..99 and every frame arrives at the PC's 6002 as spring_encoder."""
    assert sahr.message("spring_encoder").period_ns == 66_667
    seen: list[Received] = []
    with (
        PcEndpoint(sahr, host_map=hosts) as pc,
        StandInMcu(sahr, "mcu_spring", hosts, periodic=True, periodic_limit=100) as mcu,
    ):
        while len(seen) < 100 and (got := pc.recv(2.0)) is not None:
            seen.append(got)
    assert [(g.message, g.values["spring_encoder_raw"]) for g in seen] == [("spring_encoder", k) for k in range(100)]
    assert mcu.periodic_sent == {"spring_encoder": 100} and mcu.answer is None


def never_early(result: ExchangeResult, period_ns: int) -> bool:
    """Every send at or after its slot on the pacer's grid, t0 + k * period: exchange() starts the grid at t0
    (elapsed_ns runs from there to the last answer) and a stall only moves it later. The span of the sends alone
    is no bound: it falls short of count - 1 periods by however late the first send was."""
    t0 = max(p.t_recv_ns for p in result.pairs if p.t_recv_ns is not None) - result.elapsed_ns
    return all(p.t_send_ns >= t0 + k * period_ns for k, p in enumerate(result.pairs))


def test_port_offset_moves_every_port(treadmill: rt.RuntimeConfig) -> None:
    """ntua_treadmill.yaml: pwm_cmd 6001 -> 5001, encoder 5001 -> 6001. With port_offset 10000 on one address the
    MCU listens on 15001 and answers from it to 16001; 20 pairs paced at the configured 2 kHz (500,000 ns) match."""
    assert treadmill.message("pwm_cmd").period_ns == 500_000
    one = {n.name: f"{NET}.1" for n in treadmill.nodes}
    with (
        PcEndpoint(treadmill, host_map=one, port_offset=10_000) as pc,
        StandInMcu(treadmill, "mcu", one, port_offset=10_000) as mcu,
    ):
        assert pc.local_address(6001) == (f"{NET}.1", 16001)
        assert mcu.endpoint.local_address(5001) == (f"{NET}.1", 15001)
        result = exchange(pc, "pwm_cmd", "encoder", 20)
    assert result.answered == 20 and all(p.matched for p in result.pairs)
    assert never_early(result, 500_000)


def test_ten_thousand_pairs_at_the_configured_rate(sahr: rt.RuntimeConfig, hosts: dict[str, str]) -> None:
    """The acceptance test: the PC sends 10,000 hip_pwm commands paced at their configured period (1,000,000 ns
    = the 1 kHz PID, runtime.json), mcu_hip answers each with hip_encoder echoing the command and its count, and
    every pair must match. hip_pwm is the only command in ntua_sahr.yaml (mcu_spring consumes none), so pairs
    cannot be split across both MCUs: the run takes 10 s. Meanwhile mcu_spring streams spring_encoder at its
    configured 15 kHz, as on the robot, so the PC tells the two 0x42 streams apart by port while it measures.
    Random PWM+DIR bytes (fixed seed) make a shifted or corrupted echo visible. No timing is asserted."""
    cmd = sahr.message("hip_pwm")
    assert cmd.period_ns == 1_000_000
    rng = random.Random(1)
    commands = [rng.randrange(256) for _ in range(PAIRS)]
    spring: list[int] = []
    started = time.monotonic()
    with (
        PcEndpoint(sahr, host_map=hosts) as pc,
        StandInMcu(sahr, "mcu_hip", hosts) as hip,
        StandInMcu(sahr, "mcu_spring", hosts, periodic=True) as spring_mcu,
    ):
        result = exchange(
            pc,
            "hip_pwm",
            "hip_encoder",
            PAIRS,
            values=lambda i: {"hip_pwm_raw": commands[i]},
            on_other=lambda got: spring.append(int(got.values["spring_encoder_raw"])),
        )
    wall = time.monotonic() - started

    assert len(result.pairs) == PAIRS and result.answered == PAIRS
    assert [p.seq for p in result.pairs] == list(range(PAIRS))
    assert all(p.answer_seq == p.seq for p in result.pairs)
    assert all(p.sent == {"hip_pwm_raw": c} and p.echoed == p.sent for p, c in zip(result.pairs, commands))
    assert (result.unmatched, result.duplicates) == (0, 0)
    assert (hip.commands, hip.answers, hip.counters.malformed, hip.counters.unknown) == (PAIRS, PAIRS, 0, 0)
    assert (pc.counters.sent, pc.counters.malformed, pc.counters.unknown) == (PAIRS, 0, 0)
    # the spring stream: its counter only rises (0, 1, 2, ...; none reordered), never more than were sent
    assert set(result.others) <= {"spring_encoder"}
    assert spring, "the spring stream must actually arrive for the two 0x42 streams to be told apart"
    assert spring == sorted(set(spring)) and len(spring) <= spring_mcu.periodic_sent["spring_encoder"]
    assert never_early(result, cmd.period_ns)  # paced at the configured period

    rtt = result.rtt()
    rate = (PAIRS - 1) / ((result.pairs[-1].t_send_ns - result.pairs[0].t_send_ns) / 1e9)
    print(f"\nUDP loopback, {PAIRS} hip_pwm/hip_encoder pairs at {rate:.1f} Hz (configured 1000 Hz), {wall:.1f} s")
    print(f"round trip: {rtt}")
    print(
        f"spring_encoder meanwhile: {len(spring)} received of {spring_mcu.periodic_sent['spring_encoder']} sent, "
        f"{spring_mcu.missed_slots} slots missed (configured 15 kHz)"
    )
