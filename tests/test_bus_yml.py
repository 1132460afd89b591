"""Lely dcfgen / ros2_canopen bus.yml: `netcfg import bus-yml` and the canopen/bus.yml emitter.

The bus.yml files below are written from the format's documentation: ros2_canopen's "Bus Configuration File" page
(options/master/defaults/nodes, master.baudrate in kbit/s, sync_period and sync_window in us, heartbeat_producer in
ms) and Lely dcfgen's keys (rpdo/tpdo keyed by PDO number with enabled, cob_id 'auto' = the CiA 301 default COB-ID,
transmission, mapping as {index, sub_index}; sdo as {index, sub_index, value}). The devices are the vendor EDS of the
maxon EPOS4 (tests/conftest.py EPOS4_EDS). Every number asserted comes from these texts, from CiA 301's pre-defined
connection set (TPDO1 = 0x180 + node id, RPDO1 = 0x200 + node id, ...), from the vendor EDS's DefaultValues, or from
specs/allex2.yaml.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import canopen
import pytest
import yaml
from canopen.objectdictionary import ODVariable
from conftest import EPOS4_EDS, SPECS, cli, cli_json

# ros2_canopen layout: config/<bus config name>/bus.yml next to the device files
BUS_YML = """\
options:
  dcf_path: "@BUS_CONFIG_PATH@"

master:
  node_id: 127
  driver: "ros2_canopen::MasterDriver"
  package: "canopen_master_driver"
  baudrate: 500
  sync_period: 10000
  sync_window: 8000

defaults:
  dcf: "epos4.eds"
  driver: "ros2_canopen::Cia402Driver"
  package: "canopen_402_driver"
  heartbeat_producer: 100
  sdo:
    - {index: 0x6060, sub_index: 0, value: 9}
  rpdo:
    1:
      enabled: true
      cob_id: "auto"
      transmission: 1
      mapping:
        - {index: 0x6040, sub_index: 0}
        - {index: 0x60FF, sub_index: 0}
    2: {enabled: false}
  tpdo:
    1:
      enabled: true
      cob_id: "auto"
      transmission: 1
      mapping:
        - {index: 0x6041, sub_index: 0}
        - {index: 0x6064, sub_index: 0}
    2:
      enabled: true
      cob_id: "auto"
      transmission: 1
      mapping:
        - {index: 0x606C, sub_index: 0}
        - {index: 0x6077, sub_index: 0}

nodes:
  joint_1:
    node_id: 1
  joint_2:
    node_id: 2
    tpdo:
      1:
        enabled: true
        cob_id: 0x190
        transmission: 2
        mapping:
          - {index: 0x6041, sub_index: 0}
          - {index: 0x606C, sub_index: 0}
      2: {enabled: false}
"""

# What BUS_YML configures, per node: PDO number -> (COB-ID, transmission type, [(index, sub-index)]).
# joint_1 takes 'defaults' as they are; joint_2's own 'tpdo' replaces the defaults' (the node's value wins).
EXPECTED = {
    "joint_1": (
        1,
        {1: (0x200 + 1, 1, [(0x6040, 0), (0x60FF, 0)])},
        {1: (0x180 + 1, 1, [(0x6041, 0), (0x6064, 0)]), 2: (0x280 + 1, 1, [(0x606C, 0), (0x6077, 0)])},
    ),
    "joint_2": (
        2,
        {1: (0x200 + 2, 1, [(0x6040, 0), (0x60FF, 0)])},
        {1: (0x190, 2, [(0x6041, 0), (0x606C, 0)])},
    ),
}
EPOS4_PDO_SLOTS = 4  # the vendor EDS has 0x1400-0x1403 and 0x1800-0x1803


def config(tmp_path: Path, text: str = BUS_YML, folder: str = "epos_pair") -> Path:
    cfg = tmp_path / folder
    cfg.mkdir(parents=True, exist_ok=True)
    shutil.copy(EPOS4_EDS, cfg / "epos4.eds")
    bus = cfg / "bus.yml"
    bus.write_text(text, encoding="utf-8")
    return bus


def import_bus(bus: Path, spec: Path, *extra: str) -> Any:
    return cli("import", "bus-yml", str(bus), "-o", str(spec), *extra)


def line_of(text: str, marker: str) -> int:
    return next(n for n, line in enumerate(text.splitlines(), 1) if marker in line)


def value(od: canopen.ObjectDictionary, index: int) -> Any:
    """The configured value (ParameterValue) of a variable in a DCF."""
    var = od[index]
    assert isinstance(var, ODVariable)
    return var.value


def pdo_maps(maps: Any) -> dict[int, tuple[bool, int | None, int | None, list[tuple[int, int]]]]:
    """PDO number -> (enabled, COB-ID, transmission type, [(index, sub-index)]) as canopen reads a DCF."""
    maps.read(from_od=True)
    return {n: (m.enabled, m.cob_id, m.trans_type, [(v.index, v.subindex) for v in m.map]) for n, m in maps.map.items()}


@pytest.mark.usefixtures("needs_shared")
def test_ros2_canopen_bus_yml_imports_checks_and_builds(tmp_path: Path) -> None:
    bus = config(tmp_path)
    spec = tmp_path / "spec.yaml"
    done = import_bus(bus, spec)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    # joint_2 overrides the defaults' tpdo; the SDO write is kept as a comment, with one warning per node
    assert "node 'joint_2' overrides defaults tpdo" in done.stderr
    assert done.stderr.count("SDO write(s) kept as comments") == 2
    text = spec.read_text(encoding="utf-8")
    assert "system: epos_pair" in text  # the folder's name: the stem 'bus' says nothing
    assert "sdo 0x6060:0 = 9" in text
    assert f"bus.yml line {line_of(BUS_YML, 'joint_2:')}: nodes.joint_2" in text

    code, report = cli_json("check", str(spec))
    assert code == 0, report["errors"]
    (can,) = report["buses"]
    assert can["protocol"] == "canopen" and can["bitrate"] == 500_000  # master.baudrate 500 kbit/s
    period = {m["name"]: m["period_us"] for m in can["messages"]}
    assert period["joint_1_tpdo1"] == 10_000  # transmission 1: every SYNC, sync_period 10000 us
    assert period["joint_2_tpdo1"] == 20_000  # transmission 2: every 2nd SYNC
    assert period["joint_1_rpdo1"] == 10_000  # synchronous RPDO: the master sends it every SYNC

    out = tmp_path / "out"
    built = cli("build", str(spec), "-o", str(out))
    assert built.returncode == 0, built.stderr
    network = canopen.Network()  # never connected: reading the maps only registers their COB-IDs
    for name, (node_id, rpdos, tpdos) in EXPECTED.items():
        dcf = out / "canopen" / f"{name}.dcf"
        node = canopen.RemoteNode(node_id, str(dcf))
        network.add_node(node)
        for maps, table in ((node.rpdo, rpdos), (node.tpdo, tpdos)):
            got = pdo_maps(maps)
            assert sorted(got) == list(range(1, EPOS4_PDO_SLOTS + 1)), name
            for n in range(1, EPOS4_PDO_SLOTS + 1):
                if n in table:
                    assert got[n] == (True, *table[n]), (name, n)
                else:  # 'enabled: false' or not configured: off, nothing mapped
                    assert got[n][0] is False and got[n][3] == [], (name, n)
        od = canopen.import_od(str(dcf), node_id)
        assert value(od, 0x1017) == 100  # defaults.heartbeat_producer: 100 ms, in both nodes
    master = canopen.import_od(str(out / "canopen" / "master.dcf"), 127)
    assert value(master, 0x1006) == 10_000  # master.sync_period, us
    assert value(master, 0x1007) == 8_000  # master.sync_window, us
    # and the build's own bus.yml says the same as the one imported
    again = yaml.safe_load((out / "canopen" / "bus.yml").read_text(encoding="utf-8"))
    assert again["master"] == {"node_id": 127, "baudrate": 500, "sync_period": 10000, "sync_window": 8000}
    assert again["joint_2"]["tpdo"][1]["cob_id"] == 0x190
    assert again["joint_2"]["tpdo"][1]["mapping"] == [
        {"index": 0x6041, "sub_index": 0},
        {"index": 0x606C, "sub_index": 0},
    ]
    assert again["joint_1"]["tpdo"][2]["cob_id"] == "auto"
    assert again["joint_2"]["tpdo"][2] == {"enabled": False}


@pytest.mark.usefixtures("needs_shared")
def test_lely_layout_keeps_what_the_dcf_enables(tmp_path: Path) -> None:
    """dcfgen's own layout: slaves at the top level. Keys left out keep the DCF's values and a PDO the file does not
    mention stays as the DCF has it. The EPOS4 EDS enables TPDO1 (0x1800 sub 1 = $NODEID+0x40000180, bit 31 clear)
    mapping the statusword (0x1A00 sub 1 = 0x60410010), transmission type 255 (0x1800 sub 2), inhibit time 10 x 100 us
    (0x1800 sub 3)."""
    text = """\
master:
  node_id: 127
  sync_period: 20000

drive:
  dcf: "epos4.eds"
  node_id: 5
  rpdo:
    1:
      mapping:
        - {index: 0x60FF, sub_index: 0}
"""
    bus = config(tmp_path, text, "lely")
    spec = tmp_path / "lely.yaml"
    done = import_bus(bus, spec)
    assert done.returncode == 0, done.stderr
    assert "TPDO1 of node 'drive' is not in bus.yml but its dcf enables it" in done.stderr
    data = yaml.safe_load(spec.read_text(encoding="utf-8"))
    assert data["system"] == "lely"
    assert data["buses"][0]["bitrate"] == "1000 kbit/s"  # dcfgen's default baudrate
    messages = {m["name"]: m for m in data["messages"]}
    assert messages["drive_tpdo1"]["pdo"] == {"tpdo": 1, "transmission": 255, "inhibit": "1000 us", "map": [0x6041]}
    assert "id" not in messages["drive_tpdo1"]  # 0x40000180 + 5: the CiA default, bit 30 only forbids RTR
    # RPDO1 without cob_id keeps the EDS's $NODEID+0x200 (the CiA default: no id) and its type 255; the master is
    # assumed to write it once per SYNC period
    assert messages["drive_rpdo1"]["pdo"] == {"rpdo": 1, "transmission": 255, "map": [0x60FF]}
    assert "id" not in messages["drive_rpdo1"] and messages["drive_rpdo1"]["period"] == "20 ms"
    code, report = cli_json("check", str(spec))
    assert code == 0, report["errors"]
    sporadic = next(m for m in report["buses"][0]["messages"] if m["name"] == "drive_tpdo1")
    assert sporadic["id"] == 0x180 + 5


def test_allex2_round_trips_through_bus_yml(tmp_path: Path) -> None:
    """build specs/allex2.yaml -> A; import A/canopen/bus.yml -> S.yaml; build S.yaml -> B: the CANopen files (every
    EDS and DCF and the bus.yml) are byte-identical. runtime.json, report.md and c/master.h differ: the bus.yml has no
    place for the spec's descriptions and the master's tasks, and runtime.json carries the spec's file hash."""
    a, b, spec = tmp_path / "A", tmp_path / "B", tmp_path / "S.yaml"
    assert cli("build", str(SPECS / "allex2.yaml"), "-o", str(a)).returncode == 0
    done = import_bus(a / "canopen" / "bus.yml", spec)
    assert done.returncode == 0, done.stderr
    built = cli("build", str(spec), "-o", str(b))
    assert built.returncode == 0, built.stderr
    names = sorted(p.name for p in (a / "canopen").iterdir())
    assert names == sorted(p.name for p in (b / "canopen").iterdir())
    assert len(names) == 6 * 3 + 1 + 1  # 6 drives x (EDS + DCF + concise DCF), the master's DCF, bus.yml
    for name in names:
        assert (a / "canopen" / name).read_bytes() == (b / "canopen" / name).read_bytes(), name
    assert (a / "dbc" / "can0.dbc").read_bytes() == (b / "dbc" / "can0.dbc").read_bytes()


def test_bus_yml_says_what_allex2_says(tmp_path: Path) -> None:
    """specs/allex2.yaml: 1 Mbit/s, SYNC 20 ms, window 10 ms, master node 127; hip_l (node 1) RxPDO1 = 0x60FF,
    0x60B1 type 255, TxPDO2 = 0x6077, 0x30D1:2 type 1; the built-in epos4 profile has 4 RPDOs and 4 TPDOs."""
    out = tmp_path / "A"
    assert cli("build", str(SPECS / "allex2.yaml"), "-o", str(out)).returncode == 0
    text = (out / "canopen" / "bus.yml").read_text(encoding="utf-8")
    data = yaml.safe_load(text)
    assert data["options"] == {"dcf_path": "."}
    assert data["master"] == {"node_id": 127, "baudrate": 1000, "sync_period": 20000, "sync_window": 10000}
    hip = data["hip_l"]
    assert hip["dcf"] == "hip_l.eds" and hip["node_id"] == 1
    assert hip["rpdo"][1] == {
        "enabled": True,
        "cob_id": "auto",
        "transmission": 255,
        "mapping": [{"index": 0x60FF, "sub_index": 0}, {"index": 0x60B1, "sub_index": 0}],
    }
    assert hip["tpdo"][2]["transmission"] == 1
    assert hip["tpdo"][2]["mapping"] == [{"index": 0x6077, "sub_index": 0}, {"index": 0x30D1, "sub_index": 2}]
    assert hip["rpdo"][3] == hip["rpdo"][4] == hip["tpdo"][3] == hip["tpdo"][4] == {"enabled": False}
    assert list(data) == ["options", "master", "hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r"]
    assert "1:  # netcfg: message=hip_l_cmd" in text  # names the bus.yml has no place for
    again = tmp_path / "B"
    assert cli("build", str(SPECS / "allex2.yaml"), "-o", str(again)).returncode == 0
    assert (again / "canopen" / "bus.yml").read_bytes() == text.encode("utf-8")


def test_several_canopen_buses_get_one_file_each(tmp_path: Path) -> None:
    """Two CANopen buses: canopen/<bus>.bus.yml each; a drive on both has its EDS in canopen/<bus>/ (canopen_dcf)."""
    spec = {
        "system": "two_buses",
        "buses": [
            {"name": f"can{i}", "protocol": "canopen", "bitrate": "1 Mbit/s", "canopen": {"sync_period": "10 ms"}}
            for i in (1, 2)
        ],
        "nodes": [
            {"name": "pc", "role": "master", "node_id": 127, "buses": ["can1", "can2"]},
            {"name": "left", "node_id": 1, "device": "epos4", "buses": ["can1"]},
            {"name": "both", "node_id": 2, "device": "epos4", "buses": ["can1", "can2"]},
        ],
        "messages": [
            {
                "name": "left_state",
                "bus": "can1",
                "producer": "left",
                "consumers": ["pc"],
                "pdo": {"tpdo": 1, "transmission": 1, "map": [0x6064]},
            },
        ],
    }
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    out = tmp_path / "out"
    built = cli("build", str(path), "-o", str(out))
    assert built.returncode == 0, built.stderr
    assert not (out / "canopen" / "bus.yml").exists()
    can1 = yaml.safe_load((out / "canopen" / "can1.bus.yml").read_text(encoding="utf-8"))
    can2 = yaml.safe_load((out / "canopen" / "can2.bus.yml").read_text(encoding="utf-8"))
    assert can1["left"]["dcf"] == "left.eds" and can1["both"]["dcf"] == "can1/both.eds"
    assert can2["both"]["dcf"] == "can2/both.eds" and "left" not in can2
    for bus, data in (("can1", can1), ("can2", can2)):
        for name, node in data.items():
            if name not in ("options", "master"):
                assert (out / "canopen" / node["dcf"]).is_file(), (bus, name)


BAD = [
    # (what, how to break BUS_YML, the marker on the line the error points at, words the message must contain)
    ("bad YAML", ("  sync_window: 8000", "  sync_window: [8000"), "sync_window: [8000", ["YAML"]),
    ("unknown key", ("    node_id: 2\n", "    node_id: 2\n    tpdo_typo: 1\n"), "tpdo_typo", ["tpdo_typo", "joint_2"]),
    ("node id 200", ("    node_id: 2\n", "    node_id: 200\n"), "node_id: 200", ["joint_2", "200"]),
    (
        "object the EDS lacks",  # the vendor EDS has no [5FFF] section
        (
            "          - {index: 0x606C, sub_index: 0}\n      2: {enabled: false}",
            "          - {index: 0x5FFF, sub_index: 0}\n      2: {enabled: false}",
        ),
        "0x5FFF",
        ["0x5FFF", "joint_2"],
    ),
    (
        "missing dcf file",
        ('dcf: "epos4.eds"', 'dcf: "epos4_missing.eds"'),
        "epos4_missing.eds",
        ["epos4_missing.eds", "joint_1"],
    ),
    (
        "SDO to a PDO parameter",
        ("{index: 0x6060, sub_index: 0, value: 9}", "{index: 0x1800, sub_index: 2, value: 254}"),
        "0x1800",
        ["0x1800:2", "joint_1", "--lenient"],
    ),
]


@pytest.mark.usefixtures("needs_shared")
@pytest.mark.parametrize(("what", "change", "marker", "words"), BAD, ids=[b[0] for b in BAD])
def test_malformed_bus_yml_is_refused(
    tmp_path: Path, what: str, change: tuple[str, str], marker: str, words: list[str]
) -> None:
    assert change[0] in BUS_YML
    text = BUS_YML.replace(change[0], change[1], 1)
    bus = config(tmp_path, text)
    spec = tmp_path / "spec.yaml"
    done = import_bus(bus, spec)
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    assert not spec.exists() and list(tmp_path.glob("*.tmp")) == []
    errors = [line for line in done.stderr.splitlines() if ": error: " in line]
    here = f"{bus}:{line_of(text, marker)}:"
    assert any(line.startswith(here) and all(w in line for w in words) for line in errors), done.stderr


@pytest.mark.usefixtures("needs_shared")
def test_lenient_turns_an_unknown_key_into_a_warning(tmp_path: Path) -> None:
    text = BUS_YML.replace("    node_id: 2\n", "    node_id: 2\n    tpdo_typo: 1\n", 1)
    bus = config(tmp_path, text)
    spec = tmp_path / "spec.yaml"
    done = import_bus(bus, spec, "--lenient")
    assert done.returncode == 0, done.stderr
    here = f"{bus}:{line_of(text, 'tpdo_typo')}:"
    assert any(
        line.startswith(here) and ": warning: " in line and "tpdo_typo" in line for line in done.stderr.splitlines()
    )
    assert "tpdo_typo: 1 (unknown key)" in spec.read_text(encoding="utf-8")
    assert cli("check", str(spec)).returncode == 0
