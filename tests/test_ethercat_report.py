"""The cycle analysis of specs/allex2_ethercat.yaml as report.md and check's text show it, each figure worked out by
hand here from the spec and the frame layout of netcfg.links.ethercat (IEEE 802.3, ETG.1000.4)."""

from __future__ import annotations

from netcfg.check import analyse_spec
from netcfg.emit import emit_all
from tests.conftest import SPECS, cli

C = 0.7 * 299_792_458  # cables at 0.7 c
# six EPOS4 axes: RxPDO 0x1600 (controlword 2 + target position 4 + velocity offset 4 = 10 bytes), TxPDOs 0x1A00
# (status 2 + position 4 + velocity 4) and 0x1A01 (torque 2 + current 4): 16 bytes; 60 out, 96 in
IMAGE = 6 * (10 + 16)  # 156 bytes in one LRW datagram
FRAME = 8 + 14 + 2 + 10 + IMAGE + 2 + 4 + 12  # 208 bytes on the wire
WIRE_US = FRAME * 0.08  # 16.64 us
CABLES_M = [0.5, 0.6, 0.6, 1.2, 0.6, 0.6]
# the spec's master_jitter; 2 us a slave (a CoE drive without an ESI: an RJ45 one, EK1101's "1 us typ." out and back)
JITTER_US, SLAVES_US = 50, 6 * 2.0
CABLES_US = 2 * sum(CABLES_M) / C * 1e6  # out and back: 0.039 us
LATENCY_US = JITTER_US + WIRE_US + SLAVES_US + CABLES_US  # 78.679 us
PASSED_LAST_US = JITTER_US + WIRE_US + SLAVES_US + sum(CABLES_M) / C * 1e6  # the frame has passed ankle_r: 78.66
MARGIN_US = 500 - 0.1 - PASSED_LAST_US  # SYNC0 at 500 us, less distributed clocks' 100 ns: 421.24 us


def test_report_md_shows_the_cycle() -> None:
    model, report = analyse_spec(SPECS / "allex2_ethercat.yaml")
    assert model is not None
    md = emit_all(model, report)["report.md"].decode()
    assert "## Bus ecat0: EtherCAT, 100 Mbit/s" in md and "### EtherCAT cycle" in md
    assert f"{FRAME} bytes on the wire" in md and f"Frame time: **{WIRE_US:.2f} us**" in md
    assert f"Back at the master after **{LATENCY_US:.3f} us**" in md
    assert f"the slaves' forwarding delays\n  ({SLAVES_US:g} us)" in md and f"({CABLES_US:.3f} us)" in md
    assert f"mailbox (CoE SDO) traffic: **{1000 - LATENCY_US:.3f} us**" in md
    assert f"SYNC0 shift margin: **{MARGIN_US:.2f} us**" in md
    row = (f"| 5 | ankle_r | epos4 | 10 | 16 | {SLAVES_US / 6:g} | 0.6 | {PASSED_LAST_US:.2f} | 500 | {MARGIN_US:.2f} "
           "| 0x0300 | ok |")
    assert row in md
    # the PDOs the hip's loop follows: TxPDO 0x1A00 at logical byte 60 (after the 60 output bytes), back with the
    # frame; RxPDO 0x1600 at byte 0, at hip_l once the frame has passed it (the jitter, the wire, its 2 us, 0.5 m)
    assert f"| hip_l_actual | 0x3C | 10 | 1,000 | 80 | 0.08 % | {LATENCY_US:.3f} |" in md
    passed_hip_us = JITTER_US + WIRE_US + SLAVES_US / 6 + CABLES_M[0] / C * 1e6
    assert f"| hip_l_target | 0x0 | 10 | 1,000 | 80 | 0.08 % | {passed_hip_us:.3f} |" in md


def test_check_text_shows_the_same_figures() -> None:
    done = cli("check", str(SPECS / "allex2_ethercat.yaml"))
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert f"1 frame(s) of {FRAME} bytes on the wire" in out
    assert f"back at the master after {LATENCY_US:.3f} us = jitter 50 + wire {WIRE_US:.2f} + slaves 12" in out
    assert f"{1000 - LATENCY_US:.3f} us left for mailbox traffic" in out
    assert f"SYNC0 after the frame has passed with {MARGIN_US:.2f} us to spare" in out
