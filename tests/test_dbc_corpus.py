"""Real CAN databases, end to end: the DBC corpus in tests/data/dbc (public files from opendbc, MIT, and our own
hard cases; README.md there names each file's source and licence).

The references are peer tools, never netcfg's own output:
- cantools (strict=False, as DBC tools read files) decides what a loadable DBC is: netcfg must analyse every
  message of every such file without a refusal cantools does not make;
- cantools' own Message.encode gives the bytes netcfg's Python runtime and its generated C (gcc -std=c99 -Wall
  -Wextra -Wpedantic -Werror) must produce for every signal: Motorola, multiplexed (simple and extended),
  signed, float, scaled and enum signals;
- the frame lengths of hard_cases.dbc come from Davis, Burns, Bril, Lukkien, "Controller Area Network (CAN)
  schedulability analysis: refuted, revisited and revised" (2007), eq. (1) with worst-case stuffing:
  55 + 10 * s bits for an 11-bit frame of s bytes, 80 + 10 * s for a 29-bit one.
"""

from __future__ import annotations

import math
import struct
from pathlib import Path
from typing import Any

import cantools
import pytest
from cantools.database.can import Database, Signal
from cantools.database.can import Message as CanMessage
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from test_emit_c import GCC, c_literal, run_c_codec

from netcfg.check import analyse_spec
from netcfg.emit import c_header, runtime_json
from netcfg.importers import ImportOptions
from netcfg.model import Model
from netcfg.runtime import RuntimeConfig, parse
from netcfg.runtime.codec import Field, Number, _struct_layout, decode, decoder, encode, present

CORPUS = Path(__file__).resolve().parent / "data" / "dbc"
FILES = sorted(p.name for p in CORPUS.glob("*.dbc"))
# files that give no bit rate (opendbc's do not): the rate only scales the timing, it decides no refusal
ASSUMED_BITRATE = 500_000
# the C comparison compiles one program per file: these cover Motorola, simple and extended multiplexing,
# floats, signed, scaled and enum signals (the Python comparison runs on every file)
C_FILES = ["hard_cases.dbc", "tesla_model3_party.dbc", "toyota_prius_2010_pt.dbc", "vw_mqb.dbc"]


def cantools_db(name: str) -> Database:
    db = cantools.database.load_file(str(CORPUS / name), database_format="dbc", strict=False)
    assert isinstance(db, Database)
    return db


def options_for(db: Database, **more: Any) -> ImportOptions:
    has_rate = db.dbc is not None and ("Baudrate" in db.dbc.attributes or "BusSpeed" in db.dbc.attributes)
    return ImportOptions(bitrate=None if has_rate else ASSUMED_BITRATE, **more)


def analysed(name: str, **more: Any) -> tuple[Model, dict[str, Any], Database]:
    db = cantools_db(name)
    model, report = analyse_spec(CORPUS / name, options_for(db, **more))
    assert model is not None, report["errors"]
    return model, report, db


# --- every loadable file is analysed -----------------------------------------------------------------------------


def test_the_corpus_is_small_and_documented() -> None:
    """A few MB at most in the repository, and every file's source and licence is in the README."""
    readme = (CORPUS / "README.md").read_text(encoding="utf-8")
    assert sum((CORPUS / f).stat().st_size for f in FILES) < 3_000_000
    for f in FILES:
        assert f"`{f}`" in readme, f


@pytest.mark.parametrize("name", FILES)
def test_every_message_of_every_file_cantools_loads_is_analysed(name: str) -> None:
    """No refusal that cantools does not make, without --lenient: every frame of the DBC is in the report."""
    _, report, db = analysed(name)
    assert report["errors"] == []
    assert report["ok"]
    frames = [m for b in report["buses"] for m in b["messages"]]
    assert len(frames) == len(db.messages)
    assert {(m["id"], m["size"]) for m in frames} == {(m.frame_id, m.length) for m in db.messages}


@pytest.mark.parametrize("name", ["gm_global_a_lowspeed_1818125.dbc", "vw_mqb.dbc"])
def test_default_period_analyses_messages_without_a_cycle_time(name: str) -> None:
    """opendbc files give no GenMsgCycleTime: with --default-period every message gets a response time, and a
    warning names the assumption for each one."""
    _, report, db = analysed(name, default_period_ns=1_000_000_000)
    frames = [m for b in report["buses"] for m in b["messages"]]
    assert len(frames) == len(db.messages)
    assert all(m["period_us"] == 1_000_000 and m["wcrt_us"] is not None for m in frames)
    assumed = [w for w in report["warnings"] if w["code"] == "dbc-default-period"]
    assert len(assumed) == len(db.messages)


def test_hard_cases_timing_and_warnings() -> None:
    """hard_cases.dbc gives its bit rate (Baudrate 500000, so no --bitrate) and every timing attribute kind.
    Expected, from the file: EngineStatus Cyclic 10 ms with GenMsgStartDelayTime 2 ms; Sporadic IfActive with
    GenMsgCycleTimeFast 20 ms (its 3 repetitions) and GenMsgDelayTime 50 ms: sporadic, 20 ms apart (the
    smaller gap); frame lengths from Davis et al. (2007) eq. (1); the sender-less, receiver-less and
    overlapping messages are warnings with their own codes."""
    model, report, _ = analysed("hard_cases.dbc")
    assert report["buses"][0]["bitrate"] == 500_000
    engine, sporadic = model.messages["EngineStatus"], model.messages["Sporadic"]
    assert (engine.kind, engine.period_ns, engine.offset_ns) == ("periodic", 10_000_000, 2_000_000)
    assert (sporadic.kind, sporadic.interval_ns) == ("sporadic", 20_000_000)
    bits = {m["name"]: m["frame_bits_worst"] for m in report["buses"][0]["messages"]}
    assert bits["EngineStatus"] == 55 + 10 * 8 and bits["ExtMux"] == 80 + 10 * 8 and bits["Logged"] == 55 + 10
    codes = {(w["code"], w["message"].split("'")[1]) for w in report["warnings"]}
    assert codes == {
        ("dbc-no-sender", "Orphan"),
        ("dbc-no-receiver", "Logged"),
        ("dbc-signal-layout", "Wide"),
    }
    # cantools tolerates the overlap; the narrower signal stays, the frame keeps its size
    assert [s.name for s in model.messages["Overlap"].signals] == ["Narrow"]
    assert model.messages["Overlap"].size == 2


# --- every signal packs as cantools packs it -------------------------------------------------------------------


def runtime_of(model: Model, report: dict[str, Any]) -> RuntimeConfig:
    import json

    (text,) = runtime_json.emit(model, report).values()
    return parse(json.loads(text))


def _raw_candidates(f: Field) -> list[int]:
    lo, hi = f.raw_range()
    mid = (lo + hi) // 2
    pattern = 0x5A5A_5A5A_5A5A_5A5A & ((1 << f.bits) - 1)
    if f.signed and pattern >> (f.bits - 1):
        pattern -= 1 << f.bits
    return list(dict.fromkeys([lo, hi, mid, pattern, lo + 1 if lo < hi else lo, 0 if lo <= 0 <= hi else lo]))


def candidates(f: Field) -> list[Number]:
    """Physical values of the field inside its DBC range: raw limits, middle, a bit pattern; floats as floats."""
    if f.is_float:
        values: list[Number] = [0.0, 1.5, -2.25, 100.125, -0.5]
    elif f.is_integer:
        values = list(_raw_candidates(f))
    else:
        values = [raw * f.scale + f.offset for raw in _raw_candidates(f)]
    kept = [v for v in values if inside(f, v)]
    if f.is_float and f.bits == 32:
        kept = [v for v in kept if struct.unpack("<f", struct.pack("<f", v))[0] == v]
    return kept


def selections(fields: list[Field]) -> list[dict[str, Number]]:
    """Multiplexer settings that, together, select every multiplexed field once: {multiplexer: value}."""
    out: list[dict[str, Number]] = [{}]
    by_name = {f.name: f for f in fields}
    for f in fields:
        if f.mux is None:
            continue
        chosen: dict[str, Number] = {}
        g: Field | None = f
        while g is not None and g.mux is not None and g.mux in by_name:
            switch = by_name[g.mux]
            chosen[switch.name] = switch.from_raw(g.mux_values[0] & ((1 << switch.bits) - 1))
            g = switch
        if chosen not in out:
            out.append(chosen)
    return out


def vectors(fields: list[Field]) -> list[dict[str, Number]]:
    """Values for the fields present under each multiplexer setting, cycling through each field's candidates."""
    out = []
    cands = {f.name: candidates(f) for f in fields}
    for f in fields:  # cantools encodes a multiplexer only with a value some signal is multiplexed on
        ids = sorted({v & ((1 << f.bits) - 1) for g in fields if g.mux == f.name for v in g.mux_values})
        if ids:
            cands[f.name] = [f.from_raw(v) for v in ids]
    for k, chosen in enumerate(selections(fields)):
        base = {f.name: chosen.get(f.name, cands[f.name][0] if cands[f.name] else 0) for f in fields}
        fields_here = present(fields, base)
        if any(not cands[f.name] for f in fields_here if f.name not in chosen):
            continue  # a DBC range that holds no value of the field (none in the corpus; kept honest below)
        n = max((len(cands[f.name]) for f in fields_here), default=1)
        for i in range(min(n, 4)):
            values = {
                f.name: chosen[f.name] if f.name in chosen else cands[f.name][(i + k) % len(cands[f.name])]
                for f in fields_here
            }
            if present(fields, values) == fields_here:
                out.append(values)
    return out


def comparable(model: Model, db: Database) -> list[tuple[CanMessage, str, list[Field]]]:
    """The corpus messages netcfg imported with all their signals under their DBC names."""
    from netcfg.emit import field_of

    out = []
    for cm in db.messages:
        ours = model.messages.get(cm.name)
        if ours is None or not ours.signals:
            continue
        if {s.name for s in ours.signals} != {s.name for s in cm.signals}:
            continue
        out.append((cm, cm.name, [field_of(s) for s in ours.signals]))
    return out


def same_value(a: Number, b: Number) -> bool:
    return a == b or math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=1e-12)


@pytest.mark.parametrize("name", FILES)
def test_python_runtime_encodes_every_signal_as_cantools(name: str) -> None:
    """Every signal of every message, several values each (and under every multiplexer setting): the runtime's
    bytes equal cantools' Message.encode, and its decode gives cantools' values back; a value name (VAL_)
    encodes as its number does."""
    model, report, db = analysed(name)
    cfg = runtime_of(model, report)
    messages = comparable(model, db)
    # left out: messages with a renamed signal, or one netcfg leaves out (overlapping: cantools needs them all)
    with_signals = [m for m in db.messages if m.signals and m.name in model.messages]
    codes = ("dbc-signal-layout", "dbc-name")
    left_out = {w["message"].split("'")[3] for w in report["warnings"] if w["code"] in codes}
    assert len(messages) + len(left_out) >= len(with_signals)
    compared = enums = 0
    for cm, msg_name, fields in messages:
        runtime_msg = cfg.message(msg_name)
        for values in vectors(fields):
            expected = cm.encode(values, scaling=True, padding=False, strict=False)
            got = runtime_msg.encode(**values)
            assert got == expected, (name, msg_name, values, got.hex(), expected.hex())
            theirs = cm.decode(expected, decode_choices=False, scaling=True)
            back = runtime_msg.decode(got)
            assert set(back) == set(values), (msg_name, sorted(back), sorted(values))
            for key, value in back.items():
                assert same_value(value, theirs[key]), (msg_name, key, value, theirs[key])
            compared += len(values)
            for f in fields:
                if not f.choices or f.name not in values or any(g.mux == f.name for g in fields):
                    continue  # a multiplexer's value decides which signals are present: left as chosen
                names = [text for _, text in f.choices]
                unique = [(raw, text) for raw, text in f.choices if names.count(text) == 1]
                if not unique:
                    continue
                raw, text = unique[-1]  # a name given to two values stands for the first (as in cantools)
                number = f.from_raw(raw & ((1 << f.bits) - 1))
                if inside(f, number):
                    named = runtime_msg.encode(**dict(values, **{f.name: text}))
                    assert named == cm.encode(dict(values, **{f.name: number}), padding=False, strict=False)
                    assert named == cm.encode(dict(values, **{f.name: text}), padding=False, strict=False)
                    enums += 1
    assert compared > 0
    if any(s.choices for m in db.messages for s in m.signals):
        assert enums > 0


def inside(f: Field, value: Number) -> bool:
    return (f.minimum is None or value >= f.minimum) and (f.maximum is None or value <= f.maximum)


@pytest.mark.skipif(GCC is None, reason="gcc is not installed")
@pytest.mark.parametrize("name", C_FILES)
def test_c_packs_every_signal_as_cantools(tmp_path: Path, name: str) -> None:
    """The generated C headers (gcc -std=c99 -Wall -Wextra -Wpedantic -Werror) pack every vector of the
    Python comparison into cantools' bytes, and unpack them into cantools' values."""
    model, report, db = analysed(name)
    files = c_header.emit(model, report)
    cases: list[tuple[str, list[Field], dict[str, Number]]] = []
    expected: list[tuple[bytes, dict[str, Any]]] = []
    for cm, msg_name, fields in comparable(model, db):
        for values in vectors(fields):
            here = [f for f in fields if f.name in values]
            cases.append((msg_name, here, values))
            data = cm.encode(values, scaling=True, padding=False, strict=False)
            expected.append((data, cm.decode(data, decode_choices=False, scaling=True)))
    assert cases
    for _, fields, values in cases:  # the C program is given every value as a C literal
        assert all(c_literal(f, values[f.name]) for f in fields)
    out = run_c_codec(tmp_path, files, cases)
    assert len(out) == len(cases)
    for (msg_name, fields, values), (data, theirs), got in zip(cases, expected, out):
        assert got[0] == "1" and got[1] == data.hex(), (name, msg_name, values, got[:2], data.hex())
        for f, text in zip(fields, got[2:]):
            value: Number = float(text) if f.is_float or not f.is_integer else int(text)
            assert same_value(value, theirs[f.name]), (msg_name, f.name, value, theirs[f.name])


# --- any layout, not only the corpus's ----------------------------------------------------------------------------


@st.composite
def layouts(draw: st.DrawFn) -> tuple[CanMessage, Field, int]:
    """One signal anywhere cantools accepts it in an 8-byte frame (strict), either byte order, and a raw value."""
    big = draw(st.booleans())
    bits = draw(st.integers(1, 64))
    signed = draw(st.booleans())
    start = draw(st.integers(0, 63))
    byte_order = "big_endian" if big else "little_endian"
    try:
        sig = Signal("s", start, bits, byte_order=byte_order, is_signed=signed)
        msg = CanMessage(1, "m", 8, [sig], strict=True)
    except Exception:  # cantools refuses a signal outside the frame: not a layout to compare
        assume(False)
        raise
    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    return msg, Field("s", start, bits, signed, big_endian=big), draw(st.integers(lo, hi))


@settings(max_examples=300, deadline=None, derandomize=True)
@given(layouts())
def test_codec_places_any_signal_as_cantools(case: tuple[CanMessage, Field, int]) -> None:
    """netcfg.runtime.codec's byte placement (Intel and Motorola) is cantools' for every start bit and length."""
    msg, f, raw = case
    data = encode([f], 8, {"s": raw})
    assert data == msg.encode({"s": raw}, scaling=False)
    assert decode([f], data) == {"s": raw}
    assert decoder([f])(data) == {"s": raw}  # the compiled decoder masters use


@settings(max_examples=200, deadline=None, derandomize=True)
@given(
    st.lists(
        st.tuples(st.integers(0, 7), st.integers(1, 4), st.booleans(), st.booleans(), st.sampled_from([1, 0.5, 3]),
                  st.sampled_from([0, -10, 2.5]), st.booleans()),
        min_size=1, max_size=4,
    ),
    st.binary(min_size=8, max_size=8),
)
def test_the_compiled_decoder_reads_what_decode_reads(
    shapes: list[tuple[int, int, bool, bool, float, float, bool]], payload: bytes
) -> None:
    """codec.decoder() (a layout worked out once) returns decode()'s values, key for key and type for type, for
    signed, scaled, offset, Motorola and IEEE float fields over any payload (decode() is cantools' above)."""
    fields = []
    for k, (byte, size, signed, big, scale, offset, is_float) in enumerate(shapes):
        if is_float:
            fields.append(Field(f"f{k}", 0, 32, is_float=True))
        elif big:
            fields.append(Field(f"f{k}", 8 * byte + 7, 8 * min(size, 8 - byte), signed, scale=scale, offset=offset,
                                big_endian=True))
        else:
            fields.append(Field(f"f{k}", 8 * byte, 8 * min(size, 8 - byte), signed, scale=scale, offset=offset))
    want = decode(fields, payload)
    got = decoder(fields)(payload)
    assert list(got) == list(want)
    assert [repr(v) for v in got.values()] == [repr(v) for v in want.values()]  # a NaN float equals itself here


@settings(max_examples=200, deadline=None, derandomize=True)
@given(
    st.lists(st.tuples(st.integers(0, 2), st.sampled_from([8, 16, 32, 64]), st.booleans(), st.booleans()),
             min_size=1, max_size=4),
    st.binary(min_size=0, max_size=40),
)
def test_whole_byte_fields_decode_through_struct_as_decode_reads_them(
    shapes: list[tuple[int, int, bool, bool]], payload: bytes
) -> None:
    """PDO-shaped layouts (whole little-endian bytes of 8-64 bits, integers or IEEE floats, gaps between them) go
    through one struct unpack in codec.decoder(); its values are decode()'s, key for key and type for type, and a
    payload shorter than the fields reads its missing bytes as zeros, as decode() does."""
    fields, at = [], 0
    for k, (gap, bits, signed, is_float) in enumerate(shapes):
        at += gap
        fields.append(Field(f"f{k}", 8 * at, bits, signed, is_float=is_float and bits in (32, 64)))
        at += bits // 8
    assert _struct_layout(tuple(fields)) is not None  # the layout this test is about
    want = decode(fields, payload)
    got = decoder(fields)(payload)
    assert list(got) == list(want)
    assert [repr(v) for v in got.values()] == [repr(v) for v in want.values()]


@pytest.mark.parametrize("name", FILES)
def test_the_imported_spec_checks_as_the_dbc_does(tmp_path: Path, name: str) -> None:
    """`netcfg import dbc` writes YAML (value names, multiplexing and byte order included) whose model is the
    DBC's own, signal for signal, with the same response times."""
    from netcfg.diagnostics import Collector
    from netcfg.importers import write_spec
    from netcfg.importers.dbc import import_dbc

    model, report, db = analysed(name)
    got = import_dbc(CORPUS / name, options_for(db), Collector())
    assert got is not None
    spec = tmp_path / "spec.yaml"
    spec.write_text(write_spec(*got), encoding="utf-8")
    again, again_report = analyse_spec(spec)
    assert again is not None and again_report["ok"], again_report["errors"]
    for m in model.messages.values():
        assert again.messages[m.name].signals == m.signals, m.name
    wcrt = [[(m["name"], m["wcrt_us"]) for m in b["messages"]] for b in report["buses"]]
    assert [[(m["name"], m["wcrt_us"]) for m in b["messages"]] for b in again_report["buses"]] == wcrt


def test_dbc_to_spec_to_dbc_keeps_every_signal(tmp_path: Path) -> None:
    """hard_cases.dbc imported and built again: cantools reads the same signals from both files (byte order,
    sign, float type, scale, offset, range, unit, multiplexing, value names), except the overlapping one netcfg
    leaves out; the cycle times are the same."""
    from netcfg.emit import dbc as emit_dbc

    model, report, source = analysed("hard_cases.dbc")
    (text,) = emit_dbc.emit(model, report).values()
    built = cantools.database.load_string(text.decode("cp1252"), database_format="dbc", strict=False)
    assert isinstance(built, Database)

    def signal(s: Signal) -> tuple[Any, ...]:
        choices = tuple(sorted((int(k), str(v)) for k, v in (s.choices or {}).items()))
        mux = (s.multiplexer_signal, tuple(s.multiplexer_ids or ()), s.is_multiplexer)
        return (s.name, s.start, s.length, s.byte_order, s.is_signed, s.is_float, s.scale, s.offset, mux, choices,
                s.minimum, s.maximum, s.unit)

    for m in source.messages:
        again = built.get_message_by_name(m.name)
        expected = {signal(s) for s in m.signals if (m.name, s.name) != ("Overlap", "Wide")}
        assert {signal(s) for s in again.signals} == expected, m.name
        assert again.cycle_time == m.cycle_time
