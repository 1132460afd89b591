"""Device profiles: netcfg's built-in EPOS4 profile against maxon's own EDS, and PDO maps against both."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from conftest import EPOS4_EDS, SPECS, bus, check, check_data, load_spec

from netcfg.devices import builtin_profile, builtin_profile_names
from netcfg.devices.eds import import_eds


def test_builtin_profiles_are_listed() -> None:
    assert "epos4" in builtin_profile_names()


@pytest.mark.usefixtures("needs_shared")
def test_builtin_epos4_agrees_with_the_vendor_eds() -> None:
    """Every object of the built-in profile exists in maxon's EDS with the same data type, access and PDO
    mapping flag; the PDO counts and the missing TPDO event timer (0x1800 has sub-indices 0-3) agree too."""
    vendor = import_eds(EPOS4_EDS, "epos4_vendor")
    ours = builtin_profile("epos4")
    for (index, sub), obj in ours.objects.items():
        theirs = vendor.lookup(index, sub)
        assert theirs is not None, obj.ref
        assert (obj.data_type, obj.access, obj.pdo_mappable) == (
            theirs.data_type,
            theirs.access,
            theirs.pdo_mappable,
        ), obj.ref
    assert (ours.rpdo_count, ours.tpdo_count) == (vendor.rpdo_count, vendor.tpdo_count) == (4, 4)
    assert ours.max_mapped_objects == vendor.max_mapped_objects == 12
    assert ours.tpdo_event_timer is vendor.tpdo_event_timer is False
    assert ours.vendor_id == 0xFB


@pytest.mark.usefixtures("needs_shared")
def test_allex2_pdo_maps_validate_against_the_vendor_eds(tmp_path: Path) -> None:
    """The same network with every drive described by maxon's EDS instead of the built-in profile."""
    shutil.copy(EPOS4_EDS, tmp_path / "epos4.eds")
    data = load_spec("allex2.yaml")
    for node in data["nodes"]:
        if node.get("device") == "epos4":
            node["device"] = {"eds": "epos4.eds"}
    report = check_data(tmp_path, data)
    assert report["ok"], report["errors"]
    builtin = check(SPECS / "allex2.yaml")
    assert bus(report, "can0")["messages"] == bus(builtin, "can0")["messages"]


@pytest.mark.usefixtures("needs_shared")
@pytest.mark.parametrize(
    ("change", "code", "text"),
    [
        ({"map": [0x6064]}, "pdo-direction", "read-only"),  # position actual value into an RPDO
        ({"map": [0x1000]}, "not-mappable", "not PDO-mappable"),  # device type
        ({"map": [0x6999]}, "unknown-object", "does not exist"),
        ({"map": [0x60C2]}, "not-mappable", "give '0x60C2:1'"),  # a record: its sub-index 0 is the count
        ({"map": [0x60FF, 0x60B1, 0x607A]}, "pdo-length", "96 bits"),
        ({"rpdo": 5}, "pdo-number", "has 4 RPDOs"),
    ],
)
def test_pdo_map_mistakes_against_the_vendor_eds(tmp_path: Path, change: dict, code: str, text: str) -> None:
    shutil.copy(EPOS4_EDS, tmp_path / "epos4.eds")
    data = load_spec("allex2.yaml")
    for node in data["nodes"]:
        if node.get("device") == "epos4":
            node["device"] = {"eds": "epos4.eds"}
    cmd = next(m for m in data["messages"] if m["name"] == "hip_l_cmd")
    cmd["pdo"].update(change)
    if "rpdo" in change:
        cmd["id"] = 0x220
    report = check_data(tmp_path, data)
    assert not report["ok"]
    err = next(e for e in report["errors"] if e["code"] == code)
    assert text in err["message"]
    if code != "pdo-length":
        assert "(epos4.eds)" in err["message"]  # the device file as the spec names it


def test_broken_eds_is_reported(tmp_path: Path) -> None:
    (tmp_path / "broken.eds").write_text("[1000]\nParameterName=x\nObjectType=0x7\nDataType=zz\n")
    data = load_spec("allex2.yaml")
    data["nodes"][1]["device"] = {"eds": "broken.eds"}
    report = check_data(tmp_path, data)
    assert any(e["code"] == "eds-invalid" for e in report["errors"])
