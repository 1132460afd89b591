"""netcfg.runtime.ethercat_setup, the bring-up of specs/allex2_ethercat.yaml's segment through SOEM's pysoem: on a
stand-in for pysoem's master whose slave methods take the calls as pysoem's own classes do, the identity check, the
start-up SDOs byte for byte and SYNC0 in each slave's hook, and the mapped image against netcfg's layout."""

from __future__ import annotations

import inspect
from dataclasses import dataclass, field
from typing import Any

import pytest

from netcfg.runtime.ethercat_setup import SetupError, check_image, configure, sdo_data
from tests.conftest import SPECS, runtime_config

EPOS4_VENDOR = 0x000000FB  # maxon's vendor id (the EPOS4 EDS's [DeviceInfo] VendorNumber; the epos4 profile's)
NODES = ["hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r"]


@dataclass
class Slave:
    """pysoem's CdefSlave as far as the bring-up uses it: what SOEM read of the slave, and what is written to it."""

    name: str = "EPOS4"
    man: int = EPOS4_VENDOR
    id: int = 0x12345678  # any: the spec's epos4 profile names no product code (a variant's), so none is compared
    rev: int = 0x01
    output: bytes = bytes(10)  # what SOEM maps after the hook's PDOs: 10 bytes out, 16 in (the spec's, by hand below)
    input: bytes = bytes(16)
    config_func: Any = None
    written: list[tuple[int, int, bytes]] = field(default_factory=list)
    synced: list[tuple[bool, int, int]] = field(default_factory=list)

    def sdo_write(self, index: int, subindex: int, data: bytes, ca: bool = False) -> None:
        self.written.append((index, subindex, data))

    def dc_sync(self, act: bool, sync0_cycle_time: int, sync0_shift_time: int = 0,
                sync1_cycle_time: int | None = None) -> None:
        self.synced.append((act, sync0_cycle_time, sync0_shift_time))


@dataclass
class Master:
    slaves: list[Slave]


def segment() -> Any:
    return runtime_config(SPECS / "allex2_ethercat.yaml").bus("ecat0").ethercat


def line() -> Master:
    return Master([Slave() for _ in NODES])


def test_the_calls_are_pysoems() -> None:
    """The calls the bring-up makes bind to pysoem's own methods, their arguments in pysoem's order (pysoem 1.1.13:
    sdo_write(index, subindex, data, ca=False), dc_sync(act, sync0_cycle_time, sync0_shift_time=0, ...)), and the
    attributes it reads and sets are pysoem's properties."""
    pysoem = pytest.importorskip("pysoem")

    def names(f: Any, n: int) -> list[str]:
        return list(inspect.signature(f).parameters)[:n]

    inspect.signature(pysoem.CdefSlave.sdo_write).bind(None, 0x1600, 1, b"\x10\x00\x40\x60")
    inspect.signature(pysoem.CdefSlave.dc_sync).bind(None, True, 1_000_000, 500_000)
    assert names(pysoem.CdefSlave.sdo_write, 4) == names(Slave.sdo_write, 4) == ["self", "index", "subindex", "data"]
    assert names(pysoem.CdefSlave.dc_sync, 4) == names(Slave.dc_sync, 4) == [
        "self", "act", "sync0_cycle_time", "sync0_shift_time"]
    for name in ("config_func", "man", "id", "rev", "name", "output", "input"):
        assert isinstance(getattr(pysoem.CdefSlave, name), property), name
    assert pysoem.Master().slaves is None  # before config_init: configure() takes it as no slave found


def test_each_slave_writes_its_mapping_then_its_assignment() -> None:
    master = line()
    configure(master, segment())
    for k, slave in enumerate(master.slaves):
        slave.config_func(k)  # as SOEM runs the hook, PRE-OP to SAFE-OP (pysoem passes the 0-based position)
    # The spec's RxPDO 0x1600: controlword (0x6040, 16 bits), target position (0x607A, 32), velocity offset
    # (0x60B1, 32). A mapping entry is index << 16 | sub << 8 | bits (CiA 301 7.4.8.2), an UNSIGNED32 sent
    # little-endian (ETG.1000.6): 0x60400010 -> 10 00 40 60. The sub-index 0 is cleared first and counted last.
    first = master.slaves[0].written
    assert first[:5] == [
        (0x1600, 0, b"\x00"),
        (0x1600, 1, b"\x10\x00\x40\x60"),
        (0x1600, 2, b"\x20\x00\x7a\x60"),
        (0x1600, 3, b"\x20\x00\xb1\x60"),
        (0x1600, 0, b"\x03"),
    ]
    # then the assignments: 0x1C12 gets 0x1600 (an UNSIGNED16: 00 16), 0x1C13 gets 0x1A00 and 0x1A01
    assert first[-7:] == [
        (0x1C12, 0, b"\x00"), (0x1C12, 1, b"\x00\x16"), (0x1C12, 0, b"\x01"),
        (0x1C13, 0, b"\x00"), (0x1C13, 1, b"\x00\x1a"), (0x1C13, 2, b"\x01\x1a"), (0x1C13, 0, b"\x02"),
    ]
    sdo = segment()["slaves"][0]["sdo"]
    assert first == [(x["index"], x["sub"], sdo_data(x)) for x in sdo]  # every one, in runtime.json's order
    assert all(s.written == first for s in master.slaves)  # six drives with the same PDOs
    # then SYNC0 (the spec: a 1 ms cycle, SYNC0 500 us after its start; every EPOS4 in DC mode, AssignActivate
    # 0x0300), started before the slave enters SAFE-OP, where a DC slave checks it
    assert all(s.synced == [(True, 1_000_000, 500_000)] for s in master.slaves)


def test_a_line_that_differs_is_refused_before_anything_is_written() -> None:
    master = line()
    master.slaves[3].man, master.slaves[3].name = 0x00000002, "EK1100"  # Beckhoff's vendor id (0x2) at hip_r's place
    with pytest.raises(SetupError, match=r"slave 3 \(hip_r, epos4\): vendor id 0x00000002 on the wire, "
                                         r"0x000000FB in the spec \('EK1100' is at its place\)"):
        configure(master, segment())
    assert all(s.config_func is None for s in master.slaves)
    short = Master(line().slaves[:5])
    with pytest.raises(SetupError, match="found 5 slave"):
        configure(short, segment())
    with pytest.raises(SetupError, match="found 0 slave"):
        configure(Master([]), segment())
    newer = line()
    newer.slaves[0].rev = 0x02  # newer firmware than the spec's: SOEM does not compare revisions, nor does this
    configure(newer, segment())


def test_more_than_sync0_is_refused() -> None:
    seg = segment()
    seg["slaves"][0]["dc"]["assign_activate"] = 0x0700  # SYNC0 and SYNC1: the segment gives no SYNC1 cycle
    master = line()
    with pytest.raises(SetupError, match=r"slave 0 \(hip_l\): AssignActivate 0x0700 is not SYNC0 alone"):
        configure(master, seg)
    assert all(s.config_func is None for s in master.slaves)


def test_the_mapped_image_is_netcfgs() -> None:
    """Each EPOS4: 10 bytes out (2 + 4 + 4, the RxPDO above), 16 in (0x1A00: 2 + 4 + 4; 0x1A01: 2 + 4)."""
    check_image(line(), segment())
    master = line()
    master.slaves[5].input = bytes(12)  # a TxPDO SOEM did not map as netcfg laid it out
    with pytest.raises(SetupError, match=r"slave 5 \(ankle_r\): SOEM mapped 12 bytes of inputs, netcfg laid out 16"):
        check_image(master, segment())
