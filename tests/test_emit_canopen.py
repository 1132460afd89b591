"""CANopen EDS/DCF emitter: the canopen package reads our files back, and what it reads is what the spec says.

Expected values come from the spec (node ids, transmission types, PDO maps), from CiA 301 (the pre-defined
connection set: TPDO1 = 0x180 + node id, TPDO2 = 0x280 + node id, RPDO1 = 0x200 + node id, RPDO2 = 0x300 + node id;
0x1006 in microseconds, 0x1017 in milliseconds, inhibit time in 100 us, 0x1005 bit 30 = SYNC producer, PDO COB-ID
bit 31 = not valid; mapping entry = index << 16 | sub-index << 8 | bit length), from CiA 402 / maxon's firmware
specification for the object sizes (0x6064, 0x606C, 0x60FF, 0x60B1, 0x30D1:2 INTEGER32; 0x6077 INTEGER16;
0x60C2:1 UNSIGNED8, 0x60C2:2 INTEGER8) and from CiA 306 for the file structure (Baudrate in kbit/s).
"""

from __future__ import annotations

import configparser
import dataclasses
import logging
import re
import shutil
from pathlib import Path
from typing import Any

import canopen
import pytest
import yaml
from canopen.objectdictionary import ODArray, ODRecord, ODVariable
from conftest import EPOS4_EDS, SPECS, load_spec

from netcfg.check import analyse_spec
from netcfg.devices import ObjectEntry, builtin_profile
from netcfg.emit import c_header
from netcfg.model import Model
from netcfg.protocols.canopen.dcf import emit, ini_text

logging.getLogger("canopen").setLevel(logging.ERROR)

# allex2.yaml: node ids of the six drives
DRIVES = {"hip_l": 1, "knee_l": 2, "ankle_l": 3, "hip_r": 4, "knee_r": 5, "ankle_r": 6}
# allex2.yaml, the same four PDOs on every drive: (CiA 301 default COB-ID base, transmission type, map)
RPDOS = {
    1: (0x200, 255, [(0x60FF, 0, 32), (0x60B1, 0, 32)]),  # <drive>_cmd: target velocity, velocity offset
    2: (0x300, 255, [(0x60C2, 1, 8), (0x60C2, 2, 8)]),  # <drive>_interp: interpolation time period
}
TPDOS = {
    1: (0x180, 1, [(0x6064, 0, 32), (0x606C, 0, 32)]),  # <drive>_state: position, velocity
    2: (0x280, 1, [(0x6077, 0, 16), (0x30D1, 2, 32)]),  # <drive>_effort: torque, current
}
PDO_SLOTS = 4  # the EPOS4 has 4 RxPDOs and 4 TxPDOs (built-in profile and maxon's EDS agree)


def emitted(spec: Path) -> tuple[Model, dict[str, bytes]]:
    model, report = analyse_spec(spec)
    assert model is not None and report["ok"], report["errors"]
    return model, emit(model, report)


def write(files: dict[str, bytes], out: Path) -> Path:
    for rel, data in files.items():
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return out


def ini(data: bytes) -> configparser.RawConfigParser:
    """The files as canopen reads them: ';' starts an inline comment, keys keep their case."""
    parser = configparser.RawConfigParser(inline_comment_prefixes=(";",), strict=True)
    parser.optionxform = str  # type: ignore[assignment,method-assign]
    parser.read_string(data.decode("ascii"))
    return parser


def vendor_spec(tmp_path: Path) -> Path:
    """allex2 with every drive described by maxon's EDS instead of the built-in profile."""
    shutil.copy(EPOS4_EDS, tmp_path / "epos4.eds")
    data = load_spec("allex2.yaml")
    for node in data["nodes"]:
        if node.get("device") == "epos4":
            node["device"] = {"eds": "epos4.eds"}
    path = tmp_path / "allex2_vendor.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def allex2(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, bytes]]:
    _, files = emitted(SPECS / "allex2.yaml")
    return write(files, tmp_path_factory.mktemp("allex2")), files


def entry(od: canopen.ObjectDictionary, index: int, sub: int | None = None) -> ODVariable:
    obj = od[index]
    if sub is not None:
        assert isinstance(obj, (ODRecord, ODArray))
        obj = obj[sub]
    assert isinstance(obj, ODVariable)
    return obj


def pdo_maps(maps: Any) -> dict[int, tuple[bool, int, int, list[tuple[int, int, int]]]]:
    """map number -> (enabled, COB-ID, transmission type, [(index, sub-index, bits)]) as canopen reads them."""
    maps.read(from_od=True)
    return {
        n: (m.enabled, m.cob_id, m.trans_type, [(v.index, v.subindex, v.length) for v in m.map])
        for n, m in maps.map.items()
    }


def pdo_map(maps: Any, number: int) -> list[Any]:
    return list(maps.map[number].map)


def check_drive_pdos(dcf: Path, name: str) -> None:
    node_id = DRIVES[name]
    network = canopen.Network()  # never connected: reading the maps only registers their COB-IDs
    node = canopen.RemoteNode(node_id, str(dcf))
    network.add_node(node)
    for maps, table in ((node.rpdo, RPDOS), (node.tpdo, TPDOS)):
        got = pdo_maps(maps)
        assert sorted(got) == list(range(1, PDO_SLOTS + 1)), name
        for n in range(1, PDO_SLOTS + 1):
            if n in table:
                base, transmission, mapping = table[n]
                assert got[n] == (True, base + node_id, transmission, mapping), (name, n)
            else:  # an unused slot: disabled (COB-ID bit 31), nothing mapped
                assert got[n][0] is False and got[n][3] == [], (name, n)


def test_canopen_imports_every_file_of_the_seed_specs(allex2: tuple[Path, dict[str, bytes]], tmp_path: Path) -> None:
    """allex2: 6 drives x (EDS + DCF) + the master's DCF = 13 files; large_plant: 25 axes x 2 + 1 = 51."""
    _, plant = emitted(SPECS / "large_plant.yaml")
    for (out, files), count in ((allex2, 13), ((write(plant, tmp_path), plant), 51)):
        assert len(files) == count
        for rel in files:
            od = canopen.import_od(str(out / rel))
            assert 0x1018 in od and 0x1000 in od, rel
            if rel.endswith(".dcf"):
                assert od.bitrate == 1_000_000, rel  # both CANopen buses run at 1 Mbit/s


def test_dcf_names_the_node_and_its_network(allex2: tuple[Path, dict[str, bytes]]) -> None:
    _, files = allex2
    for name, node_id in DRIVES.items():
        dcf = ini(files[f"canopen/{name}.dcf"])
        assert dict(dcf["DeviceComissioning"]) == {
            "NodeID": str(node_id),
            "NodeName": name,
            "Baudrate": "1000",
            "NetworkName": "can0",
            "CANopenManager": "0",
        }
        assert not ini(files[f"canopen/{name}.eds"]).has_section("DeviceComissioning")


@pytest.mark.parametrize("drive", sorted(DRIVES))
def test_drive_pdo_maps_read_back_through_canopen(allex2: tuple[Path, dict[str, bytes]], drive: str) -> None:
    out, _ = allex2
    check_drive_pdos(out / "canopen" / f"{drive}.dcf", drive)


def test_eds_carries_the_configuration_as_defaults(allex2: tuple[Path, dict[str, bytes]]) -> None:
    """The EDS has no ParameterValue; its defaults are the configuration (TPDO1 of knee_l, node 2: COB-ID
    0x182 written relative to the node id, with the customary 'no RTR' bit 30)."""
    out, files = allex2
    eds = ini(files["canopen/knee_l.eds"])
    assert not any(eds.has_option(s, "ParameterValue") for s in eds.sections())
    assert eds.get("1800sub1", "DefaultValue") == "$NODEID+0x40000180"
    od = canopen.import_od(str(out / "canopen" / "knee_l.eds"), 2)
    assert entry(od, 0x1800, 1).default == 0x40000182
    assert entry(od, 0x1A00, 1).default == 0x6064 << 16 | 0 << 8 | 32


@pytest.mark.usefixtures("needs_shared")
def test_vendor_eds_drives_read_back_through_canopen(tmp_path: Path) -> None:
    """Every object maxon's EDS lists is in our EDS and DCF, and the PDO maps read back as with the built-in
    profile."""
    _, files = emitted(vendor_spec(tmp_path))
    out = write(files, tmp_path / "out")
    vendor = ini(EPOS4_EDS.read_bytes().decode("latin-1").encode("ascii", "replace"))
    lists = ("MandatoryObjects", "OptionalObjects", "ManufacturerObjects")
    theirs = {vendor.get(g, k) for g in lists for k in vendor.options(g) if k != "SupportedObjects"}
    assert len(theirs) == sum(vendor.getint(g, "SupportedObjects") for g in lists)
    for name in DRIVES:
        for ext in ("eds", "dcf"):
            ours = ini(files[f"canopen/{name}.{ext}"])
            listed = {ours.get(g, k) for g in lists for k in ours.options(g) if k != "SupportedObjects"}
            assert {int(i, 16) for i in theirs} <= {int(i, 16) for i in listed}, name
        check_drive_pdos(out / "canopen" / f"{name}.dcf", name)


def test_master_dcf_mirrors_the_slave_pdos(allex2: tuple[Path, dict[str, bytes]]) -> None:
    """The master consumes the 12 slave TPDOs (6 drives x 2) and produces the 12 slave RPDOs; each mirror has
    the slave PDO's COB-ID and maps one manufacturer object per value, of the slave object's data type."""
    out, files = allex2
    network = canopen.Network()
    master = canopen.LocalNode(127, str(out / "canopen" / "master.dcf"))
    network.add_node(master)
    epos4 = builtin_profile("epos4")
    for maps, table in ((master.rpdo, TPDOS), (master.tpdo, RPDOS)):
        got = pdo_maps(maps)
        assert len(got) == 12 and all(enabled for enabled, *_ in got.values())
        expected = {base + node_id: (n, table[n]) for node_id in DRIVES.values() for n, (base, *_) in table.items()}
        assert {cob for _, cob, _, _ in got.values()} == set(expected)
        for map_no, (_, cob, transmission, mapping) in got.items():
            _, (_, slave_type, slave_map) = expected[cob]
            assert transmission == slave_type
            assert [bits for *_, bits in mapping] == [bits for *_, bits in slave_map]
            for (index, sub, _), (slave_index, slave_sub, _) in zip(mapping, slave_map):
                assert 0x2000 <= index <= 0x5FFF and sub == 0
                slave_object = epos4.lookup(slave_index, slave_sub)
                assert slave_object is not None
                assert entry(master.object_dictionary, index).data_type == slave_object.data_type
            drive = next(d for d, i in DRIVES.items() if i == cob & 0x7F)
            var_names = [v.name for v in pdo_map(maps, map_no)]
            assert all(name.startswith(f"{drive}_") for name in var_names), var_names
    dcf = ini(files["canopen/master.dcf"])
    assert dcf.getint("DeviceComissioning", "NodeID") == 127  # spec
    assert dcf.getint("DeviceComissioning", "Baudrate") == 1000  # 1 Mbit/s in kbit/s
    assert dcf.getint("DeviceComissioning", "CANopenManager") == 1
    assert dcf.getint("DeviceInfo", "NrOfRXPDO") == dcf.getint("DeviceInfo", "NrOfTXPDO") == 12
    od = master.object_dictionary
    assert entry(od, 0x1006).value == 20_000  # sync_period 20 ms in us
    assert entry(od, 0x1007).value == 10_000  # sync_window 10 ms in us
    sync = entry(od, 0x1005).value
    assert isinstance(sync, int)
    assert sync & (1 << 30) and sync & 0x7FF == 0x080  # producer, CiA 301 default SYNC id


def test_large_plant_master_and_heartbeats(tmp_path: Path) -> None:
    """large_plant: the master's RPDOs are exactly the axis TPDOs it consumes, counted in the spec; every axis
    produces a heartbeat every 100 ms (0x1017 in ms = 100)."""
    data = load_spec("large_plant.yaml")
    consumed = [m for m in data["messages"] if "tpdo" in m.get("pdo", {}) and "motion_master" in m["consumers"]]
    produced = [m for m in data["messages"] if "rpdo" in m.get("pdo", {}) and m["producer"] == "motion_master"]
    _, files = emitted(SPECS / "large_plant.yaml")
    out = write(files, tmp_path)
    dcf = ini(files["canopen/motion_master.dcf"])
    assert dcf.getint("DeviceInfo", "NrOfRXPDO") == len(consumed)
    assert dcf.getint("DeviceInfo", "NrOfTXPDO") == len(produced)
    for node in data["nodes"]:
        if node.get("device") == "epos4":
            od = canopen.import_od(str(out / "canopen" / f"{node['name']}.dcf"))
            assert node["heartbeat"] == "100 ms" and entry(od, 0x1017).value == 100


def test_heartbeat_consumers_are_the_nodes_whose_dcf_supervises_them(tmp_path: Path) -> None:
    """A heartbeat's consumers are the nodes configured to consume it (CiA 301 7.5.2.18: consumer heartbeat time
    0x1016, node id in bits 16-23, time in ms below): in allex2 only the master's DCF has 0x1016, one entry per
    drive with the default consumer time 3 x 100 ms = 300 ms, so each drive's heartbeat has the master alone as
    consumer, and the drives' C headers do not receive each other's heartbeats. A heartbeat nobody supervises
    (here the master's own, 50 ms, added for the test) has no consumer."""
    data = load_spec("allex2.yaml")
    master = next(n for n in data["nodes"] if n["name"] == "master")
    master["heartbeat"] = "50 ms"
    spec = tmp_path / "allex2_hb.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    model, report = analyse_spec(spec)
    assert model is not None and report["ok"], report["errors"]
    out = write(emit(model, report), tmp_path / "out")
    od = canopen.import_od(str(out / "canopen" / "master.dcf"))
    consumers = {msg.name: msg.consumers for msg in model.buses["can0"].messages if msg.implicit == "heartbeat"}
    assert od[0x1016][0].default == len(DRIVES)  # sub-index 0: the number of entries
    supervised = {od[0x1016][sub].value >> 16: od[0x1016][sub].value & 0xFFFF for sub in range(1, len(DRIVES) + 1)}
    assert supervised == dict.fromkeys(DRIVES.values(), 300)
    for drive in DRIVES:
        assert consumers[f"{drive}_heartbeat"] == ("master",)
        assert 0x1016 not in canopen.import_od(str(out / "canopen" / f"{drive}.dcf"))
    assert consumers["master_heartbeat"] == ()
    header = c_header.emit(model, report)["c/hip_l.h"].decode()
    assert "message hip_l_heartbeat on can0: hip_l -> master; sent here" in header
    assert "knee_l_heartbeat" not in header


def test_inhibit_time_and_sync_start_reach_the_tpdo_parameters(tmp_path: Path) -> None:
    """An inhibit time of 1 ms is 10 units of 100 us (0x1800 sub 3); a SYNC start value goes to sub 6."""
    data = load_spec("allex2.yaml")
    for m in data["messages"]:
        if m["name"] == "hip_l_state":
            m["pdo"].update(transmission=255, inhibit="1 ms")
            m["min_interarrival"] = "20 ms"
        if m["name"] == "hip_l_effort":
            m["pdo"].update(transmission=2, sync_start=1)
    spec = tmp_path / "spec.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    _, files = emitted(spec)
    od = canopen.import_od(str(write(files, tmp_path) / "canopen" / "hip_l.dcf"))
    assert (entry(od, 0x1800, 2).value, entry(od, 0x1800, 3).value) == (255, 10)
    assert (entry(od, 0x1801, 2).value, entry(od, 0x1801, 6).value) == (2, 1)
    assert entry(od, 0x1801, 0).default == 6  # highest sub-index now present


def test_sections_and_counts_are_consistent(allex2: tuple[Path, dict[str, bytes]]) -> None:
    """CiA 306: SupportedObjects counts the listed objects, which are exactly the object sections; SubNumber
    counts a record's sub sections; NrOfRXPDO/NrOfTXPDO count the 0x14xx/0x18xx objects; no dates."""
    _, plant = emitted(SPECS / "large_plant.yaml")
    lists = ("MandatoryObjects", "OptionalObjects", "ManufacturerObjects")
    for rel, data in {**allex2[1], **plant}.items():
        f = ini(data)
        assert f.get("FileInfo", "FileName") == rel.rsplit("/", 1)[1]
        assert not {k for k in f.options("FileInfo") if "Date" in k or "Time" in k}, rel
        listed: list[int] = []
        for group in lists:
            keys = [k for k in f.options(group) if k != "SupportedObjects"]
            assert keys == [str(i) for i in range(1, len(keys) + 1)], (rel, group)
            assert f.getint(group, "SupportedObjects") == len(keys), (rel, group)
            listed += [int(f.get(group, k), 16) for k in keys]
        objects = [int(s, 16) for s in f.sections() if re.fullmatch(r"[0-9A-F]{4}", s)]
        assert sorted(listed) == sorted(objects) and len(set(listed)) == len(listed), rel
        subs: dict[int, int] = {}
        for s in f.sections():
            match = re.fullmatch(r"([0-9A-F]{4})sub([0-9A-F]+)", s)
            if match:
                subs[int(match[1], 16)] = subs.get(int(match[1], 16), 0) + 1
            if match or (s in map("{:04X}".format, objects) and not f.has_option(s, "SubNumber")):
                for key in ("ParameterName", "ObjectType", "DataType", "AccessType", "PDOMapping"):
                    assert f.has_option(s, key), (rel, s, key)
        for index in objects:
            section = f"{index:04X}"
            assert f.getint(section, "SubNumber", fallback=0) == subs.get(index, 0), (rel, section)
        assert f.getint("DeviceInfo", "NrOfRXPDO") == sum(1 for i in objects if 0x1400 <= i < 0x1600), rel
        assert f.getint("DeviceInfo", "NrOfTXPDO") == sum(1 for i in objects if 0x1800 <= i < 0x1A00), rel
        assert f.getint("DeviceInfo", "Granularity") == 8
        assert f.getint("DeviceInfo", "BaudRate_1000") == 1  # the buses' 1 Mbit/s
        assert rel.endswith(".dcf") == f.has_section("DeviceComissioning"), rel


def test_names_cannot_break_the_ini_structure(tmp_path: Path) -> None:
    """A profile name with a newline, brackets and ';' stays on its line, in its section, whole."""
    assert ini_text("Position]\n[actual;value\x00 é") == "Position) (actual,value e"
    model, report = analyse_spec(SPECS / "allex2.yaml")
    assert model is not None
    node = model.nodes["hip_l"]
    assert node.device is not None
    objects = dict(node.device.objects)
    objects[(0x6064, 0)] = dataclasses.replace(objects[(0x6064, 0)], name="Position]\n[evil]\nx=1;y")
    objects[(0x2100, 0)] = ObjectEntry(0x2100, 0, "Vendor\r\n[1000]", 0x07, "rw", False, 5)
    node.device = dataclasses.replace(node.device, objects=objects)
    files = emit(model, report)
    f = ini(files["canopen/hip_l.dcf"])
    assert "evil" not in f.sections() and f.get("6064", "ParameterName") == "Position) (evil) x=1,y"
    assert f.get("2100", "ParameterName") == "Vendor (1000)"
    od = canopen.import_od(str(write(files, tmp_path) / "canopen" / "hip_l.dcf"))
    assert entry(od, 0x2100).default == 5


def test_two_emits_give_identical_bytes() -> None:
    for spec in ("allex2.yaml", "large_plant.yaml"):
        assert emitted(SPECS / spec)[1] == emitted(SPECS / spec)[1]


@pytest.mark.usefixtures("needs_shared")
def test_vendor_identity_is_kept_in_eds_and_dcf(tmp_path: Path) -> None:
    """What maxon's EDS says of itself ([DeviceInfo]: VendorName 'maxon motor ag', VendorNumber 0x000000FB,
    ProductName 'EPOS4 Module 50/5', ProductNumber 0x61500000, RevisionNumber 0x01700000) reaches our files, in
    [DeviceInfo] and as the defaults of 0x1018 sub 1-3, as canopen reads them back: a master's identity check
    compares a drive with these."""
    _, files = emitted(vendor_spec(tmp_path))
    out = write(files, tmp_path / "out")
    vendor = canopen.import_od(str(EPOS4_EDS)).device_information
    for ext in ("eds", "dcf"):
        od = canopen.import_od(str(out / "canopen" / f"hip_l.{ext}"), 1)
        info = od.device_information
        assert (info.vendor_name, info.product_name) == ("maxon motor ag", "EPOS4 Module 50/5")
        assert (info.vendor_name, info.product_name) == (vendor.vendor_name, vendor.product_name)
        assert (info.vendor_number, info.product_number, info.revision_number) == (0xFB, 0x61500000, 0x01700000)
        assert [entry(od, 0x1018, s).default for s in (1, 2, 3)] == [0xFB, 0x61500000, 0x01700000]
