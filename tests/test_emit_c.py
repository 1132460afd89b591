"""C headers (c/<node>.h) and FTT-CAN SRT files (ftt/<bus>_srt.*): real compilers build them, and the bytes a
generated pack() writes are the bytes netcfg.runtime.codec.encode writes.

The references: gcc/g++ with -Wall -Wextra -Wpedantic -Werror (DESIGN.md: "gcc compiles our C"), the Python
codec (the one definition of the payload layout), the CAMBADA paper's Table 2 (tests/test_seeds.py TABLE_2)
and the FTT-CAN rule that an entry of period T and init time O is due in EC k when (k - O) mod T = 0.
"""

from __future__ import annotations

import csv
import io
import math
import re
import shutil
import struct
import subprocess
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import ROOT, SPECS, load_spec
from test_seeds import TABLE_2

from netcfg.build import build
from netcfg.check import analyse_spec
from netcfg.emit import c_header
from netcfg.model import Model
from netcfg.protocols.ftt import srt
from netcfg.runtime import raw_signal_name
from netcfg.runtime.codec import CodecError, Field, Number, decode, encode
from netcfg.templating import field_of

GCC = shutil.which("gcc")
GXX = shutil.which("g++")
needs_gcc = pytest.mark.skipif(GCC is None, reason="gcc is not installed")
needs_gxx = pytest.mark.skipif(GXX is None, reason="g++ is not installed")
C_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror"]
CXX_FLAGS = ["-std=c++17", "-Wall", "-Wextra", "-Wpedantic", "-Werror"]
ALL_SPECS = sorted(p.name for p in SPECS.glob("*.yaml"))
# the specs whose nodes talk on message buses, so get node headers; an EtherCAT segment's C header is its process
# image, which tests/test_ethercat.py compiles
C_SPECS = [
    n for n in ALL_SPECS
    if any(b["protocol"] != "ethercat" for b in yaml.safe_load((SPECS / n).read_text(encoding="utf-8"))["buses"])
]


# --- helpers ------------------------------------------------------------------------------------------------------


def model_of(path: Path) -> tuple[Model, dict[str, Any]]:
    model, report = analyse_spec(path)
    assert model is not None and report["ok"], report["errors"]
    return model, report


def emit_c(path: Path) -> tuple[Model, dict[str, bytes]]:
    """Only this module's emitters (the other formats are tested on their own)."""
    model, report = model_of(path)
    return model, {**c_header.emit(model, report), **srt.emit(model, report)}


def write(files: dict[str, bytes], out: Path) -> None:
    for rel, data in files.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(data)


def compile_units(compiler: str, flags: list[str], units: list[Path], cwd: Path) -> None:
    """One compiler run, each file its own translation unit; objects land in cwd."""
    proc = subprocess.run(
        [compiler, *flags, "-c", *map(str, units)], cwd=cwd, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-4000:]


def dump_spec(tmp_path: Path, data: dict[str, Any], name: str) -> Path:
    tmp_path.mkdir(parents=True, exist_ok=True)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def with_signals(spec: dict[str, Any], signals: dict[str, list[dict[str, Any]]]) -> dict[str, Any]:
    for msg in spec["messages"]:
        if msg["name"] in signals:
            msg["signals"] = signals[msg["name"]]
    return spec


def cambada_with_signals(tmp_path: Path) -> Path:
    """specs/cambada.yaml with payload layouts (the paper gives only sizes): unaligned fields, a float32 that
    starts at bit 4, scaled fields whose half steps test round-half-to-even, bounded fields."""
    s16 = {"bits": 16, "signed": True, "scale": 0.01, "unit": "rad/s"}
    spec = with_signals(
        load_spec("cambada.yaml"),
        {
            "motor_setpoints": [{"name": f"w{i}", **s16} for i in (1, 2, 3)],
            "encoder1": [{"name": "count", "bits": 24, "signed": True}],
            "odo_position": [
                {"name": "x", "bits": 20, "signed": True, "scale": 0.001, "unit": "m"},
                {"name": "y", "bits": 20, "signed": True, "scale": 0.001, "offset": -100.0, "unit": "m"},
                {"name": "valid", "bits": 1},
                {"name": "quality", "bits": 15, "min": 0, "max": 10000},
            ],
            "odo_orientation": [{"name": "theta", "bits": 32, "float": True, "min": -3.5, "max": 3.5}],
            "velocity_linear": [
                {"name": "flags", "bits": 4},
                {"name": "vx", "bits": 32, "float": True},
                {"name": "vy", "bits": 20, "signed": True, "scale": 0.5},
            ],
            "velocity_angular": [
                {"name": "omega", "bits": 12, "signed": True, "scale": 0.01, "offset": 0.5, "min": -10, "max": 10},
                {"name": "mode", "bits": 3},
            ],
            "kick": [{"name": "strength", "bits": 7, "max": 100}, {"name": "armed", "bits": 1}],
        },
    )
    return dump_spec(tmp_path, spec, "cambada.yaml")


def ntua_with_signals(tmp_path: Path) -> Path:
    """specs/ntua_sahr.yaml with Table 6.1's layouts (0x31: PWM duty + direction in 1 byte; 0x42: a 4-byte
    encoder count) and a test-only 38-byte telemetry datagram with the 64-bit cases a CAN frame cannot hold."""
    spec = with_signals(
        load_spec("ntua_sahr.yaml"),
        {
            "hip_encoder": [{"name": "count", "bits": 32, "signed": True}],
            "hip_pwm": [{"name": "duty", "bits": 7, "max": 100, "unit": "%"}, {"name": "dir", "bits": 1}],
        },
    )
    spec["messages"].append(
        {
            "name": "telemetry",
            "id": 0x55,
            "producer": "mcu_hip",
            "consumers": ["pc"],
            "size": 38,
            "rate": "100 Hz",
            "udp": {"src_port": 5002, "dst_port": 6003},
            "signals": [
                {"name": "flags", "bits": 3},
                {"name": "pos", "bits": 64, "float": True},
                {"name": "ticks", "bits": 64},
                {"name": "delta", "bits": 64, "signed": True},
                {"name": "big", "bits": 40, "signed": True, "scale": 0.25, "offset": 10.0},
                {"name": "huge", "bits": 64, "scale": 2.0},
            ],
        }
    )
    return dump_spec(tmp_path, spec, "ntua_sahr.yaml")


# --- every header and SRT file compiles ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, dict[str, bytes]]]:
    out = {}
    for name in ALL_SPECS:
        folder = tmp_path_factory.mktemp(Path(name).stem)
        _, files = emit_c(SPECS / name)
        write(files, folder)
        out[name] = (folder, files)
    return out


def include_units(folder: Path, headers: list[str], suffix: str) -> list[Path]:
    """A tiny translation unit per header that includes it and nothing else."""
    units = []
    for i, rel in enumerate(headers):
        unit = folder / f"unit{i}{suffix}"
        unit.write_text(f'#include "{rel}"\nint netcfg_unit_{i};\n', encoding="utf-8")
        units.append(unit)
    return units


@needs_gcc
@pytest.mark.parametrize("name", C_SPECS)
def test_every_header_and_srt_compiles_as_c99(name: str, built: dict[str, tuple[Path, dict[str, bytes]]]) -> None:
    folder, files = built[name]
    headers = [rel for rel in files if rel.endswith(".h")]
    assert any(rel.startswith("c/") for rel in headers)
    assert GCC is not None
    compile_units(GCC, C_FLAGS, include_units(folder, headers, ".c"), folder)
    sources = [folder / rel for rel in files if rel.endswith(".c")]
    if sources:
        compile_units(GCC, C_FLAGS, sources, folder)
    # all of a system's headers in one translation unit: shared messages and buses are defined once
    every = folder / "every.c"
    every.write_text("".join(f'#include "{rel}"\n' for rel in headers) + "int netcfg_every;\n", encoding="utf-8")
    compile_units(GCC, C_FLAGS, [every], folder)
    compile_units(GCC, ["-std=c11", *C_FLAGS[1:]], [every], folder)  # the _Static_assert branch
    compile_units(GCC, [*C_FLAGS, "-DNETCFG_FLOAT_ACCESSORS"], [every], folder)  # and the physical-unit accessors


@needs_gxx
@pytest.mark.parametrize("name", C_SPECS)
def test_every_header_and_srt_compiles_as_cxx17(name: str, built: dict[str, tuple[Path, dict[str, bytes]]]) -> None:
    folder, files = built[name]
    headers = [rel for rel in files if rel.endswith(".h")]
    assert GXX is not None
    compile_units(GXX, CXX_FLAGS, include_units(folder, headers, ".cpp"), folder)
    compile_units(GXX, [*CXX_FLAGS, "-DNETCFG_FLOAT_ACCESSORS"], include_units(folder, headers, ".cpp"), folder)
    sources = [folder / rel for rel in files if rel.endswith(".c")]
    if sources:
        compile_units(GXX, ["-x", "c++", *CXX_FLAGS], sources, folder)


def test_headers_include_only_the_three_standard_headers(built: dict[str, tuple[Path, dict[str, bytes]]]) -> None:
    for _, files in built.values():
        for rel, data in files.items():
            if rel.startswith("c/"):
                includes = set(re.findall(r"^#include (.*)$", data.decode(), re.M))
                assert includes == {"<stdbool.h>", "<stdint.h>", "<string.h>"}, rel
                assert b"malloc" not in data


def test_one_header_per_node_that_communicates() -> None:
    """allex2: the master and the six drives exchange PDOs; cambada: every node sits on the FTT-CAN bus and
    receives the trigger message; ntua_sahr: the two MCUs and the PC exchange datagrams."""
    for name, nodes in [
        ("allex2.yaml", {"master", "hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r"}),
        ("ntua_sahr.yaml", {"mcu_hip", "mcu_spring", "pc"}),
    ]:
        _, files = emit_c(SPECS / name)
        assert {rel for rel in files if rel.startswith("c/")} == {f"c/{n}.h" for n in nodes}
    model, files = emit_c(SPECS / "cambada.yaml")
    assert {rel for rel in files if rel.startswith("c/")} == {f"c/{n}.h" for n in model.nodes}
    assert sorted(rel for rel in files if rel.startswith("ftt/")) == [
        "ftt/lowlevel_srt.c",
        "ftt/lowlevel_srt.csv",
        "ftt/lowlevel_srt.h",
        "ftt/lowlevel_srt.md",
    ]


def test_header_constants_of_the_seed_systems() -> None:
    """Values from the seeds: ALLEX-2 drive hip_l is node 1, 1 Mbit/s, SYNC every 20 ms (COB-ID 0x80, CiA 301),
    its RPDO1 is COB-ID 0x200 + 1; CAMBADA EC = 5 ms, TM of 5 bytes, encoder1 is FTT id 1 with Table 2's
    period 2 and init time 2, trigger 8 (encoder reading) activates motor1; NTUA: mcu_hip at 192.168.1.11
    sends message 0x42, receives 0x31 (Table 6.1)."""
    _, files = emit_c(SPECS / "allex2.yaml")
    hip = files["c/hip_l.h"].decode()
    for line in [
        "#define NODE_HIP_L_ID 1",
        "#define BUS_CAN0_BITRATE UINT32_C(1000000)",
        "#define BUS_CAN0_SYNC_PERIOD_NS UINT32_C(20000000)",
        "#define BUS_CAN0_SYNC_ID 0x080",
        "#define MSG_HIP_L_CMD_ID 0x201",
        "#define MSG_HIP_L_CMD_EXTENDED 0",
        "#define MSG_HIP_L_CMD_SIZE 8",
    ]:
        assert line in hip
    _, files = emit_c(SPECS / "cambada.yaml")
    motor = files["c/motor1.h"].decode()
    for line in [
        "#define BUS_LOWLEVEL_EC_NS UINT32_C(5000000)",
        "#define BUS_LOWLEVEL_TM_SIZE 5",
        "#define MSG_ENCODER1_FTT_ID 1",
        "#define MSG_ENCODER1_PERIOD_EC 2",
        "#define MSG_ENCODER1_INIT_EC 2",
        "#define TRIG_ENCODER_READ_FTT_ID 8",
        "#define TRIG_ENCODER_READ_FTT_BIT (UINT64_C(1) << 8)",
    ]:
        assert line in motor
    _, files = emit_c(SPECS / "ntua_sahr.yaml")
    mcu = files["c/mcu_hip.h"].decode()
    for line in [
        '#define NODE_MCU_HIP_IP "192.168.1.11"',
        "#define NODE_MCU_HIP_IP_U32 UINT32_C(0xC0A8010B)",
        "#define MSG_HIP_ENCODER_ID 0x42",
        "#define MSG_HIP_ENCODER_DATAGRAM_SIZE (1 + MSG_HIP_ENCODER_SIZE)",
        "#define MSG_HIP_PWM_ID 0x31",
        "#define MSG_HIP_PWM_DST_PORT 5001",
    ]:
        assert line in mcu


def test_extended_identifiers_carry_the_flag(tmp_path: Path) -> None:
    """A 29-bit identifier: MSG_<name>_EXTENDED is 1 and the id is written with all 8 hex digits."""
    spec = {
        "system": "ext",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": "500 kbit/s", "id_bits": 29}],
        "nodes": [{"name": "a", "buses": ["can0"]}, {"name": "b", "buses": ["can0"]}],
        "messages": [
            {"name": "m", "id": 0x18FF1234, "producer": "a", "consumers": ["b"], "size": 2, "period": "10 ms"}
        ],
    }
    _, files = emit_c(dump_spec(tmp_path, spec, "ext.yaml"))
    text = files["c/a.h"].decode()
    assert "#define MSG_M_ID 0x18FF1234" in text and "#define MSG_M_EXTENDED 1" in text


def test_c_types_are_the_smallest_that_hold_the_bits(tmp_path: Path) -> None:
    """The rule: integers take the smallest of (u)int8/16/32/64 holding their bits, floats float/double, and
    scaled values their raw integer the same way (so an MCU without an FPU never needs a double); a 24-bit
    count is int32_t, a 7-bit duty uint8_t, a 48-bit raw payload uint64_t, a 20-bit signed scaled x int32_t,
    a 16-bit signed scaled w1 int16_t, a 40-bit signed scaled `big` int64_t."""
    _, files = emit_c(cambada_with_signals(tmp_path))
    text = files["c/gateway.h"].decode() + files["c/odometry.h"].decode() + files["c/holonomic.h"].decode()
    for decl in [
        "int32_t count;",
        "uint8_t valid;",
        "uint16_t quality;",
        "int32_t x;",
        "float theta;",
        "float vx;",
        "int32_t vy;",
        "uint8_t strength;",
        "int16_t w1;",
    ]:
        assert re.search(rf"^    {re.escape(decl)}", text, re.M), decl
    _, files = emit_c(SPECS / "cambada.yaml")
    assert "    uint64_t motor_setpoints_raw;" in files["c/holonomic.h"].decode()  # 6 bytes, no layout given
    _, files = emit_c(ntua_with_signals(tmp_path))
    pc = files["c/pc.h"].decode()
    for decl in ["double pos;", "uint64_t ticks;", "int64_t delta;", "int64_t big;", "uint64_t huge;"]:
        assert f"    {decl}" in pc


# --- pack/unpack agree with the Python codec, byte for byte ---------------------------------------------------------


def _c_width(f: Field) -> int:
    return next(w for w in (8, 16, 32, 64) if w >= f.bits)


def _is_f32(x: float) -> bool:
    try:
        return math.isnan(x) or struct.unpack("<f", struct.pack("<f", x))[0] == x
    except OverflowError:
        return False


def candidates(f: Field) -> list[Number]:
    """Values for one field: limits, zero, negatives, half steps, and values just out of range, as far as the
    C type can hold them (a uint8_t cannot be given 300)."""
    lo, hi = f.raw_range()
    if f.is_float:
        vals: list[float] = [0.0, -0.0, 1.5, -2.25, 0.1, 3.4028234663852886e38, 1.401298464324817e-45]
        vals += [math.inf, -math.inf, 1e300, -123456.789]
        for b in (f.minimum, f.maximum):
            if b is not None:
                vals += [b, b - 0.25, b + 0.25]
        return [v for v in vals if f.bits == 64 or _is_f32(v)]
    if f.is_integer:
        ints = [0, lo, hi, lo + 1, hi - 1, 1, -1, hi // 3, lo // 3, hi + 1, lo - 1]
        for b in (f.minimum, f.maximum):
            if b is not None:
                ints += [math.ceil(b), math.floor(b), math.ceil(b) - 1, math.floor(b) + 1]
        w = _c_width(f)
        t_lo, t_hi = (-(1 << (w - 1)), (1 << (w - 1)) - 1) if f.signed else (0, (1 << w) - 1)
        return list(dict.fromkeys(v for v in ints if t_lo <= v <= t_hi))
    s, o = f.scale, f.offset
    vals = [o, lo * s + o, hi * s + o, (hi + 1) * s + o, (lo - 1) * s + o, o + 2.5 * s, o - 3.5 * s, o + 1.5 * s]
    vals += [o - 0.5 * s, o + 0.49 * s, 1.2345, -7.0]  # infinities: test_c_range_checks_reject_out_of_range_values
    for b in (f.minimum, f.maximum):
        if b is not None:
            vals += [b, b - s, b + s]
    return vals


def c_literal(f: Field, v: Number) -> str:
    if f.is_float or not f.is_integer:
        v = float(v)
        if math.isinf(v):
            return "INFINITY" if v > 0 else "-INFINITY"
        return repr(v)
    if f.signed:
        return "(-INT64_C(9223372036854775807) - 1)" if v == -(1 << 63) else f"INT64_C({v})"
    return f"UINT64_C({v})"


def message_fields(model: Model) -> dict[str, tuple[int, str, list[Field]]]:
    """name -> (size, protocol, fields) of every message with a struct: its signals, or the `<name>_raw`
    field spanning a payload of 1-8 bytes given only as a size (the runtime's convention)."""
    out = {}
    for bus in model.buses.values():
        for msg in bus.messages:
            if msg.signals:
                out[msg.name] = (msg.size, bus.protocol, [field_of(s) for s in msg.signals])
            elif 0 < msg.size <= 8:
                out[msg.name] = (msg.size, bus.protocol, [Field(raw_signal_name(msg.name), 0, 8 * msg.size)])
    return out


def vectors(fields: list[Field]) -> list[dict[str, Number]]:
    cands = {f.name: candidates(f) for f in fields}
    n = max(len(c) for c in cands.values())
    return [{name: c[i % len(c)] for name, c in cands.items()} for i in range(n)]


def is_scaled(f: Field) -> bool:
    return not f.is_float and not f.is_integer


def run_c_codec(
    tmp_path: Path, files: dict[str, bytes], cases: list[tuple[str, list[Field], dict[str, Number]]]
) -> list[list[str]]:
    """Generate, build and run a C program that packs every case with the generated headers, prints
    `ok hexbytes` (the buffer starts as 0xAA bytes) and, when packed, the values unpack() gives back."""
    write(files, tmp_path)
    lines = ["#include <inttypes.h>", "#include <math.h>", "#include <stdio.h>"]
    lines += [f'#include "{rel}"' for rel in files if rel.startswith("c/")]
    lines += [
        "static void hex(const uint8_t *d, size_t n)",
        "{",
        "    size_t i;",
        "    for (i = 0; i < n; i++) {",
        '        printf("%02x", d[i]);',
        "    }",
        "}",
        "int main(void)",
        "{",
    ]
    for name, fields, values in cases:
        lines += [
            "    {",
            f"        struct msg_{name} v, w;",
            f"        uint8_t data[MSG_{name.upper()}_SIZE];",
            "        bool ok;",
            "        memset(&v, 0, sizeof v);",
            "        memset(data, 0xAA, sizeof data);",
        ]
        lines.append("        ok = true;")
        for f in fields:  # scaled signals are raw integers: physical values go through the float setters
            if is_scaled(f):
                lines.append(f"        ok = msg_{name}_{f.name}_set(&v, {c_literal(f, values[f.name])}) && ok;")
            else:
                lines.append(f"        v.{f.name} = {c_literal(f, values[f.name])};")
        lines += [
            f"        ok = ok && msg_{name}_pack(data, &v);",
            '        printf("%d ", ok ? 1 : 0);',
            "        hex(data, sizeof data);",
            "        if (ok) {",
            f"            msg_{name}_unpack(&w, data);",
        ]
        for f in fields:
            if is_scaled(f):
                lines.append(f'            printf(" %.17g", msg_{name}_{f.name}_get(&w));')
            elif f.is_float:
                lines.append(f'            printf(" %.17g", (double)w.{f.name});')
            elif f.signed:
                lines.append(f'            printf(" %" PRId64, (int64_t)w.{f.name});')
            else:
                lines.append(f'            printf(" %" PRIu64, (uint64_t)w.{f.name});')
        lines += ["        }", '        printf("\\n");', "    }"]
    lines += ["    return 0;", "}"]
    source = tmp_path / "vectors.c"
    source.write_text("\n".join(lines) + "\n", encoding="utf-8")
    assert GCC is not None
    exe = tmp_path / "vectors"
    proc = subprocess.run(
        [GCC, *C_FLAGS, "-DNETCFG_FLOAT_ACCESSORS", "-o", str(exe), str(source)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=True)
    return [line.split() for line in run.stdout.splitlines()]


def same_number(a: Number, b: Number) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return struct.pack("<d", float(a)) == struct.pack("<d", float(b))  # exact, and -0.0 is not 0.0
    return a == b


@needs_gcc
@pytest.mark.parametrize("which", ["allex2", "cambada", "ntua_sahr"])
def test_c_pack_and_unpack_match_the_python_codec(tmp_path: Path, which: str) -> None:
    """Every message with a layout, several vectors per signal (negative, limits, half steps, floats, infinities,
    out of range): C's bytes equal codec.encode's, C rejects exactly what the codec rejects and then leaves the
    buffer as it was, and C's unpack gives codec.decode's values."""
    spec = {
        "allex2": lambda: SPECS / "allex2.yaml",
        "cambada": lambda: cambada_with_signals(tmp_path),
        "ntua_sahr": lambda: ntua_with_signals(tmp_path),
    }[which]()
    model, files = emit_c(spec)
    cases = []
    for name, (_, _, fields) in message_fields(model).items():
        cases += [(name, fields, values) for values in vectors(fields)]
    assert len(cases) >= 20
    out = run_c_codec(tmp_path, files, cases)
    assert len(out) == len(cases)
    rejected = 0
    for (name, fields, values), got in zip(cases, out):
        size = message_fields(model)[name][0]
        try:
            expected = encode(fields, size, values)
        except CodecError:
            rejected += 1
            assert got == ["0", "aa" * size], (name, values)
            continue
        assert got[0] == "1" and got[1] == expected.hex(), (name, values, got)
        back = decode(fields, expected)
        for f, text in zip(fields, got[2:]):
            value: Number = float(text) if f.is_float or not f.is_integer else int(text)
            assert same_number(value, back[f.name]), (name, f.name, value, back[f.name])
    if which != "allex2":  # allex2's PDO fields fill their C types: nothing to reject
        assert rejected >= 5


@needs_gcc
def test_c_range_checks_reject_out_of_range_values(tmp_path: Path) -> None:
    """Hand-picked limits: hip_pwm.duty has max 100 in the spec; hip_encoder.count is a 32-bit two's complement
    integer held in an int32_t (nothing to reject); kick.strength 0..100, 7 bits; encoder1.count is 24-bit
    two's complement: -8388608..8388607; odo_orientation.theta is bounded to [-3.5, 3.5]; velocity_linear.vy
    has 20 bits at scale 0.5: raw -524288..524287, so physical -262144..262143.5, and no raw value for an
    infinity."""
    model, files = emit_c(ntua_with_signals(tmp_path / "ntua"))
    fields = message_fields(model)
    cases = [
        ("hip_pwm", {"duty": 100, "dir": 1}, True),
        ("hip_pwm", {"duty": 101, "dir": 0}, False),
        ("hip_pwm", {"duty": 0, "dir": 1}, True),
    ]
    out = run_c_codec(tmp_path / "ntua", files, [(n, fields[n][2], v) for n, v, _ in cases])
    assert [line[0] == "1" for line in out] == [ok for *_, ok in cases]
    assert out[1] == ["0", "aa"]
    model, files = emit_c(cambada_with_signals(tmp_path / "cambada"))
    fields = message_fields(model)
    cases = [
        ("kick", {"strength": 100, "armed": 1}, True),
        ("kick", {"strength": 101, "armed": 1}, False),
        ("encoder1", {"count": -8388608}, True),
        ("encoder1", {"count": 8388607}, True),
        ("encoder1", {"count": 8388608}, False),
        ("encoder1", {"count": -8388609}, False),
        ("odo_orientation", {"theta": 3.5}, True),
        ("odo_orientation", {"theta": -3.75}, False),
        ("velocity_linear", {"flags": 15, "vx": 1.0, "vy": 262143.5}, True),
        ("velocity_linear", {"flags": 15, "vx": 1.0, "vy": 262144.0}, False),
        ("velocity_linear", {"flags": 16, "vx": 1.0, "vy": 0.0}, False),
        ("velocity_linear", {"flags": 1, "vx": math.inf, "vy": 0.0}, True),  # a float field holds infinity
        ("velocity_linear", {"flags": 1, "vx": 1.0, "vy": math.inf}, False),  # a scaled one has no raw for it
        ("velocity_linear", {"flags": 1, "vx": 1.0, "vy": -math.inf}, False),
    ]
    out = run_c_codec(tmp_path / "cambada", files, [(n, fields[n][2], v) for n, v, _ in cases])
    assert [line[0] == "1" for line in out] == [ok for *_, ok in cases]
    for line, (name, _, ok) in zip(out, cases):
        if not ok:
            assert set(re.findall("..", line[1])) == {"aa"}, name  # nothing written


@needs_gcc
def test_udp_datagram_helpers_put_the_message_id_first(tmp_path: Path) -> None:
    """Seed 001, Table 6.1: the datagram is the 1-byte message id (0x31 for the PWM command) then the data; so
    duty 50 (0x32) with direction 1 (bit 7) is the datagram 31 b2."""
    _, files = emit_c(ntua_with_signals(tmp_path))
    write(files, tmp_path)
    source = tmp_path / "dgram.c"
    source.write_text(
        '#include <stdio.h>\n#include "c/mcu_hip.h"\n'
        "int main(void)\n{\n"
        "    struct msg_hip_pwm v, w;\n    uint8_t d[MSG_HIP_PWM_DATAGRAM_SIZE];\n"
        "    v.duty = 50;\n    v.dir = 1;\n"
        "    if (!msg_hip_pwm_pack_datagram(d, &v)) {\n        return 1;\n    }\n"
        '    printf("%02x%02x %d", d[0], d[1], msg_hip_pwm_unpack_datagram(&w, d, sizeof d) ? w.duty : -1);\n'
        "    d[0] = 0x42;\n"
        '    printf(" %d %d\\n", msg_hip_pwm_unpack_datagram(&w, d, sizeof d), '
        "msg_hip_pwm_unpack_datagram(&w, d, 1));\n"
        "    return 0;\n}\n",
        encoding="utf-8",
    )
    assert GCC is not None
    exe = tmp_path / "dgram"
    subprocess.run([GCC, *C_FLAGS, "-o", str(exe), str(source)], cwd=tmp_path, check=True, timeout=120)
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=True)
    assert run.stdout.split() == ["31b2", "50", "0", "0"]


# --- the CAMBADA SRT is Table 2 -------------------------------------------------------------------------------------


def test_cambada_srt_csv_is_table_2() -> None:
    """Rows (FTT id, period, init time) are exactly Table 2's, messages 0-7 then triggers 8-13, with Table 2's
    columns; row 0 goes from the holonomic controller to the three motor nodes, as in the paper."""
    _, files = emit_c(SPECS / "cambada.yaml")
    rows = list(csv.reader(io.StringIO(files["ftt/lowlevel_srt.csv"].decode())))
    assert rows[0] == ["FTT ID", "Source", "Destination", "Period (#ECs)", "Init time (#ECs)", "Short description"]
    table = {int(r[0]): (int(r[3]), int(r[4])) for r in rows[1:]}
    assert table == TABLE_2 and len(rows) - 1 == len(TABLE_2)
    assert [int(r[0]) for r in rows[1:]] == list(range(14))
    assert rows[1][1:3] == ["holonomic", "motor1, motor2, motor3"]
    assert rows[9][1] == ""  # a trigger has no source: the master's TM carries it
    md = files["ftt/lowlevel_srt.md"].decode()
    assert "| FTT ID | Source | Destination | Period (#ECs) | Init time (#ECs) | Short description |" in md
    assert "| 4 | odometry | gateway | 10 | 4 |" in md


@needs_gcc
def test_cambada_srt_c_tables_follow_table_2(tmp_path: Path) -> None:
    """The C tables, run: 14 entries with Table 2's period and init time, a macro-cycle of 30 ECs (LCM of 6, 2,
    10, 1), and in EC k the TM announces exactly the ids with (k - init) mod period = 0; the payload of the
    5-byte TM is the mask little-endian."""
    _, files = emit_c(SPECS / "cambada.yaml")
    write(files, tmp_path)
    source = tmp_path / "srt_main.c"
    source.write_text(
        '#include <inttypes.h>\n#include <stdio.h>\n#include "ftt/lowlevel_srt.h"\n'
        "int main(void)\n{\n    unsigned i;\n    uint8_t tm[FTT_LOWLEVEL_TM_SIZE];\n"
        '    printf("%d %d %d\\n", FTT_LOWLEVEL_SRT_LENGTH, FTT_LOWLEVEL_MACRO_CYCLE_EC, FTT_LOWLEVEL_TM_SIZE);\n'
        "    for (i = 0; i < FTT_LOWLEVEL_SRT_LENGTH; i++) {\n"
        '        printf("%u %" PRIu32 " %" PRIu32 "\\n", (unsigned)ftt_lowlevel_srt[i].ftt_id, '
        "ftt_lowlevel_srt[i].period_ec, ftt_lowlevel_srt[i].init_ec);\n    }\n"
        "    for (i = 0; i < FTT_LOWLEVEL_MACRO_CYCLE_EC; i++) {\n"
        '        printf("%" PRIu64 "\\n", (uint64_t)ftt_lowlevel_ec_schedule[i]);\n    }\n'
        "    ftt_lowlevel_tm_payload(tm, 24);\n"
        '    printf("%02x%02x%02x%02x%02x\\n", tm[0], tm[1], tm[2], tm[3], tm[4]);\n'
        "    return 0;\n}\n",
        encoding="utf-8",
    )
    assert GCC is not None
    exe = tmp_path / "srt_main"
    cmd = [GCC, *C_FLAGS, "-I", str(tmp_path), "-o", str(exe), str(source), str(tmp_path / "ftt/lowlevel_srt.c")]
    subprocess.run(cmd, cwd=tmp_path, check=True, timeout=120)
    out = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=True).stdout.splitlines()
    assert out[0] == "14 30 5"
    assert {int(a): (int(b), int(c)) for a, b, c in (line.split() for line in out[1:15])} == TABLE_2
    masks = [int(x) for x in out[15:45]]
    for k, mask in enumerate(masks):
        due = {i for i, (period, init) in TABLE_2.items() if (k - init) % period == 0}
        assert mask == sum(1 << i for i in due), k
    # EC 24 by hand from Table 2: ids 1-3 ((24-2) mod 2 = 0), 4-5 ((24-4) mod 10), 6-7 (24 mod 6), 8 (every EC),
    # 13 ((24-6) mod 6); mask 0x21FE, the TM bytes fe 21 00 00 00
    assert out[45] == "fe21000000"


# --- hostile text, determinism --------------------------------------------------------------------------------------

HOSTILE = '*/ #include <x>\n#error "boom" /* | a, b; ` <b> [x](y) */\n\\'


def hostile_spec(tmp_path: Path) -> Path:
    spec = {
        "system": "hostile",
        "description": HOSTILE,
        "buses": [
            {
                "name": "can0",
                "protocol": "ftt-can",
                "bitrate": "500 kbit/s",
                "ftt": {"ec": "5 ms", "tm_size": 2},
                "description": HOSTILE,
            }
        ],
        "nodes": [
            {"name": "m", "role": "master", "buses": ["can0"], "description": HOSTILE},
            {
                "name": "a",
                "buses": ["can0"],
                "description": HOSTILE,
                "tasks": [{"name": "t", "wcet": "100 us", "description": HOSTILE}],
            },
            {"name": "b", "buses": ["can0"]},
        ],
        "messages": [
            {
                "name": "x",
                "ftt_id": 0,
                "producer": "a",
                "consumers": ["b"],
                "period": "2 EC",
                "description": HOSTILE,
                "signals": [{"name": "v", "bits": 16, "signed": True, "unit": HOSTILE}],
            }
        ],
        "triggers": [
            {"name": "go", "ftt_id": 1, "bus": "can0", "period": "1 EC", "tasks": ["a.t"], "description": HOSTILE}
        ],
    }
    return dump_spec(tmp_path, spec, "hostile.yaml")


@needs_gcc
def test_hostile_descriptions_stay_comments(tmp_path: Path) -> None:
    """A description that closes a comment, includes a file and breaks lines must not reach the preprocessor:
    every header and the SRT source still compile, and the CSV and Markdown tables keep their shape."""
    model, files = emit_c(hostile_spec(tmp_path))
    assert model.messages["x"].description == HOSTILE  # it reached the Model, so the emitters saw it
    write(files, tmp_path)
    headers = [rel for rel in files if rel.endswith(".h")]
    assert GCC is not None
    compile_units(GCC, C_FLAGS, include_units(tmp_path, headers, ".c"), tmp_path)
    compile_units(GCC, C_FLAGS, [tmp_path / "ftt/can0_srt.c"], tmp_path)
    assert "#include <x>" in files["c/a.h"].decode()  # message x's description and unit are there...
    for rel in headers:  # ...but only inside comments, never as a directive of their own
        assert not re.search(r"^\s*#\s*(include <x>|error)", files[rel].decode(), re.M), rel
    rows = list(csv.reader(io.StringIO(files["ftt/can0_srt.csv"].decode())))
    assert [len(r) for r in rows] == [6, 6, 6]
    assert rows[1][5] == " ".join(HOSTILE.split())  # one line, quotes preserved
    md = [line for line in files["ftt/can0_srt.md"].decode().splitlines() if line.startswith("| 0 | a |")]
    assert len(md) == 1 and md[0].count("|") - md[0].count("\\|") == 7


def test_two_emits_are_byte_identical_and_carry_no_machine_paths() -> None:
    for name in ALL_SPECS:
        _, first = emit_c(SPECS / name)
        _, second = emit_c(SPECS / name)
        assert first == second, name
        for rel, data in first.items():
            assert str(ROOT).encode() not in data, rel
            assert not re.search(rb"20\d\d-\d\d-\d\d", data), rel  # no build dates


# A vendor EDS whose object names are no C identifiers: 'Switch' is a C keyword once in lower case, '2nd input'
# starts with a digit. Objects 0x1800/0x1A00 give the device one TPDO of up to two mapped objects (CiA 301).
IO_EDS = """\
[FileInfo]
FileName=io.eds
[DeviceInfo]
VendorName=netcfg tests
ProductName=io module
NrOfRXPDO=0
NrOfTXPDO=1
[1000]
ParameterName=Device type
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0
PDOMapping=0
[1800]
ParameterName=TPDO 1 communication
ObjectType=0x9
SubNumber=3
[1800sub0]
ParameterName=Highest sub-index
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=2
PDOMapping=0
[1800sub1]
ParameterName=COB-ID
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=$NODEID+0x180
PDOMapping=0
[1800sub2]
ParameterName=Transmission type
ObjectType=0x7
DataType=0x0005
AccessType=rw
DefaultValue=255
PDOMapping=0
[1A00]
ParameterName=TPDO 1 mapping
ObjectType=0x9
SubNumber=3
[1A00sub0]
ParameterName=Number of mapped objects
ObjectType=0x7
DataType=0x0005
AccessType=rw
DefaultValue=0
PDOMapping=0
[1A00sub1]
ParameterName=Mapped object 1
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0
PDOMapping=0
[1A00sub2]
ParameterName=Mapped object 2
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0
PDOMapping=0
[2000]
ParameterName=Switch
ObjectType=0x7
DataType=0x0004
AccessType=ro
PDOMapping=1
[2001]
ParameterName=2nd input
ObjectType=0x7
DataType=0x0005
AccessType=ro
PDOMapping=1
"""


@needs_gcc
def test_eds_object_names_become_c_identifiers(tmp_path: Path) -> None:
    """Signal names taken from EDS object names obey the name rules (netcfg.spec.schema.check_name): 'Switch'
    becomes switch_obj, not the keyword switch; '2nd input' becomes obj_2nd_input. The build's headers compile."""
    (tmp_path / "io.eds").write_text(IO_EDS, encoding="utf-8")
    spec = {
        "system": "eds_names",
        "buses": [{"name": "can0", "protocol": "canopen", "bitrate": "1 Mbit/s", "canopen": {"sync_period": "10 ms"}}],
        "nodes": [
            {"name": "master", "role": "master", "node_id": 1, "buses": ["can0"]},
            {"name": "io", "node_id": 2, "buses": ["can0"], "device": {"eds": "io.eds"}},
        ],
        "messages": [
            {
                "name": "io_inputs",
                "producer": "io",
                "consumers": ["master"],
                "pdo": {"tpdo": 1, "transmission": 1, "map": [0x2000, 0x2001]},
            }
        ],
    }
    report, out, files = build(dump_spec(tmp_path, spec, "eds_names.yaml"), tmp_path / "out")
    assert out is not None, report["errors"]
    master = files["c/master.h"].decode()
    assert "int32_t switch_obj;" in master and "uint8_t obj_2nd_input;" in master
    headers = [rel for rel in files if rel.startswith("c/")]
    assert GCC is not None
    compile_units(GCC, C_FLAGS, include_units(out, headers, ".c"), out)


def test_headers_are_the_same_when_the_blocks_marker_is_in_the_text(monkeypatch: pytest.MonkeyPatch) -> None:
    """c_header joins the message blocks into the rendered header as bytes at a marker; where the header's own text
    holds the marker too it renders them in the plain way, with the same result."""
    model, report = model_of(SPECS / "allex2.yaml")
    joined = c_header.emit(model, report)
    monkeypatch.setattr(c_header, "_BLOCKS", "#define")  # in every header: each takes the plain way
    assert c_header.emit(model, report) == joined
