"""Integer-only access in the generated C headers: scaled signals are raw integer fields with exact fixed-point
scale macros, so an MCU without an FPU never touches a double; float accessors exist only under
NETCFG_FLOAT_ACCESSORS.

The references: gcc with -std=c99 -Wall -Wextra -Wpedantic -Werror, and -mgeneral-regs-only (x86: any
floating-point or SSE register use is a compile error), cantools reading our DBC, canopen reading our DCF's
PDO mappings; the fixed-point figures are hand-derived in each test's docstring.
"""

from __future__ import annotations

import math
import os
import platform
import re
import shutil
import subprocess
from fractions import Fraction
from pathlib import Path
from typing import Any

import canopen
import cantools
import pytest
from conftest import SPECS
from test_emit_c import C_FLAGS, dump_spec, write

from netcfg.check import analyse_spec
from netcfg.emit import c_header, dbc
from netcfg.model import Model
from netcfg.protocols.canopen import dcf as canopen_dcf

GCC = shutil.which("gcc")
needs_gcc = pytest.mark.skipif(GCC is None, reason="gcc is not installed")
# x86's -mgeneral-regs-only turns any floating-point code into a compile error: the proof that nothing needs an FPU
NO_FPU = ["-mgeneral-regs-only"] if platform.machine() in ("x86_64", "AMD64", "i686") else []

SPEC: dict[str, Any] = {
    "system": "fixed",
    "buses": [{"name": "can0", "protocol": "can", "bitrate": "500 kbit/s"}],
    "nodes": [{"name": "mcu", "buses": ["can0"]}, {"name": "pc", "buses": ["can0"]}],
    "messages": [
        {
            "name": "sensor",
            "id": 0x123,
            "producer": "mcu",
            "consumers": ["pc"],
            "size": 8,
            "period": "10 ms",
            "signals": [
                {"name": "angle", "bits": 16, "signed": True, "scale": 1 / 65536, "unit": "rad"},
                {"name": "pos", "bits": 20, "signed": True, "scale": 0.001, "offset": -100, "unit": "m"},
                {"name": "temp", "bits": 8, "scale": 0.5, "offset": -40, "min": -40, "max": 85, "unit": "degC"},
                {"name": "count", "bits": 12},
            ],
        }
    ],
}
FIELDS = ("angle", "pos", "temp", "count")


def analysed(tmp_path: Path, spec: dict[str, Any]) -> tuple[Model, dict[str, Any]]:
    model, report = analyse_spec(dump_spec(tmp_path, spec, "fixed.yaml"))
    assert model is not None and report["ok"], report["errors"]
    return model, report


def run(tmp_path: Path, source: str, flags: list[str]) -> list[str]:
    assert GCC is not None
    (tmp_path / "prog.c").write_text(source, encoding="utf-8")
    exe = tmp_path / "prog"
    proc = subprocess.run(
        [GCC, *C_FLAGS, *flags, "-I", str(tmp_path / "c"), "-o", str(exe), str(tmp_path / "prog.c")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    return subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=True).stdout.splitlines()


def test_scale_macros_are_the_exact_fractions_the_spec_wrote(tmp_path: Path) -> None:
    """physical * DEN = raw * SCALE_NUM + OFFSET_NUM by hand: angle's 1/65536 is 1/65536 (a binary fraction,
    exact as a double too); pos's 0.001 with offset -100 is (raw - 100000) / 1000; temp's 0.5 with offset -40 is
    (raw - 80) / 2. The struct holds each as its raw integer type: int16_t, int32_t (20 bits), uint8_t."""
    model, report = analysed(tmp_path, SPEC)
    text = c_header.emit(model, report)["c/mcu.h"].decode()
    for sig, (num, off, den) in {"ANGLE": (1, 0, 65536), "POS": (1, -100000, 1000), "TEMP": (1, -80, 2)}.items():
        assert f"#define MSG_SENSOR_{sig}_SCALE_NUM INT64_C({num})" in text
        assert f"#define MSG_SENSOR_{sig}_OFFSET_NUM INT64_C({off})" in text
        assert f"#define MSG_SENSOR_{sig}_DEN INT64_C({den})" in text
    for decl in ("int16_t angle;", "int32_t pos;", "uint8_t temp;", "uint16_t count;"):
        assert f"    {decl}" in text
    # the only doubles in the code (comments aside) are the accessors', behind the macro
    code = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    before, accessors = code.split("#ifdef NETCFG_FLOAT_ACCESSORS")
    assert "double" not in before and "double" in accessors
    assert c_header.fixed_point(1e-30, 0.0) is None  # 10^30 does not fit an int64_t: no macros, a comment


@needs_gcc
def test_integer_only_codecs_round_trip_with_cantools(tmp_path: Path) -> None:
    """Built without NETCFG_FLOAT_ACCESSORS (and on x86 with -mgeneral-regs-only, so no floating point at all):
    raw fields packed by C decode in cantools (our DBC) to raw * scale + offset, which equals the macros'
    (raw * SCALE_NUM + OFFSET_NUM) / DEN; frames cantools encodes from physical values unpack in C to the raws
    whose fixed-point value is that physical value. temp: max 85 degC is raw (85 + 40) / 0.5 = 250, so raw 251
    is refused and the buffer left as it was; min -40 is raw 0."""
    model, report = analysed(tmp_path, SPEC)
    files = {**c_header.emit(model, report), **dbc.emit(model, report)}
    write(files, tmp_path)
    db = cantools.database.load_file(str(tmp_path / "dbc" / "can0.dbc"))
    msg = db.get_message_by_name("sensor")
    raws = [
        {"angle": 0, "pos": 0, "temp": 0, "count": 0},
        {"angle": -32768, "pos": -524288, "temp": 250, "count": 4095},
        {"angle": 32767, "pos": 524287, "temp": 80, "count": 1},
        {"angle": -1, "pos": 100000, "temp": 1, "count": 2048},
        {"angle": 1, "pos": 0, "temp": 251, "count": 0},  # temp above max
    ]
    physical = [  # chosen exact in both decimal and binary, so cantools' float encode has no rounding to argue
        {"angle": 0.375, "pos": -99.5, "temp": 21.5, "count": 7},
        {"angle": -0.25, "pos": 0.0, "temp": -40.0, "count": 0},
        {"angle": 0.0001220703125, "pos": 423.75, "temp": 85.0, "count": 100},
    ]
    frames = [msg.encode(v, scaling=True, strict=True) for v in physical]
    lines = ["#include <inttypes.h>", "#include <stdio.h>", '#include "mcu.h"', "int main(void)", "{"]
    lines += ["    struct msg_sensor v, w;", "    uint8_t d[MSG_SENSOR_SIZE];", "    size_t i;"]
    lines.append(
        '    printf("%" PRId64 " %" PRId64 " %" PRId64 " %" PRId64 " %" PRId64 " %" PRId64 " %" PRId64 " %" PRId64'
        ' " %" PRId64 "\\n", MSG_SENSOR_ANGLE_SCALE_NUM, MSG_SENSOR_ANGLE_OFFSET_NUM, MSG_SENSOR_ANGLE_DEN,'
        " MSG_SENSOR_POS_SCALE_NUM, MSG_SENSOR_POS_OFFSET_NUM, MSG_SENSOR_POS_DEN, MSG_SENSOR_TEMP_SCALE_NUM,"
        " MSG_SENSOR_TEMP_OFFSET_NUM, MSG_SENSOR_TEMP_DEN);"
    )
    for r in raws:
        lines += ["    memset(&v, 0, sizeof v);", "    memset(d, 0xAA, sizeof d);"]
        lines += [f"    v.{name} = {r[name]};" for name in FIELDS]
        lines += ['    printf("%d ", msg_sensor_pack(d, &v) ? 1 : 0);']
        lines += ['    for (i = 0; i < sizeof d; i++) { printf("%02x", d[i]); }', '    printf("\\n");']
    for data in frames:
        lines.append("    {")
        lines.append(f"        const uint8_t f[MSG_SENSOR_SIZE] = {{{', '.join(str(b) for b in data)}}};")
        lines.append("        msg_sensor_unpack(&w, f);")
        lines.append('        printf("%ld %ld %ld %ld\\n", (long)w.angle, (long)w.pos, (long)w.temp, (long)w.count);')
        lines.append("    }")
    lines += ["    return 0;", "}"]
    out = run(tmp_path, "\n".join(lines) + "\n", NO_FPU)
    macro = [int(x) for x in out[0].split()]
    fixed = {name: (macro[3 * k], macro[3 * k + 1], macro[3 * k + 2]) for k, name in enumerate(FIELDS[:3])}
    fixed["count"] = (1, 0, 1)
    assert fixed["pos"] == (1, -100000, 1000)

    def exact(name: str, raw: int) -> Fraction:
        num, off, den = fixed[name]
        return Fraction(raw * num + off, den)

    packed = out[1 : 1 + len(raws)]
    for r, line in zip(raws, packed):
        ok, hexdata = line.split()
        if r["temp"] > 250:
            assert (ok, hexdata) == ("0", "aa" * 8)
            continue
        assert ok == "1"
        data = bytes.fromhex(hexdata)
        assert msg.decode(data, scaling=False) == r  # the raws cantools reads from C's bytes
        theirs = msg.decode(data, scaling=True, decode_choices=False)
        for name in FIELDS:
            assert math.isclose(float(theirs[name]), float(exact(name, r[name])), rel_tol=1e-15, abs_tol=1e-12)
    for values, line in zip(physical, out[1 + len(raws) :]):
        got = dict(zip(FIELDS, map(int, line.split())))
        for name in FIELDS:
            assert exact(name, got[name]) == Fraction(values[name]), (name, got[name], values[name])


@needs_gcc
def test_float_accessors_only_under_their_macro(tmp_path: Path) -> None:
    """The same header: without NETCFG_FLOAT_ACCESSORS msg_sensor_pos_get() does not exist (an implicit
    declaration is an error under -Werror); with it, _set(-99.5) stores raw (-99.5 + 100) / 0.001 = 500, and
    _get gives the value back; _set(85.5) on temp (max 85) is refused and leaves the field as it was."""
    model, report = analysed(tmp_path, SPEC)
    write(c_header.emit(model, report), tmp_path)
    source = "\n".join(
        [
            "#include <stdio.h>",
            '#include "mcu.h"',
            "int main(void)",
            "{",
            "    struct msg_sensor v;",
            "    bool ok;",
            "    memset(&v, 0, sizeof v);",
            "    v.temp = 7;",
            "    ok = msg_sensor_pos_set(&v, -99.5);",
            '    printf("%d %ld ", ok ? 1 : 0, (long)v.pos);',
            "    ok = msg_sensor_temp_set(&v, 85.5);",
            '    printf("%d %ld ", ok ? 1 : 0, (long)v.temp);',
            '    printf("%.17g\\n", msg_sensor_pos_get(&v));',
            "    return 0;",
            "}",
        ]
    )
    assert GCC is not None
    (tmp_path / "acc.c").write_text(source + "\n", encoding="utf-8")
    without = subprocess.run(
        [GCC, *C_FLAGS, "-I", str(tmp_path / "c"), "-c", "-o", os.devnull, str(tmp_path / "acc.c")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert without.returncode != 0 and "msg_sensor_pos_set" in without.stderr
    assert run(tmp_path, source + "\n", ["-DNETCFG_FLOAT_ACCESSORS"]) == ["1 500 0 7 -99.5"]


@needs_gcc
def test_allex2_pdo_codecs_agree_with_canopen_reading_our_dcf(tmp_path: Path) -> None:
    """ALLEX-2's PDOs (seed 000: position, velocity, torque of the EPOS4s) are plain integers: the bytes C packs
    are the bytes canopen's PDO map (read from our DCF with from_od=True) holds for the same values, and C's
    unpack of canopen's bytes gives its values back; integer-only, so built with -mgeneral-regs-only on x86."""
    model, report = analyse_spec(SPECS / "allex2.yaml")
    assert model is not None
    write({**c_header.emit(model, report), **canopen_dcf.emit(model, report)}, tmp_path)
    messages = [m for bus in model.buses.values() for m in bus.messages if m.pdo is not None and m.signals]
    messages = [m for m in messages if m.pdo is not None and m.pdo.node == "hip_l"]
    assert len(messages) >= 3  # seed 000: 1 RxPDO + 2 TxPDO per drive
    node_id = model.nodes["hip_l"].node_id
    assert node_id is not None
    node = canopen.RemoteNode(node_id, str(tmp_path / "canopen" / "hip_l.dcf"))
    canopen.Network().add_node(node)  # not connected: the PDO maps only subscribe to their COB-IDs
    assert node.tpdo is not None and node.rpdo is not None
    node.tpdo.read(from_od=True)
    node.rpdo.read(from_od=True)
    cases: list[tuple[str, dict[str, int], bytes]] = []
    for msg in messages:
        assert msg.pdo is not None
        pdo_map = (node.tpdo if msg.pdo.kind == "tpdo" else node.rpdo).map[msg.pdo.number]
        assert len(pdo_map.map) == len(msg.signals)
        for k in range(3):
            values = {}
            for sig, var in zip(msg.signals, pdo_map.map):
                lo, hi = (-(1 << (sig.bits - 1)), (1 << (sig.bits - 1)) - 1) if sig.signed else (0, (1 << sig.bits) - 1)
                values[sig.name] = (
                    (lo, hi, -1 if sig.signed else 1)[k] if k < 2 else (lo // 3 if sig.signed else hi // 3)
                )
                var.raw = values[sig.name]
            cases.append((msg.name, values, bytes(pdo_map.data)))
    lines = ["#include <stdio.h>", "#include <inttypes.h>", '#include "hip_l.h"', "int main(void)", "{"]
    for name, values, data in cases:
        lines += ["    {", f"        struct msg_{name} v, w;", f"        uint8_t d[MSG_{name.upper()}_SIZE];"]
        lines += [f"        const uint8_t f[MSG_{name.upper()}_SIZE] = {{{', '.join(str(b) for b in data)}}};"]
        lines += ["        size_t i;", "        memset(&v, 0, sizeof v);"]
        lines += [f"        v.{s} = ({'INT64_C' if x < 0 else 'UINT64_C'}({x}));" for s, x in values.items()]
        lines += [f"        if (!msg_{name}_pack(d, &v)) {{ return 1; }}"]
        lines += ['        for (i = 0; i < sizeof d; i++) { printf("%02x", d[i]); }']
        lines += [f"        msg_{name}_unpack(&w, f);"]
        lines += [f'        printf(" %" PRId64, (int64_t)w.{s});' for s in values]
        lines += ['        printf("\\n");', "    }"]
    lines += ["    return 0;", "}"]
    out = run(tmp_path, "\n".join(lines) + "\n", NO_FPU)
    assert len(out) == len(cases)
    for (name, values, data), line in zip(cases, out):
        hexdata, *back = line.split()
        assert bytes.fromhex(hexdata) == data, name
        assert [int(x) for x in back] == list(values.values()), name
