"""dbc/<bus>.dbc: cantools loads every generated file, and it agrees with the spec and with netcfg.runtime.

Sources of the numbers: the specs; CiA 301's pre-defined connection set (RPDO1/2 = 0x200/0x300 + node id,
TPDO1/2 = 0x180/0x280 + node id, SYNC 0x080); the EPOS4 object sizes (epos4.yaml, from the CiA 402 profile and
maxon's firmware specification); IEEE 754 for float32; the hand calculations in the docstrings.
"""

from __future__ import annotations

from pathlib import Path

import cantools
import pytest
from cantools.database.can import Database
from conftest import SPECS, load_spec

import netcfg.runtime as rt
from netcfg.build import build
from netcfg.check import load_model
from netcfg.diagnostics import Collector
from netcfg.emit import dbc
from netcfg.emit.dbc import sanitise

ALL_SPECS = sorted(p.name for p in SPECS.glob("*.yaml"))


def build_into(spec: Path, out: Path) -> Path:
    report, target, _ = build(spec, out)
    assert target is not None, report["errors"]
    return target


@pytest.fixture(scope="module")
def outputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("dbc")
    return {name: build_into(SPECS / name, base / name) for name in ALL_SPECS}


def load_dbc(out: Path, bus: str) -> Database:
    db = cantools.database.load_file(out / "dbc" / f"{bus}.dbc")
    assert isinstance(db, Database)
    return db


@pytest.mark.parametrize("spec", ALL_SPECS)
def test_cantools_loads_every_dbc_and_it_lists_every_frame(outputs: dict[str, Path], spec: str) -> None:
    out = outputs[spec]
    cfg = rt.load(out / "runtime.json")
    can_buses = [b for b in cfg.buses if b.is_can]
    if not can_buses:
        assert not (out / "dbc").exists()
    assert sorted(p.stem for p in (out / "dbc").glob("*.dbc")) == sorted(b.name for b in can_buses)
    for bus in can_buses:
        db = load_dbc(out, bus.name)
        assert (db.buses[0].name, db.buses[0].baudrate) == (bus.name, bus.bitrate)
        assert [n.name for n in db.nodes] == list(bus.nodes)
        expected = {m.name for m in cfg.messages_on(bus.name)} | ({f"{bus.name}_TM"} if bus.ftt else set())
        assert {m.name for m in db.messages} == expected
        for m in cfg.messages_on(bus.name):
            d = db.get_message_by_name(m.name)
            assert (d.frame_id, d.is_extended_frame, d.length, d.senders) == (
                m.id,
                m.extended,
                m.frame_size,  # a CAN FD frame's DBC length is its padded data length
                [m.producer],
            )
            assert d.is_fd == m.fd
            assert db.get_message_by_frame_id(m.id | (0x80000000 if m.extended else 0)).name == m.name
            assert [(s.name, s.start, s.length, s.is_signed) for s in d.signals] == [
                (f.name, f.start_bit, f.bits, f.signed) for f in m.fields
            ]


def test_allex2_frames_are_the_cia301_pdos(outputs: dict[str, Path]) -> None:
    """allex2.yaml: drives hip_l..ankle_r are nodes 1..6. Lengths: 0x60FF + 0x60B1 (INTEGER32 each) = 8 bytes,
    0x60C2:1 + 0x60C2:2 (UNSIGNED8, INTEGER8) = 2, 0x6064 + 0x606C (INTEGER32) = 8, 0x6077 (INTEGER16) +
    0x30D1:2 (INTEGER32) = 6. Commands and state every 20 ms; the interpolation RPDO is on demand (no cycle)."""
    db = load_dbc(outputs["allex2.yaml"], "can0")
    spec = load_spec("allex2.yaml")
    node_ids = {n["name"]: n["node_id"] for n in spec["nodes"]}
    for joint in ("hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r"):
        nid = node_ids[joint]
        expected = {
            f"{joint}_cmd": (0x200 + nid, 8, "master", 20),
            f"{joint}_interp": (0x300 + nid, 2, "master", None),
            f"{joint}_state": (0x180 + nid, 8, joint, 20),
            f"{joint}_effort": (0x280 + nid, 6, joint, 20),
        }
        for name, (frame_id, length, sender, cycle) in expected.items():
            d = db.get_message_by_name(name)
            assert (d.frame_id, d.length, d.senders, d.cycle_time) == (frame_id, length, [sender], cycle), name
    sync = db.get_message_by_name("can0_SYNC")
    assert (sync.frame_id, sync.length, sync.senders, sync.cycle_time, sync.signals) == (0x80, 0, ["master"], 20, [])
    cmd = db.get_message_by_name("hip_l_cmd")
    assert [(s.name, s.byte_order, s.receivers) for s in cmd.signals] == [
        ("target_velocity", "little_endian", ["hip_l"]),
        ("velocity_offset", "little_endian", ["hip_l"]),
    ]


def test_cambada_frames_are_table_1(outputs: dict[str, Path]) -> None:
    """cambada.yaml (Table 1 / Table 2): synchronous messages get CAN id 0x100 + FTT id (the spec's default
    id_base), the asynchronous ones their explicit ids; sizes as given. Cycle times: period in ECs x 5 ms
    (6 EC = 30 ms, 2 EC = 10 ms, 10 EC = 50 ms); battery_status 1000 ms; sporadic messages have none. The
    master's trigger message is id 0 (default tm_id), 5 bytes (tm_size), every EC (5 ms)."""
    db = load_dbc(outputs["cambada.yaml"], "lowlevel")
    cycles = {"motor_setpoints": 30, "encoder1": 10, "encoder2": 10, "encoder3": 10, "odo_position": 50}
    cycles |= {"odo_orientation": 50, "velocity_linear": 30, "velocity_angular": 30, "battery_status": 1000}
    for m in load_spec("cambada.yaml")["messages"]:
        d = db.get_message_by_name(m["name"])
        frame_id = m["id"] if "id" in m else 0x100 + m["ftt_id"]
        assert (d.frame_id, d.length, d.senders) == (frame_id, m["size"], [m["producer"]]), m["name"]
        assert d.cycle_time == cycles.get(m["name"]), m["name"]
        assert [s.receivers for s in d.signals] == [sorted(m["consumers"])]
        assert [(s.name, s.length) for s in d.signals] == [(f"{m['name']}_raw", 8 * m["size"])]
    tm = db.get_message_by_name("lowlevel_TM")
    assert (tm.frame_id, tm.length, tm.senders, tm.cycle_time) == (0, 5, ["master"], 5)


@pytest.mark.parametrize("spec", ["allex2.yaml", "cambada.yaml"])
def test_runtime_and_cantools_agree_on_every_payload(outputs: dict[str, Path], spec: str) -> None:
    """Two independent codecs, one layout: what netcfg.runtime encodes cantools decodes to the same values,
    and the other way round. Values: the most negative for signed fields (sign extension), a 0101... pattern
    for unsigned ones (byte order)."""
    cfg = rt.load(outputs[spec] / "runtime.json")
    for bus in cfg.buses:
        db = load_dbc(outputs[spec], bus.name)
        for m in cfg.messages_on(bus.name):
            d = db.get_message_by_name(m.name)
            values = {f.name: f.raw_range()[0] if f.signed else f.raw_range()[1] // 3 for f in m.fields}
            data = m.encode(**values)
            assert d.decode(data) == values, m.name
            swapped = {f.name: f.raw_range()[1] // 5 for f in m.fields}
            assert m.decode(d.encode(swapped)) == swapped, m.name


SIGNALS_SPEC = """
system: dbc_signals
buses: [{name: body, protocol: can, bitrate: 500 kbit/s}]
nodes:
  - {name: ecu, buses: [body]}
  - {name: dash, buses: [body]}
messages:
  - name: climate
    id: 0x123
    producer: ecu
    consumers: [dash]
    period: 100 ms
    signals:
      - {name: temperature, bits: 16, signed: true, scale: 0.1, offset: -40, min: -40, max: 125, unit: "°C"}
      - {name: pressure, bits: 32, float: true, unit: kPa}
      - {name: flags, bits: 4}
  - {name: level, id: 0x18FF0001, extended: true, producer: ecu, consumers: [dash], min_interarrival: 50 ms,
     signals: [{name: fill, bits: 8, scale: 0.5, unit: "%"}]}
"""


def test_scaled_float_and_extended_signals(tmp_path: Path) -> None:
    """temperature 25.0 degC at scale 0.1, offset -40 is raw (25 + 40) / 0.1 = 650 = 0x028A -> 8a 02;
    pressure 1.5 as IEEE 754 binary32 is 0x3FC00000 -> 00 00 c0 3f; flags 0b1010 sits in bits 48-51 -> 0a.
    Payload: 16 + 32 + 4 = 52 bits -> 7 bytes."""
    spec = tmp_path / "signals.yaml"
    spec.write_text(SIGNALS_SPEC, encoding="utf-8")
    out = build_into(spec, tmp_path / "out")
    db = load_dbc(out, "body")
    climate = db.get_message_by_name("climate")
    temp, pressure, flags = climate.signals
    assert (temp.scale, temp.offset, temp.minimum, temp.maximum, temp.unit) == (0.1, -40, -40, 125, "°C")
    assert (temp.is_signed, temp.is_float, flags.start) == (True, False, 48)
    assert (pressure.is_float, pressure.length) == (True, 32)
    assert (climate.length, climate.cycle_time) == (7, 100)
    expected = bytes([0x8A, 0x02, 0x00, 0x00, 0xC0, 0x3F, 0x0A])
    values = {"temperature": 25.0, "pressure": 1.5, "flags": 0b1010}
    msg = rt.load(out / "runtime.json").message("climate")
    assert msg.encode(**values) == expected
    assert climate.encode(values) == expected
    decoded = climate.decode(expected)
    assert decoded == pytest.approx(values) and msg.decode(expected) == pytest.approx(values)
    level = db.get_message_by_name("level")
    assert (level.frame_id, level.is_extended_frame, level.cycle_time) == (0x18FF0001, True, None)
    assert level.signals[0].unit == "%" and level.signals[0].scale == 0.5


def test_dbc_is_identical_across_builds(outputs: dict[str, Path], tmp_path: Path) -> None:
    again = build_into(SPECS / "large_plant.yaml", tmp_path / "again")
    first = outputs["large_plant.yaml"]
    for path in sorted((first / "dbc").glob("*.dbc")):
        assert (again / "dbc" / path.name).read_bytes() == path.read_bytes(), path.name


LONG_NODE_SPEC = """
system: long_names
buses:
  - {name: body, protocol: can, bitrate: 500 kbit/s}
nodes:
  - {name: a_gateway_with_a_name_of_forty_chars_x, buses: [body]}
  - {name: dash, buses: [body]}
messages:
  - {name: status, id: 0x100, producer: a_gateway_with_a_name_of_forty_chars_x, consumers: [dash], size: 2,
     period: 10 ms}
"""


@pytest.mark.parametrize("spec", ALL_SPECS)
def test_dbc_text_is_what_cantools_writes_with_the_nodes(spec: str) -> None:
    """dbc_text writes the nodes' BU_ line itself and lets cantools write the rest without them (cantools'
    rename pass over nodes x frames x receivers is a no-op for netcfg's names) and without the deep copy it makes
    first; the expected text is cantools' own public writer given the whole database, nodes included."""
    model = load_model(SPECS / spec, Collector())
    assert model is not None
    for bus in (b for b in model.buses.values() if b.is_can):
        whole = dbc.database(model, bus).as_dbc_string(sort_signals=None, sort_attribute_signals=None)
        assert dbc.dbc_text(model, bus) == whole, bus.name


def test_a_node_name_cantools_shortens_takes_cantools_whole_writer(tmp_path: Path) -> None:
    """A 38-character node name is over cantools' 32 (it writes the first 32 characters and keeps the long name
    in a SystemNodeLongSymbol attribute), so the nodes go through cantools' writer as they are."""
    spec = tmp_path / "long.yaml"
    spec.write_text(LONG_NODE_SPEC, encoding="utf-8")
    model = load_model(spec, Collector())
    assert model is not None
    bus = model.buses["body"]
    text = dbc.dbc_text(model, bus)
    assert text == dbc.database(model, bus).as_dbc_string(sort_signals=None, sort_attribute_signals=None)
    assert "\r\nBU_: a_gateway_with_a_name_of_forty_c dash\r\n" in text
    assert "SystemNodeLongSymbol" in text


def test_comments_cannot_break_the_dbc_syntax() -> None:
    """A DBC string is delimited by double quotes and has no portable escape: quotes become apostrophes,
    backslashes slashes, line breaks spaces; characters outside the file's code page (cp1252) become '?'."""
    assert sanitise('say "hi"\\\nnow  \u2603 °C') == "say 'hi'/ now ? °C"


ROUND_TRIP_SPEC = """
system: roundtrip
buses:
  - {name: body, protocol: can, bitrate: 1 Mbit/s}
nodes:
  - {name: ecu, buses: [body]}
  - {name: dash, buses: [body]}
messages:
  - name: status
    producer: ecu
    consumers: [dash]
    id: 0x100
    period: 10 ms
    offset: 2500 us
    jitter: 150 us
    deadline: 8 ms
    signals:
      - {name: rpm, start_bit: 7, bits: 16, byte_order: big_endian, scale: 0.25, min: 0, max: 16383.75}
      - {name: mode, start_bit: 16, bits: 2, enum: {0: "off", 1: eco, 2: sport}}
      - {name: page, start_bit: 24, bits: 8}
      - {name: volts, start_bit: 32, bits: 16, mux: {signal: page, values: [0]}, scale: 0.001}
      - {name: count, start_bit: 32, bits: 32, mux: {signal: page, values: [1, 2]}}
  - name: fast
    producer: ecu
    consumers: [dash]
    id: 0x050
    period: 666667 ns
    size: 2
  - name: button
    producer: dash
    consumers: [ecu]
    id: 0x200
    min_interarrival: 20 ms
    deadline: 5 ms
    jitter: 1 ms
    signals: [{name: pressed, bits: 1}]
  - name: setup
    producer: dash
    consumers: [ecu]
    id: 0x300
    type: on-demand
    size: 8
"""


def test_spec_to_dbc_to_spec_keeps_every_timing_field_and_signal(tmp_path: Path) -> None:
    """The spec above (written by hand: periodic with offset, jitter and deadline, a sub-millisecond period that
    GenMsgCycleTime's whole ms cannot say, sporadic with deadline and jitter, on-demand; Motorola, enum and
    multiplexed signals) is built, its DBC imported back, and the model of that DBC has the same timing and
    the same signal layout, message by message."""
    from netcfg.check import load_dbc as check_dbc
    from netcfg.check import load_model
    from netcfg.diagnostics import Collector
    from netcfg.importers import ImportOptions

    spec = tmp_path / "roundtrip.yaml"
    spec.write_text(ROUND_TRIP_SPEC, encoding="utf-8")
    original = load_model(spec, Collector())
    assert original is not None
    out = build_into(spec, tmp_path / "out")
    diags = Collector()
    back = check_dbc(out / "dbc" / "body.dbc", diags, ImportOptions())
    assert back is not None and not diags.errors, diags.errors
    for m in original.messages.values():
        got = back.messages[m.name]
        timing = ("kind", "period_ns", "interval_ns", "offset_ns", "deadline_ns", "jitter_ns", "id", "size")
        assert {k: getattr(got, k) for k in timing} == {k: getattr(m, k) for k in timing}, m.name
        if m.signals:  # the importer lists them in start-bit order
            assert sorted(got.signals, key=lambda s: s.name) == sorted(m.signals, key=lambda s: s.name), m.name
    # what other tools read: the rounded Gen* attributes and the send type
    db = load_dbc(out, "body")
    status, fast, button, setup = (db.get_message_by_name(n) for n in ("status", "fast", "button", "setup"))
    assert (status.send_type, status.cycle_time, status.dbc.attributes["GenMsgStartDelayTime"].value) == (
        "Cyclic",
        10,
        3,  # 2.5 ms in whole ms, half up (netcfg.emit.dbc's docstring)
    )
    assert (fast.send_type, fast.cycle_time) == ("Cyclic", 1)  # 0.666667 ms rounds to 1 ms in a whole-ms field
    assert (button.send_type, button.dbc.attributes["GenMsgDelayTime"].value) == ("Spontaneous", 20)
    assert setup.send_type == "NoMsgSendType"
