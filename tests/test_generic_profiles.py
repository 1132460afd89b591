"""Generic device profiles: a CiA 402 drive or a CiA 301 device (a BMS) written without a vendor file, the latter
with its own application objects (`device: {profile: cia301, objects: [...]}`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import canopen
import pytest
from conftest import bus, check_data, cli, message

from netcfg.devices import builtin_profile

BMS_OBJECTS = [
    {"index": 0x2000, "sub": 1, "name": "Pack voltage", "type": "UNSIGNED16", "access": "ro"},
    {"index": 0x2000, "sub": 2, "name": "Pack current", "type": "INTEGER16", "access": "ro"},
    {"index": 0x2001, "name": "State of charge", "type": "UNSIGNED8", "access": "ro"},
]


def spec(device: Any, pdo_map: list[Any], name: str = "bms", node_id: int = 10) -> dict[str, Any]:
    return {
        "system": "base",
        "buses": [{"name": "can0", "protocol": "canopen", "bitrate": "500k", "canopen": {"sync_period": "10 ms"}}],
        "nodes": [
            {"name": "master", "role": "master", "node_id": 127, "buses": ["can0"]},
            {"name": name, "node_id": node_id, "buses": ["can0"], "heartbeat": "100 ms", "device": device},
        ],
        "messages": [
            {"name": f"{name}_state", "producer": name, "consumers": ["master"],
             "pdo": {"tpdo": 1, "transmission": 1, "map": pdo_map}},
        ],
    }


@pytest.mark.parametrize("profile", ["cia301", "cia402"])
def test_the_mandatory_objects_of_the_standards_are_there(profile: str) -> None:
    """CiA 301 v4.2: 0x1000, 0x1001 and 0x1018 sub 1 are mandatory; 0x1017 for the heartbeat. CiA 402-2: 0x6040,
    0x6041 and 0x6502 for every drive, and the cyclic modes' targets and actual values."""
    p = builtin_profile(profile)
    need = [(0x1000, 0), (0x1001, 0), (0x1018, 1), (0x1017, 0)]
    if profile == "cia402":
        need += [(0x6040, 0), (0x6041, 0), (0x6502, 0), (0x6060, 0), (0x6061, 0), (0x607A, 0), (0x6064, 0),
                 (0x60FF, 0), (0x606C, 0), (0x6071, 0), (0x6077, 0)]
    assert all(p.lookup(*key) is not None for key in need)
    assert p.rpdo_count == p.tpdo_count == 4  # CiA 301's predefined connection set


def test_a_bms_with_its_own_objects_is_checked_and_built(tmp_path: Path) -> None:
    """TPDO1 maps 16 + 16 + 8 bits = 5 bytes; a 5-byte standard frame is 47 + 40 = 87 bits with up to
    (34 + 40 - 1) // 4 = 18 stuff bits (ISO 11898-1), 105 bits = 210 us at 500 kbit/s."""
    report = check_data(tmp_path, spec({"profile": "cia301", "objects": BMS_OBJECTS}, ["0x2000:1", "0x2000:2", 0x2001]))
    assert report["ok"], report["errors"]
    row = message(bus(report, "can0"), "bms_state")
    assert (row["size"], row["frame_bits_worst"], row["frame_us_worst"]) == (5, 105, 210)
    proc = cli("build", str(tmp_path / "spec.yaml"), "-o", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    od = canopen.import_od(str(tmp_path / "out" / "canopen" / "bms.eds"))
    assert od[0x2000][1].name == "Pack voltage" and od[0x2000][1].data_type == 0x06  # UNSIGNED16
    assert od[0x2001].pdo_mappable and od[0x1017].name == "Producer heartbeat time"
    # the spec's device is no built-in one any more: bus.yml names its EDS, not the profile
    assert "device=cia301" not in (tmp_path / "out" / "canopen" / "bus.yml").read_text(encoding="utf-8")


def test_a_generic_drive_maps_the_cia402_objects(tmp_path: Path) -> None:
    report = check_data(tmp_path, spec("cia402", [0x6041, 0x6064], name="drive", node_id=1))
    assert report["ok"], report["errors"]
    assert message(bus(report, "can0"), "drive_state")["size"] == 6  # UNSIGNED16 + INTEGER32


def test_an_object_the_profile_has_is_one_error_at_its_line(tmp_path: Path) -> None:
    objects = [*BMS_OBJECTS, {"index": 0x2000, "sub": 1, "name": "Again", "type": "UNSIGNED8", "access": "ro"}]
    report = check_data(tmp_path, spec({"profile": "cia301", "objects": objects}, ["0x2000:1"]))
    (err,) = report["errors"]
    assert err["code"] == "device-object" and "already" in err["message"]
    lines = (tmp_path / "spec.yaml").read_text(encoding="utf-8").splitlines()
    assert "name: Again" in "\n".join(lines[err["line"] - 1 : err["line"] + 4])


@pytest.mark.parametrize(
    ("change", "code"),
    [({"index": 0x1017}, "greater-than-equal"), ({"type": "UINT8"}, "literal-error")],
)
def test_a_bad_object_is_one_error(tmp_path: Path, change: dict[str, Any], code: str) -> None:
    """Application objects live at 0x2000-0x9FFF (CiA 301 7.4.1); the type is one of CiA 301's names."""
    objects = [{**BMS_OBJECTS[0], **change}]
    report = check_data(tmp_path, spec({"profile": "cia301", "objects": objects}, [0x1001]))
    assert [e["code"] for e in report["errors"]] == [code], report["errors"]
