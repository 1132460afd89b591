"""DBC input: `netcfg check X.dbc` and `netcfg import dbc X.dbc -o spec.yaml` (netcfg.importers.dbc).

Sources of the numbers: the test network below, written once as a DBC through cantools' database API and once
by hand as the netcfg spec a user would write for it; the equality of netcfg's analysis of both is the check.
The one absolute response time is a hand calculation (test_dbc_check_equals_the_hand_written_spec).
"""

from __future__ import annotations

import json
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cantools
import cantools.database.can as cdb
import pytest
import yaml
from cantools.database.can.formats.dbc import DbcSpecifics
from cantools.database.can.formats.dbc.dbc_attribute import DbcAttribute
from cantools.database.can.formats.dbc.dbc_attribute_definition import DbcAttributeDefinition
from cantools.database.conversion import BaseConversion
from conftest import cli, message

from netcfg.check import load_model
from netcfg.diagnostics import Collector
from netcfg.importers import ImportOptions
from netcfg.importers.dbc import import_dbc


@dataclass(frozen=True)
class Sig:
    name: str
    start: int
    bits: int
    signed: bool = False
    scale: float = 1
    offset: float = 0
    minimum: float | None = None
    maximum: float | None = None
    unit: str | None = None
    big_endian: bool = False


@dataclass(frozen=True)
class Msg:
    name: str
    id: int
    extended: bool
    size: int
    sender: str | None
    receivers: tuple[str, ...]
    send_type: str | None = None  # GenMsgSendType
    cycle_ms: int | None = None  # GenMsgCycleTime
    delay_ms: int | None = None  # GenMsgDelayTime
    fast_ms: int | None = None  # GenMsgCycleTimeFast
    signals: tuple[Sig, ...] = field(default_factory=tuple)


NODES = ("ECU1", "ABS", "Dash", "Gateway")
# Mixed 11/29-bit; DiagRequest has no period. By the mapping rules (module docstring of netcfg.importers.dbc):
# Cyclic -> periodic at GenMsgCycleTime; Event with GenMsgDelayTime -> sporadic at that gap; NoMsgSendType
# without a cycle time -> on-demand.
VEHICLE = (
    Msg(
        "BrakeStatus",
        0x0C8,
        False,
        4,
        "ABS",
        ("ECU1", "Dash"),
        "Cyclic",
        20,
        signals=(Sig("BrakePressure", 0, 16, scale=0.1, maximum=6553.5, unit="bar"), Sig("BrakeActive", 16, 1)),
    ),
    Msg(
        "EngineData",
        0x100,
        False,
        8,
        "ECU1",
        ("Dash", "Gateway"),
        "Cyclic",
        10,
        signals=(Sig("RPM", 0, 16, scale=0.25, unit="rpm"), Sig("Torque", 24, 16, signed=True, scale=0.5, unit="Nm")),
    ),
    Msg("VehicleSpeed", 0x18FEF100, True, 8, "ECU1", ("Gateway",), "Cyclic", 100, signals=(Sig("Speed", 8, 16),)),
    Msg("DoorEvent", 0x300, False, 2, "Dash", ("ECU1",), "Event", None, 50, signals=(Sig("DoorOpen", 0, 4),)),
    Msg("DiagRequest", 0x18DA00F1, True, 8, "Gateway", ("ECU1",), "NoMsgSendType", signals=(Sig("Service", 0, 8),)),
    Msg("Odometer", 0x1ABCDE00, True, 6, "Dash", ("ECU1", "Gateway"), "Cyclic", 50, signals=(Sig("Km", 0, 32),)),
)
SEND_TYPES = ["Cyclic", "Event", "IfActive", "NoMsgSendType", "cyclicAndSpontaneous", "spontaneous"]


def _int_def(name: str) -> DbcAttributeDefinition:
    return DbcAttributeDefinition(name, default_value=0, kind="BO_", type_name="INT", minimum=0, maximum=65535)


DEFINITIONS = OrderedDict(
    GenMsgSendType=DbcAttributeDefinition(
        "GenMsgSendType", default_value="Cyclic", kind="BO_", type_name="ENUM", choices=SEND_TYPES
    ),
    GenMsgCycleTime=_int_def("GenMsgCycleTime"),
    GenMsgDelayTime=_int_def("GenMsgDelayTime"),
    GenMsgCycleTimeFast=_int_def("GenMsgCycleTimeFast"),
)


def _message(m: Msg) -> cdb.Message:
    attrs: OrderedDict[str, DbcAttribute] = OrderedDict()
    if m.send_type is not None:
        attrs["GenMsgSendType"] = DbcAttribute(SEND_TYPES.index(m.send_type), DEFINITIONS["GenMsgSendType"])
    for key, value in (("GenMsgDelayTime", m.delay_ms), ("GenMsgCycleTimeFast", m.fast_ms)):
        if value is not None:
            attrs[key] = DbcAttribute(value, DEFINITIONS[key])
    signals = [
        cdb.Signal(
            s.name,
            s.start,
            s.bits,
            byte_order="big_endian" if s.big_endian else "little_endian",
            is_signed=s.signed,
            conversion=BaseConversion.factory(scale=s.scale, offset=s.offset),
            minimum=s.minimum,
            maximum=s.maximum,
            unit=s.unit,
            receivers=list(m.receivers),
        )
        for s in m.signals or (Sig("Data", 0, 8),)  # receivers are named on signals: every message gets one
    ]
    return cdb.Message(
        m.id,
        m.name,
        m.size,
        signals,
        senders=[m.sender] if m.sender else [],
        cycle_time=m.cycle_ms,  # cantools writes GenMsgCycleTime itself
        is_extended_frame=m.extended,
        dbc_specifics=DbcSpecifics(attributes=attrs, attribute_definitions=DEFINITIONS),
    )


def write_dbc(
    path: Path,
    msgs: tuple[Msg, ...] = VEHICLE,
    nodes: tuple[str, ...] = NODES,
    baudrate: int | None = None,
    db_name: str | None = None,
) -> Path:
    """The network as a DBC, through cantools' model (Baudrate and DBName as database attributes)."""
    definitions = OrderedDict(DEFINITIONS)
    attributes: OrderedDict[str, DbcAttribute] = OrderedDict()
    if db_name is not None:
        definitions["DBName"] = DbcAttributeDefinition("DBName", default_value="", type_name="STRING")
        attributes["DBName"] = DbcAttribute(db_name, definitions["DBName"])
    db = cdb.Database(
        [_message(m) for m in msgs],
        [cdb.Node(n) for n in nodes],
        buses=[cdb.Bus("can0", baudrate=baudrate)] if baudrate else [],
        dbc_specifics=DbcSpecifics(attributes=attributes, attribute_definitions=definitions),
    )
    path.write_text(db.as_dbc_string(), encoding="cp1252")
    return path


def hand_spec(bitrate: str) -> dict[str, Any]:
    """The spec a user would write for VEHICLE (sizes only: frame times depend on the size alone)."""
    messages = []
    for m in VEHICLE:
        spec: dict[str, Any] = {"name": m.name, "producer": m.sender, "consumers": list(m.receivers), "id": m.id}
        if m.extended:
            spec["extended"] = True
        spec["size"] = m.size
        if m.send_type == "Cyclic":
            spec["period"] = f"{m.cycle_ms} ms"
        elif m.delay_ms is not None:
            spec["min_interarrival"] = f"{m.delay_ms} ms"
        else:
            spec["type"] = "on-demand"
        messages.append(spec)
    return {
        "system": "vehicle",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": bitrate}],
        "nodes": [{"name": n, "buses": ["can0"]} for n in NODES],
        "messages": messages,
    }


def check_json(*args: str, cwd: Path) -> tuple[int, dict[str, Any]]:
    proc = cli("check", *args, "--format", "json", cwd=cwd)
    assert "Traceback" not in proc.stderr
    return proc.returncode, json.loads(proc.stdout)


def without_consumer_order(buses: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{**b, "messages": [{**m, "consumers": sorted(m["consumers"])} for m in b["messages"]]} for b in buses]


def test_dbc_check_equals_the_hand_written_spec(tmp_path: Path) -> None:
    """`netcfg check vehicle.dbc --bitrate 500k` analyses what `netcfg check` of the hand-written spec does.

    Hand calculation for the highest-priority frame, BrakeStatus (0x0C8; the extended ids arbitrate on their base
    ids 0x63F, 0x636 and 0x6AF, all above it): at 500 kbit/s a bit is 2 us; it waits at most for the longest
    lower-priority frame, an 8-byte extended one, 80 + 10 * 8 = 160 bits = 320 us, then sends its own 4 bytes,
    55 + 10 * 4 = 95 bits = 190 us: R = 320 + 190 = 510 us (Davis et al. 2007, frame lengths as in README)."""
    dbc = write_dbc(tmp_path / "vehicle.dbc")
    (tmp_path / "spec.yaml").write_text(yaml.safe_dump(hand_spec("500 kbit/s"), sort_keys=False), encoding="utf-8")
    rc_dbc, from_dbc = check_json(str(dbc), "--bitrate", "500k", cwd=tmp_path)
    rc_spec, from_spec = check_json("spec.yaml", cwd=tmp_path)
    assert rc_spec == 0, from_spec["errors"]
    assert rc_dbc == 0, from_dbc["errors"]
    assert without_consumer_order(from_dbc["buses"]) == without_consumer_order(from_spec["buses"])
    assert from_dbc["system"] == "vehicle"
    assert message(from_dbc["buses"][0], "BrakeStatus")["wcrt_us"] == 510
    # the message without a period: in the output with no period, and a warning that names it
    diag = message(from_dbc["buses"][0], "DiagRequest")
    assert diag["period_us"] is None and diag["interval_us"] is None
    warned = [w for w in from_dbc["warnings"] if "DiagRequest" in w["message"]]
    assert len(warned) == 1 and "not analysed: no GenMsgCycleTime" in warned[0]["message"]
    assert warned[0]["file"] == str(dbc) and warned[0]["line"] > 1  # the line of its BO_


def test_bitrate_from_the_baudrate_attribute_and_the_command_line_wins(tmp_path: Path) -> None:
    """The DBC says BA_ "Baudrate" 250000 (bit/s, as cantools and Vector write it)."""
    dbc = write_dbc(tmp_path / "vehicle.dbc", baudrate=250_000)
    rc, report = check_json(str(dbc), cwd=tmp_path)
    assert rc == 0, report["errors"]
    assert report["buses"][0]["bitrate"] == 250_000
    rc, report = check_json(str(dbc), "--bitrate", "500k", cwd=tmp_path)
    assert rc == 0, report["errors"]
    assert report["buses"][0]["bitrate"] == 500_000


def test_no_bitrate_says_how_to_give_one(tmp_path: Path) -> None:
    dbc = write_dbc(tmp_path / "vehicle.dbc")
    proc = cli("check", str(dbc), cwd=tmp_path)
    assert proc.returncode == 1
    assert "--bitrate 500k" in proc.stderr and str(dbc) in proc.stderr
    assert "Traceback" not in proc.stderr


def test_import_writes_a_spec_that_checks_the_same(tmp_path: Path) -> None:
    dbc = write_dbc(tmp_path / "vehicle.dbc", db_name="Powertrain")
    proc = cli("import", "dbc", str(dbc), "--bitrate", "500k", "-o", "spec.yaml", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    text = (tmp_path / "spec.yaml").read_text(encoding="utf-8")
    # provenance: the BO_ line of each message, with its id and attributes
    assert "# BO_ 256 EngineData (0x100), line " in text
    assert "GenMsgSendType Cyclic, GenMsgCycleTime 10 ms" in text
    assert f"# BO_ {0x18FEF100 | 0x80000000} VehicleSpeed (0x18FEF100, extended)" in text
    assert "from the command line (--bitrate)" in text
    rc_spec, from_spec = check_json("spec.yaml", cwd=tmp_path)
    rc_dbc, from_dbc = check_json(str(dbc), "--bitrate", "500k", cwd=tmp_path)
    assert rc_spec == 0 and rc_dbc == 0, from_spec["errors"] + from_dbc["errors"]
    assert from_spec["buses"] == from_dbc["buses"]
    assert from_spec["buses"][0]["name"] == "Powertrain"  # DBName
    again = cli("import", "dbc", str(dbc), "--bitrate", "500k", "-o", "again.yaml", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert (tmp_path / "again.yaml").read_bytes() == (tmp_path / "spec.yaml").read_bytes()


def test_signals_keep_their_dbc_start_bits(tmp_path: Path) -> None:
    """EngineData's Torque starts at bit 24 and VehicleSpeed's Speed at bit 8 (the DBC's SG_ lines); netcfg lays
    signals out back to back, so the importer fills the unused bits and the resolved layout must agree."""
    dbc = write_dbc(tmp_path / "vehicle.dbc")
    diags = Collector()
    model = load_model(dbc, diags, ImportOptions(bitrate=500_000))
    assert model is not None and not diags.errors, diags.errors
    source = cantools.database.load_file(str(dbc))
    assert isinstance(source, cdb.Database)
    for m in source.messages:
        ours = {s.name: s for s in model.messages[m.name].signals}
        for s in m.signals:
            got = ours[s.name]
            assert (got.start_bit, got.bits, got.signed) == (s.start, s.length, s.is_signed)
            assert (got.scale, got.offset) == (s.conversion.scale, s.conversion.offset)
    assert [s.name for s in model.messages["VehicleSpeed"].signals] == ["Speed"]  # at its DBC start bit


BIG_ENDIAN = (
    Msg("Brake", 0x10, False, 2, "ABS", ("ECU1",), "Cyclic", 10, signals=(Sig("Pressure", 7, 16, big_endian=True),)),
    Msg("Engine", 0x20, False, 1, "ECU1", ("ABS",), "Cyclic", 10, signals=(Sig("Rpm", 0, 8),)),
)
BAD_TEXT = {
    "garbage": ("this is not a DBC file\n", "is this a DBC file?", 1),
    "bo_missing_field": (
        'VERSION ""\n\nNS_ :\n\nBS_:\n\nBU_: ECU1 ABS\n\nBO_ 256 EngineData: ECU1\n'
        ' SG_ Rpm : 0|8@1+ (1,0) [0|255] "" ABS\n',
        "BO_ 256 EngineData: ECU1",
        9,
    ),
}


def bad_dbc(tmp_path: Path, kind: str) -> tuple[Path, str, int | None]:
    """-> (file, text naming the item, line or None)."""
    path = tmp_path / f"{kind}.dbc"
    if kind in BAD_TEXT:
        text, item, line = BAD_TEXT[kind]
        path.write_text(text, encoding="cp1252")
        return path, item, line
    fd = Msg("Camera", 0x200, False, 64, "ECU1", ("ABS",), "Cyclic", 10, signals=(Sig("Objects", 0, 8),))
    return write_dbc(path, (fd,), ("ECU1", "ABS")), "message 'Camera'", None


@pytest.mark.parametrize("kind", ["garbage", "bo_missing_field", "can_fd_64"])
def test_malformed_dbc_is_refused_with_file_and_item(tmp_path: Path, kind: str) -> None:
    path, item, line = bad_dbc(tmp_path, kind)
    checked = cli("check", str(path), "--bitrate", "500k", cwd=tmp_path)
    imported = cli("import", "dbc", str(path), "--bitrate", "500k", "-o", "out.yaml", cwd=tmp_path)
    for proc in (checked, imported):
        assert proc.returncode == 1, proc.stderr
        assert "Traceback" not in proc.stderr
        assert item in proc.stderr
        where = f"{path}:{line}:" if line else f"{path}:"
        assert where in proc.stderr
    assert not (tmp_path / "out.yaml").exists()


def test_big_endian_signals_are_imported_with_their_dbc_start_bit(tmp_path: Path) -> None:
    """A Motorola signal (@0) keeps its DBC start bit (7: the most significant bit, bit 7 of byte 0) and its
    byte order; the spec checks without --lenient, and the model's signal has the layout cantools reads."""
    path = write_dbc(tmp_path / "brake.dbc", BIG_ENDIAN, ("ECU1", "ABS"))
    proc = cli("import", "dbc", str(path), "--bitrate", "500k", "-o", "spec.yaml", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    spec = yaml.safe_load((tmp_path / "spec.yaml").read_text(encoding="utf-8"))
    brake = next(m for m in spec["messages"] if m["name"] == "Brake")
    assert brake["signals"] == [{"name": "Pressure", "start_bit": 7, "bits": 16, "byte_order": "big_endian"}]
    rc, report = check_json("spec.yaml", cwd=tmp_path)
    assert rc == 0, report["errors"]
    rc, report = check_json(str(path), "--bitrate", "500k", cwd=tmp_path)
    assert rc == 0 and not report["warnings"], report


# --- mapping rules, through import_dbc directly -------------------------------------------------------------


def imported(path: Path, lenient: bool = False, bitrate: int | None = 500_000) -> tuple[Any, Collector]:
    diags = Collector()
    got = import_dbc(path, ImportOptions(bitrate=bitrate, lenient=lenient), diags)
    return (got[0] if got else None), diags


def test_send_types_map_to_periodic_sporadic_or_on_demand(tmp_path: Path) -> None:
    """Each expectation is the rule in netcfg.importers.dbc's docstring applied to the attributes given here."""
    msgs = (
        Msg("A", 1, False, 1, "ECU1", ("ABS",), "Cyclic", 10),  # period = GenMsgCycleTime
        Msg("B", 2, False, 1, "ECU1", ("ABS",), "Event", None, 20),  # gap = GenMsgDelayTime
        Msg("C", 3, False, 1, "ECU1", ("ABS",), "IfActive", None, None, 5),  # gap = GenMsgCycleTimeFast
        Msg("D", 4, False, 1, "ECU1", ("ABS",), "cyclicAndSpontaneous", 100, 30),  # min(30, 100)
        Msg("E", 5, False, 1, "ECU1", ("ABS",), "spontaneous"),  # no gap: on-demand
        Msg("F", 6, False, 1, "ECU1", ("ABS",), None, 40),  # no send type (the default Cyclic) -> 40 ms
        Msg("G", 7, False, 1, "ECU1", ("ABS",), "cyclicAndSpontaneous", 100),  # no gap: periodic + warning
    )
    data, diags = imported(write_dbc(tmp_path / "t.dbc", msgs, ("ECU1", "ABS")))
    timing = {m["name"]: {k: m[k] for k in ("period", "min_interarrival", "type") if k in m} for m in data["messages"]}
    assert timing == {
        "A": {"period": "10 ms"},
        "B": {"min_interarrival": "20 ms"},
        "C": {"min_interarrival": "5 ms"},
        "D": {"min_interarrival": "30 ms"},
        "E": {"type": "on-demand"},
        "F": {"period": "40 ms"},
        "G": {"period": "100 ms"},
    }
    warned = {w.message.split("'")[1]: w.code for w in diags.warnings}
    assert warned == {"E": "dbc-not-analysed", "G": "dbc-event-timing"}


def test_names_are_made_safe_and_unique(tmp_path: Path) -> None:
    msgs = (
        Msg("int", 1, False, 1, "ECU1", ("ABS",), "Cyclic", 10),  # a C keyword
        Msg("Status", 2, False, 1, "ECU1", ("ABS",), "Cyclic", 10),
        Msg("STATUS", 3, False, 1, "ECU1", ("ABS",), "Cyclic", 10),  # differs only in case
    )
    data, diags = imported(write_dbc(tmp_path / "2nd-car.dbc", msgs, ("ECU1", "ABS")))
    assert data["system"] == "dbc_2nd_car"
    assert [m["name"] for m in data["messages"]] == ["int_msg", "Status", "STATUS_2"]
    assert {w.code for w in diags.warnings} == {"dbc-name"} and len(diags.warnings) == 3


def test_senders_and_receivers(tmp_path: Path) -> None:
    """Undeclared nodes are added (a warning); no sender / no receiver is a warning with its own code (common
    and legal: a logger or gateway outside the file), analysed with a placeholder sender / all other nodes."""
    undeclared = (Msg("A", 1, False, 1, "ECU1", ("Lamp",), "Cyclic", 10),)
    data, diags = imported(write_dbc(tmp_path / "u.dbc", undeclared, ("ECU1",)))
    assert [n["name"] for n in data["nodes"]] == ["ECU1", "Lamp"]
    assert [w.code for w in diags.warnings] == ["dbc-node"] and "Lamp" in diags.warnings[0].message

    orphan = (Msg("NoSender", 1, False, 1, None, ("ABS",), "Cyclic", 10), Msg("NoReceiver", 2, False, 1, "ECU1", ()))
    path = write_dbc(tmp_path / "o.dbc", orphan, ("ECU1", "ABS", "Dash"))
    data, diags = imported(path)
    assert not diags.errors
    assert {(w.code, w.message.split("'")[1]) for w in diags.warnings if w.code != "dbc-not-analysed"} == {
        ("dbc-no-sender", "NoSender"),
        ("dbc-no-receiver", "NoReceiver"),
    }
    by_name = {m["name"]: m for m in data["messages"]}
    assert by_name["NoSender"]["producer"] == "unassigned" and by_name["NoSender"]["consumers"] == ["ABS"]
    assert by_name["NoReceiver"]["consumers"] == ["ABS", "Dash"]  # all other nodes, in BU_ order
    assert "unassigned" in [n["name"] for n in data["nodes"]]
    # CI can make them errors
    rc, report = check_json(str(path), "--bitrate", "500k", "--werror", "dbc-no-receiver", cwd=tmp_path)
    assert rc == 1 and [e["code"] for e in report["errors"]] == ["dbc-no-receiver"]
    assert "dbc-no-sender" in [w["code"] for w in report["warnings"]]


def test_bitrate_units(tmp_path: Path) -> None:
    """Baudrate in bit/s (500000) is taken as is; a value of at most 1000 (here 500) can only be kbit/s."""
    for value, expected in ((500_000, "500 kbit/s"), (500, "500 kbit/s"), (1_000_000, "1 Mbit/s")):
        data, diags = imported(write_dbc(tmp_path / "b.dbc", VEHICLE[:2], NODES, baudrate=value), bitrate=None)
        assert data["buses"][0]["bitrate"] == expected
        assert [w.code for w in diags.warnings if w.code == "dbc-bitrate"] == (["dbc-bitrate"] if value == 500 else [])
    text = write_dbc(tmp_path / "b.dbc", VEHICLE[:2], NODES).read_text(encoding="cp1252")
    (tmp_path / "s.dbc").write_text(
        text.replace("BA_DEF_ BO_", 'BA_DEF_  "BusSpeed" INT 0 1000000;\nBA_DEF_ BO_', 1)
        + '\nBA_ "BusSpeed" 125000;\n',
        encoding="cp1252",
    )
    data, _ = imported(tmp_path / "s.dbc", bitrate=None)
    assert data["buses"][0]["bitrate"] == "125 kbit/s"


def test_signal_notes_and_start_bits(tmp_path: Path) -> None:
    """A signal after bits the DBC leaves unused keeps its DBC start bit (start_bit: 16); value names become the
    signal's enum; signal comments, which the spec has no place for, stay in the comment above the signal."""
    msgs = (
        Msg(
            "Gear",
            1,
            False,
            4,
            "ECU1",
            ("ABS",),
            "Cyclic",
            10,
            signals=(Sig("Position", 0, 4), Sig("reserved_4", 16, 8)),  # bits 4..15 unused in the DBC
        ),
    )
    path = write_dbc(tmp_path / "g.dbc", msgs, ("ECU1", "ABS"))
    db = cantools.database.load_file(str(path))
    assert isinstance(db, cdb.Database)
    pos = db.messages[0].get_signal_by_name("Position")
    pos.comment = "selected gear"
    pos.choices = OrderedDict([(0, "P"), (1, "R")])
    path.write_text(db.as_dbc_string(), encoding="cp1252")
    diags = Collector()
    got = import_dbc(path, ImportOptions(bitrate=500_000), diags)
    assert got is not None and not diags.items, diags.items
    data, comments = got
    signals = data["messages"][0]["signals"]
    assert [(s["name"], s["bits"], s.get("start_bit")) for s in signals] == [
        ("Position", 4, None),
        ("reserved_4", 8, 16),
    ]
    assert signals[0]["enum"] == {0: "P", 1: "R"}
    note = comments[("messages", 0, "signals", 0)]
    assert "selected gear" in note


# --- import: file.dbc on a bus of a YAML spec ------------------------------------------------------------------


IMPORTING_SPEC = """system: plant
buses:
  - {name: body, protocol: can, bitrate: 500 kbit/s, import: vehicle.dbc}
nodes:
  - name: Dash
    buses: [body]
    tasks:
      - {name: show, period: 20 ms, wcet: 1 ms}
messages:
  - {name: EngineStatus, deadline: 4 ms}
  - {name: Sporadic, min_interarrival: 30 ms, deadline: 10 ms}
"""


def test_a_yaml_bus_imports_a_dbc_and_the_spec_adds_to_it(tmp_path: Path) -> None:
    """hard_cases.dbc joins bus 'body': its nine messages and nodes, the spec's bit rate, the spec's deadline
    for EngineStatus (the DBC's 10 ms period stays) and its own timing for Sporadic (30 ms, replacing the DBC's
    20 ms); the spec's node Dash keeps its task. The DBC's warnings name the DBC's lines."""
    from conftest import ROOT

    (tmp_path / "vehicle.dbc").write_bytes((ROOT / "tests/data/dbc/hard_cases.dbc").read_bytes())
    (tmp_path / "plant.yaml").write_text(IMPORTING_SPEC, encoding="utf-8")
    rc, report = check_json("plant.yaml", cwd=tmp_path)
    assert rc == 0, report["errors"]
    bus = report["buses"][0]
    assert bus["bitrate"] == 500_000 and len(bus["messages"]) == 9
    by_name = {m["name"]: m for m in bus["messages"]}
    assert (by_name["EngineStatus"]["period_us"], by_name["EngineStatus"]["deadline_us"]) == (10_000, 4_000)
    assert (by_name["Sporadic"]["interval_us"], by_name["Sporadic"]["deadline_us"]) == (30_000, 10_000)
    assert {w["file"] for w in report["warnings"]} == {"vehicle.dbc"}
    proc = cli("build", "plant.yaml", "-o", "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    db = cantools.database.load_file(str(tmp_path / "out/dbc/body.dbc"))
    assert isinstance(db, cdb.Database) and len(db.messages) == 9
    assert db.get_message_by_name("EngineStatus").get_signal_by_name("Rpm").byte_order == "big_endian"


def test_an_import_that_cannot_be_read_is_an_error_at_the_import_line(tmp_path: Path) -> None:
    (tmp_path / "plant.yaml").write_text(IMPORTING_SPEC, encoding="utf-8")
    rc, report = check_json("plant.yaml", cwd=tmp_path)
    assert rc == 1
    (error,) = report["errors"]
    assert (error["code"], error["line"]) == ("import", 3) and "vehicle.dbc" in error["message"]


def test_a_bus_type_other_than_can_is_refused(tmp_path: Path) -> None:
    """BusType LIN: the file describes another kind of bus; analysing it as CAN would be wrong."""
    from conftest import ROOT

    text = (ROOT / "tests/data/dbc/hard_cases.dbc").read_text(encoding="cp1252")
    path = tmp_path / "lin.dbc"
    path.write_text(text.replace('BA_ "BusType" "CAN";', 'BA_ "BusType" "LIN";'), encoding="cp1252")
    rc, report = check_json(str(path), cwd=tmp_path)
    assert rc == 1 and [e["code"] for e in report["errors"]] == ["dbc-bus-type"]
    assert report["errors"][0]["line"] == text.splitlines().index('BA_ "BusType" "CAN";') + 1


def test_the_simulator_carries_the_imported_frames(tmp_path: Path) -> None:
    """A spec importing hard_cases.dbc is simulated with a candump trace; python-can reads the trace, and every
    frame decodes the same through netcfg.runtime and through cantools (the DBC netcfg built): Motorola,
    multiplexed, float and enum messages included."""
    import can
    from conftest import ROOT

    import netcfg.runtime as rt

    (tmp_path / "vehicle.dbc").write_bytes((ROOT / "tests/data/dbc/hard_cases.dbc").read_bytes())
    (tmp_path / "plant.yaml").write_text(IMPORTING_SPEC, encoding="utf-8")
    assert cli("build", "plant.yaml", "-o", "out", cwd=tmp_path).returncode == 0
    proc = cli("simulate", "out/runtime.json", "--duration", "2s", "--log", "trace.log", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    cfg = rt.load(tmp_path / "out/runtime.json")
    db = cantools.database.load_file(str(tmp_path / "out/dbc/body.dbc"))
    assert isinstance(db, cdb.Database)
    seen = set()
    for frame in can.LogReader(str(tmp_path / "trace.log")):
        ours, values = cfg.decode_can(frame)
        seen.add(ours.name)
        dbc_id = frame.arbitration_id | (0x8000_0000 if frame.is_extended_id else 0)  # DBC's extended flag
        try:
            theirs = db.get_message_by_frame_id(dbc_id).decode(bytes(frame.data), decode_choices=False)
        except cantools.database.DecodeError:
            # a multiplexer value no signal is multiplexed on (the simulator's all-zero payload of ExtMux):
            # cantools refuses the frame; netcfg gives the multiplexer alone, which a master can act on
            assert values == {"Service": 0}, (ours.name, values)
            continue
        assert values == theirs, (ours.name, values, theirs)
    assert {"EngineStatus", "Diagnostics", "ExtMux", "FloatData", "DoubleData"} <= seen


TOLERATED = """BU_: A B
BO_ 256 M: 8 A
 SG_ s : 0|8@1+ (1,0) [0|255] "" B
 SG_ s : 8|8@1+ (1,0) [0|255] "" B
BO_ 257 N: 8 A
 SG_ x : 0|8@1+ (0,0) [0|255] "" B
 SG_ y : 8|8@1- (1,0) [0|100] "" B
 SG_ z : 16|8@1+ (1,0) [10|0] "" B
 SG_ w : 20|8@1+ (1,0) [0|255] "" B
VAL_ 257 y 300 "big" -5 "neg" ;
"""


def test_what_cantools_only_tolerates_is_a_warning_naming_message_and_signal(tmp_path: Path) -> None:
    """cantools (strict=False) loads each of these; netcfg checks the file, and says per signal what it did:
    a second signal of the same name, a scale of 0, a range with min above max, a value name for a value 8
    signed bits cannot hold (300), and a signal overlapping another (w on z's bits 20..23)."""
    path = tmp_path / "odd.dbc"
    path.write_text(TOLERATED, encoding="cp1252")
    assert cantools.database.load_file(str(path), strict=False) is not None
    rc, report = check_json(str(path), "--bitrate", "500k", cwd=tmp_path)
    assert rc == 0, report["errors"]
    got = {(w["code"], w["message"].split("'")[1], w["message"].split("'")[3]) for w in report["warnings"]}
    assert got >= {
        ("dbc-signal-layout", "s", "M"),
        ("dbc-signal-layout", "x", "N"),
        ("dbc-signal-range", "z", "N"),
        ("dbc-signal-enum", "y", "N"),
        ("dbc-signal-layout", "w", "N"),
    }
    lines = {w["message"].split("'")[1]: w["line"] for w in report["warnings"] if w["code"] != "dbc-not-analysed"}
    assert (lines["x"], lines["y"], lines["z"]) == (6, 7, 8)


@pytest.mark.parametrize("target", ['"a\\0b.dbc"', "folder.dbc", "notes.txt"])
def test_an_import_that_is_not_a_readable_dbc_is_an_error_at_the_import_line(tmp_path: Path, target: str) -> None:
    """A NUL byte in the path, a folder, a file that is not a DBC: each one error at the spec's `import`."""
    (tmp_path / "folder.dbc").mkdir()
    (tmp_path / "notes.txt").write_text("hello", encoding="utf-8")
    spec = f"system: p\nbuses:\n  - {{name: body, protocol: can, bitrate: 500 kbit/s, import: {target}}}\n"
    (tmp_path / "p.yaml").write_text(spec, encoding="utf-8")
    rc, report = check_json("p.yaml", cwd=tmp_path)
    assert rc == 1
    assert [(e["code"], e["line"]) for e in report["errors"]] == [("import", 3)]
