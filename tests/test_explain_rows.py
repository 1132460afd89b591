"""`check --explain` derives every row check's table lists, the protocol's own frames (SYNC, heartbeats) too."""

from __future__ import annotations

import json

from conftest import SPECS, cli


def explain(name: str) -> dict:
    proc = cli("check", str(SPECS / "allex2.yaml"), "--explain", name, "--format", "json")
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_the_sync_row_is_explained() -> None:
    """ALLEX-2's SYNC leaves the master's FIFO with its twelve RxPDOs (README, Transmit queues): blocking by the
    longest lower-priority frame, a 1-byte heartbeat (55 + 10 stuff bits = 65 us at 1 Mbit/s), the queue's 1,315 us
    (SYNC 55, six 8-byte RxPDO1 of 135, six 2-byte RxPDO2 of 75: 55 + 810 + 450), and the twelve TPDOs above the
    queue's lowest message (six of 135, six 6-byte of 115: 1,500): 65 + 1,315 + 1,500 = 2,880 us."""
    doc = explain("can0_SYNC")
    assert doc["frame"]["c_us"] == 55 and doc["id"] == 0x80
    assert doc["wcrt_us"] == 65 + 1315 + 1500


def test_a_heartbeat_row_is_explained() -> None:
    """A heartbeat is one byte (CiA 301 7.2.8.3.2.4): 47 + 8 = 55 bits and up to 10 stuff bits, C = 65 us."""
    doc = explain("hip_l_heartbeat")
    assert doc["id"] == 0x700 + 1 and doc["frame"]["bits_worst"] == 65 and doc["wcrt_us"] is not None


def test_an_unknown_name_suggests_a_protocol_frame() -> None:
    proc = cli("check", str(SPECS / "allex2.yaml"), "--explain", "can0_SYNK")
    assert proc.returncode == 2 and "did you mean 'can0_SYNC'?" in proc.stderr, proc.stderr
