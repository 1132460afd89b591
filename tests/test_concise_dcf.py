"""Lely's concise DCF (`canopen/<node>.bin`) beside every slave's DCF.

The format (CiA 302-3 concise DCF as Lely's dcfgen writes and Lely's master reads it): UNSIGNED32 entry count,
then per entry index U16, sub-index U8, size U32, value; little-endian. Decoded here with struct alone, then held
against the DCF as the `canopen` package reads it, against hand-written values from the spec and CiA 301, and,
where Lely's dcf-tools are installed, against Lely's own dcfgen run on the bus.yml netcfg writes.
"""

from __future__ import annotations

import logging
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import canopen
import pytest
from canopen.objectdictionary import ODArray, ODRecord, ODVariable

from netcfg.check import analyse_spec
from netcfg.emit import emit_all
from tests.conftest import SPECS

logging.getLogger("canopen").setLevel(logging.ERROR)

DRIVES = {"hip_l": 1, "knee_l": 2, "ankle_l": 3, "hip_r": 4, "knee_r": 5, "ankle_r": 6}  # allex2.yaml node ids
Entry = tuple[int, int, int, int]


def decode(data: bytes) -> list[Entry]:
    """An independent reader: count, then (index, sub, size, value) until the data ends exactly."""
    (count,) = struct.unpack_from("<I", data, 0)
    pos, out = 4, []
    for _ in range(count):
        index, sub, size = struct.unpack_from("<HBI", data, pos)
        pos += 7
        assert 0 < size <= 8 and pos + size <= len(data), (hex(index), sub, size)
        out.append((index, sub, size, int.from_bytes(data[pos : pos + size], "little")))
        pos += size
    assert pos == len(data), "bytes after the last entry"
    return out


def final(entries: list[Entry]) -> dict[tuple[int, int], int]:
    """What the slave holds after the writes: the last value written to each object."""
    return {(i, s): v for i, s, _, v in entries}


@pytest.fixture(scope="module")
def allex2(tmp_path_factory: pytest.TempPathFactory) -> Path:
    model, report = analyse_spec(SPECS / "allex2.yaml")
    assert model is not None and report["ok"]
    out = tmp_path_factory.mktemp("allex2")
    for rel, data in emit_all(model, report).items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(data)
    return out


def test_one_concise_dcf_per_slave_and_none_for_the_master(allex2: Path) -> None:
    assert sorted(p.stem for p in (allex2 / "canopen").glob("*.bin")) == sorted(DRIVES)


def test_hip_l_rpdo1_is_written_as_cia301_says(allex2: Path) -> None:
    """allex2.yaml: hip_l_cmd is RPDO1 of node 1, transmission 255, map [0x60FF, 0x60B1] (both INTEGER32).
    CiA 301: COB-ID 0x200 + 1; invalid = bit 31; a mapping entry is index << 16 | sub << 8 | bits."""
    entries = decode((allex2 / "canopen" / "hip_l.bin").read_bytes())
    rpdo1 = [e for e in entries if e[0] in (0x1400, 0x1600)]
    assert rpdo1 == [
        (0x1400, 1, 4, 0x80000201),
        (0x1400, 2, 1, 255),
        (0x1600, 0, 1, 0),
        (0x1600, 1, 4, 0x60FF0020),
        (0x1600, 2, 4, 0x60B10020),
        (0x1600, 0, 1, 2),
        (0x1400, 1, 4, 0x00000201),
    ]
    # RPDO3/4 and TPDO3/4 are unused in the spec: invalidated at their CiA 301 default COB-IDs
    assert final(entries)[(0x1402, 1)] == 0x80000401
    assert final(entries)[(0x1803, 1)] & 0x80000000


def _var(od: canopen.ObjectDictionary, index: int, sub: int) -> ODVariable:
    obj = od[index]
    if isinstance(obj, (ODRecord, ODArray)):
        return obj[sub]
    assert sub == 0
    return obj


@pytest.mark.parametrize("drive", sorted(DRIVES))
def test_every_write_matches_the_dcf_as_canopen_reads_it(allex2: Path, drive: str) -> None:
    """Each object written exists in the slave's DCF with the same size (its data type), and the value the slave
    ends with is the DCF's ParameterValue: the concise DCF and the DCF say the same."""
    od = canopen.import_od(str(allex2 / "canopen" / f"{drive}.dcf"), DRIVES[drive])
    entries = decode((allex2 / "canopen" / f"{drive}.bin").read_bytes())
    for index, sub, size, _ in entries:
        var = _var(od, index, sub)
        assert size * 8 == len(var), (hex(index), sub)
    for (index, sub), value in final(entries).items():
        var = _var(od, index, sub)
        assert var.value == value, (hex(index), sub, var.value, value)


def test_lely_dcfgen_agrees(allex2: Path, tmp_path: Path) -> None:
    """Lely's dcfgen, run on the bus.yml netcfg writes, produces its own .bin per slave. Every object it writes ends
    with the same value in ours, except bit 30 of TPDO COB-IDs: dcfgen's `cob_id: auto` leaves it clear, netcfg
    sets it as the vendors' EDS do (no RTR); both are valid COB-IDs for the same identifier."""
    beside = Path(sys.executable).parent / "dcfgen"  # installed in this environment, or anywhere on PATH
    dcfgen = str(beside) if beside.is_file() else shutil.which("dcfgen")
    if dcfgen is None:
        pytest.skip("Lely's dcf-tools (dcfgen) are not installed")
    work = tmp_path / "canopen"
    shutil.copytree(allex2 / "canopen", work)
    (work / "lely").mkdir()
    proc = subprocess.run([dcfgen, "-r", "bus.yml", "-d", "lely"], cwd=work, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    for drive in DRIVES:
        theirs = final(decode((work / "lely" / f"{drive}.bin").read_bytes()))
        ours = final(decode((work / f"{drive}.bin").read_bytes()))
        assert theirs, drive
        for (index, sub), value in theirs.items():
            mask = ~(1 << 30) if 0x1800 <= index < 0x1A00 and sub == 1 else ~0
            assert (index, sub) in ours and ours[(index, sub)] & mask == value & mask, (drive, hex(index), sub)
