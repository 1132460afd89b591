"""Bringing an EtherCAT segment up with SOEM through pysoem, from runtime.json's `ethercat` section of the bus: the
line the master found checked against the spec's, and each slave's configuration hook (pysoem's `config_func`, which
SOEM runs as the slave goes from PRE-OP to SAFE-OP, before it maps the process image): its start-up SDOs, then its
SYNC0 at the spec's cycle and shift, so that a DC slave has SYNC0 running when it checks for it on entering
SAFE-OP; then the image SOEM mapped checked against the one netcfg laid out:

    import pysoem
    from netcfg import runtime
    from netcfg.runtime.ethercat_setup import check_image, configure

    # netcfg build specs/allex2_ethercat.yaml -o build/allex2_ethercat
    segment = runtime.load("build/allex2_ethercat/runtime.json").bus("ecat0").ethercat
    master = pysoem.Master()
    master.open("eth0")
    master.config_init()
    master.config_dc()           # the clocks measured and aligned before any slave starts SYNC0
    configure(master, segment)   # SetupError if the line differs from the spec's
    master.config_map()          # runs each slave's hook, then asks every slave for SAFE-OP
    check_image(master, segment)

netcfg needs no pysoem itself: a master is anything with pysoem's `slaves` and slave methods (SlaveLike).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol

__all__ = ["SYNC0_ONLY", "MasterLike", "SetupError", "SlaveLike", "check_image", "check_line", "configure", "sdo_data"]

SYNC0_ONLY = 0x0300  # AssignActivate: cyclic unit and SYNC0 (registers 0x0980, 0x0981), what SOEM's ecx_dcsync0 sets


class SetupError(ValueError):
    """The segment on the wire is not the one runtime.json describes, or asks what SOEM cannot set."""


class SlaveLike(Protocol):
    """The part of pysoem's CdefSlave this module uses (pysoem 1.1.13, src/pysoem/pysoem.pyx)."""

    man: int  # the identity SOEM read from the slave's EEPROM (SII): vendor id, product code, revision
    id: int
    rev: int
    name: str
    output: bytes  # the slave's outputs and inputs in the mapped image
    input: bytes
    config_func: Any

    def sdo_write(self, index: int, subindex: int, data: bytes, ca: bool = False) -> None: ...

    def dc_sync(self, act: bool, sync0_cycle_time: int, sync0_shift_time: int = 0,
                sync1_cycle_time: int | None = None) -> None: ...


class MasterLike(Protocol):
    slaves: Sequence[SlaveLike] | None  # what config_init found, in wire order


def sdo_data(sdo: Mapping[str, int]) -> bytes:
    """A start-up SDO's value as CoE carries it: little-endian, its object's size (ETG.1000.6; CiA 301's encoding)."""
    bits = sdo["bits"]
    if bits % 8:
        raise SetupError(f"SDO 0x{sdo['index']:04X}:{sdo['sub']} of {bits} bits is not whole bytes")
    return int(sdo["value"]).to_bytes(bits // 8, "little")


def check_line(found: Sequence[SlaveLike], segment: Mapping[str, Any]) -> list[str]:
    """What differs between the slaves the master found and the segment's, position by position: vendor id and
    product code, where the spec knows them (0: a built-in profile without an ESI has no product code). The revision
    is not compared: a slave's firmware is often newer than its ESI, and SOEM does not compare it either."""
    expected = segment["slaves"]
    problems = []
    if len(found) != len(expected):
        problems.append(f"the master found {len(found)} slave(s); the segment has {len(expected)}")
    for k, (slave, s) in enumerate(zip(found, expected)):
        for what, key, got in (("vendor id", "vendor_id", slave.man), ("product code", "product_code", slave.id)):
            if s[key] and got != s[key]:
                problems.append(f"slave {k} ({s['node']}, {s['device']}): {what} 0x{got:08X} on the wire, "
                                f"0x{s[key]:08X} in the spec ({slave.name!r} is at its place)")
        act = s["dc"]["assign_activate"]
        if act not in (0, SYNC0_ONLY):
            problems.append(f"slave {k} ({s['node']}): AssignActivate 0x{act:04X} is not SYNC0 alone "
                            f"(0x{SYNC0_ONLY:04X}), the one SOEM's dc_sync without SYNC1 sets; the spec gives no SYNC1")
    return problems


def configure(master: MasterLike, segment: Mapping[str, Any]) -> None:
    """After config_init and config_dc: check the line, then give each slave its hook, which writes its start-up
    SDOs (the PDO mappings, then the assignments 0x1C12/0x1C13, each cleared, filled and counted) in runtime.json's
    order and then starts its SYNC0, if it has DC settings."""
    found = master.slaves or []
    problems = check_line(found, segment)
    if problems:
        raise SetupError("; ".join(problems))
    for slave, s in zip(found, segment["slaves"]):
        slave.config_func = _hook(slave, s)


def _hook(slave: SlaveLike, s: Mapping[str, Any]) -> Any:
    writes = [(sdo["index"], sdo["sub"], sdo_data(sdo)) for sdo in s["sdo"]]
    dc = s["dc"]

    def config_func(_position: int) -> None:  # pysoem passes the slave's position; the slave is bound here
        for index, sub, data in writes:
            slave.sdo_write(index, sub, data)
        if dc["assign_activate"]:
            slave.dc_sync(True, dc["sync0_cycle_ns"], dc["sync0_shift_ns"])

    return config_func


def check_image(master: MasterLike, segment: Mapping[str, Any]) -> None:
    """After config_map: each slave's outputs and inputs are the bytes netcfg laid out (its FMMUs' lengths), so
    the offsets of the analysis, the C header and the simulator are the master's."""
    problems = []
    for k, (slave, s) in enumerate(zip(master.slaves or [], segment["slaves"])):
        size = {f["direction"]: f["length"] for f in s["fmmu"]}
        for direction, got in (("outputs", len(slave.output)), ("inputs", len(slave.input))):
            if got != size.get(direction, 0):
                problems.append(f"slave {k} ({s['node']}): SOEM mapped {got} bytes of {direction}, netcfg laid out "
                                f"{size.get(direction, 0)}")
    if problems:
        raise SetupError("; ".join(problems))
