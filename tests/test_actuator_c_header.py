"""The C header of an actuator bus against the vendor's own code, byte for byte: examples/arm_damiao.yaml's
controller.h, compiled with gcc -std=c99 -Wall -Wextra -Wpedantic -Werror, packs 1,000 random in-range MIT
commands as damiao-motor's DaMiaoMotor.send_cmd_mit sends them (and as netcfg's Python codec encodes them), and
reads 1,000 random feedback frames as its decode_sensor_feedback does. An ODrive axis's host.h packs 1,000 random
Set_Input_Pos and Set_Input_Vel commands as cantools encodes them with odrive-can's own
odrive-cansimple-0.6.10.dbc (its Vel_FF and Torque_FF are int16 at factor 0.001: the header rounds half to even as
cantools and the Python codec do).

The MIT packing is damiao-motor's float_to_uint, raw = int((x - lo) * (2^bits - 1) / (hi - lo)), truncated, in
binary64; its reading uint_to_float, raw * (hi - lo) / (2^bits - 1) + lo. The header's setters and getters of
MIT-packed signals compute the same operations in the same order (a DBC factor cannot say the truncation: a
rounding setter lands one count above for about half the values). Ranges: the DM-J4310's, position +-12.5 rad,
velocity +-30 rad/s, torque +-10 Nm, kp 0..500, kd 0..5 (the profile's defaults, damiao-motor's "4310" preset).
"""

from __future__ import annotations

import math
import random
import shutil
import struct
import subprocess
from pathlib import Path

import cantools
import damiao_motor.core.motor as dm
import odrive_can
import pytest
import yaml
from conftest import ROOT, cli
from test_actuator_vendors import CaptureBus, N

from netcfg.devices.actuator_profile import builtin_actuator_profile
from netcfg.runtime.actuators import ActuatorCodec

GCC = ["gcc", "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-O2"]

DRIVER = r"""
#define NETCFG_FLOAT_ACCESSORS
#include "controller.h"
#include <stdio.h>

/* "c P V KP KD T": the shoulder's MIT command packed, in hex, or "refused";
   "f HEX": the shoulder's feedback frame read back, its position, velocity and torque */
int main(void)
{
    char kind;
    while (scanf(" %c", &kind) == 1) {
        if (kind == 'c') {
            double p, v, kp, kd, t;
            struct msg_shoulder_mit_command c;
            uint8_t d[MSG_SHOULDER_MIT_COMMAND_SIZE];
            if (scanf("%lf %lf %lf %lf %lf", &p, &v, &kp, &kd, &t) != 5) {
                return 2;
            }
            memset(&c, 0, sizeof c);
            memset(d, 0, sizeof d);
            if (!(msg_shoulder_mit_command_position_set(&c, p) && msg_shoulder_mit_command_velocity_set(&c, v)
                  && msg_shoulder_mit_command_kp_set(&c, kp) && msg_shoulder_mit_command_kd_set(&c, kd)
                  && msg_shoulder_mit_command_torque_set(&c, t) && msg_shoulder_mit_command_pack(d, &c))) {
                printf("refused\n");
                continue;
            }
            print_frame(d, MSG_SHOULDER_MIT_COMMAND_SIZE);
        } else {
            unsigned int b[MSG_SHOULDER_FEEDBACK_SIZE];
            uint8_t d[MSG_SHOULDER_FEEDBACK_SIZE];
            struct msg_shoulder_feedback f;
            int i;
            for (i = 0; i < MSG_SHOULDER_FEEDBACK_SIZE; i++) {
                if (scanf("%2x", &b[i]) != 1) {
                    return 2;
                }
                d[i] = (uint8_t)b[i];
            }
            msg_shoulder_feedback_unpack(&f, d);
            printf("%.17g %.17g %.17g\n", msg_shoulder_feedback_position_get(&f),
                   msg_shoulder_feedback_velocity_get(&f), msg_shoulder_feedback_torque_get(&f));
        }
    }
    return 0;
}
"""


# what every driver prints: a packed frame, in hex, on a line of its own
PRINT_FRAME = r"""
#include <stdint.h>
#include <stdio.h>

static void print_frame(const uint8_t *d, int n)
{
    int i;
    for (i = 0; i < n; i++) {
        printf("%02x", d[i]);
    }
    printf("\n");
}
"""


def compiled(folder: Path, spec: Path, source: str) -> Path:
    """`netcfg build` of the spec into folder, and the driver `source` (after PRINT_FRAME) compiled against its C
    headers."""
    if shutil.which("gcc") is None:
        pytest.skip("gcc is not installed")
    proc = cli("build", str(spec), "-o", str(folder / "build"))
    assert proc.returncode == 0, proc.stderr
    (folder / "driver.c").write_text(PRINT_FRAME + source)
    exe = folder / "driver"
    gcc = subprocess.run([*GCC, "-I", str(folder / "build" / "c"), str(folder / "driver.c"), "-o", str(exe)],
                         capture_output=True, text=True)
    assert gcc.returncode == 0, gcc.stderr
    return exe


@pytest.fixture(scope="module")
def driver(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return compiled(tmp_path_factory.mktemp("arm_damiao"), ROOT / "examples" / "arm_damiao.yaml", DRIVER)


def run(exe: Path, lines: list[str]) -> list[str]:
    proc = subprocess.run([str(exe)], input="\n".join(lines) + "\n", capture_output=True, text=True, check=True)
    return proc.stdout.splitlines()


def test_the_header_packs_mit_commands_as_damiao_motor(driver: Path) -> None:
    plain = builtin_actuator_profile("damiao-dm-j4310").plain
    codec = ActuatorCodec(plain, node_id=1, master_id=0x11)
    rng = random.Random(4310)
    commands = [(rng.uniform(-12.5, 12.5), rng.uniform(-30, 30), rng.uniform(0, 500), rng.uniform(0, 5),
                 rng.uniform(-10, 10)) for _ in range(N)]
    ours = run(driver, [f"c {' '.join(map(repr, c))}" for c in commands])
    assert len(ours) == N
    for (p, v, kp, kd, t), c_hex in zip(commands, ours, strict=True):
        bus = CaptureBus()
        dm.DaMiaoMotor(1, 0x11, bus, motor_type="4310").send_cmd_mit(  # type: ignore[arg-type]
            target_position=p, target_velocity=v, stiffness=kp, damping=kd, feedforward_torque=t)
        (theirs,) = bus.sent
        python = codec.encode("mit_command", position=p, velocity=v, kp=kp, kd=kd, torque=t)
        assert c_hex == bytes(theirs.data).hex() == python.data.hex(), (p, v, kp, kd, t)


def test_the_header_refuses_a_command_out_of_range(driver: Path) -> None:
    """The setters take [lo, hi] and nothing beyond it (damiao-motor clamps, netcfg's codec raises unless told to
    clamp). By hand, 12.5 rad at rest: position int(25 * 65535 / 25) = 0xFFFF, velocity int(30 * 4095 / 60) =
    0x7FF, kp and kd 0, torque int(10 * 4095 / 20) = 0x7FF, laid out FF FF | 7F F0 | 00 | 00 07 | FF (Damiao's
    MIT frame: position 16 bits, velocity 12, kp 12, kd 12, torque 12, big-endian); 12.6 rad is refused."""
    assert run(driver, ["c 12.5 0 0 0 0", "c 12.6 0 0 0 0", "c nan 0 0 0 0"]) == ["ffff7ff0000007ff", "refused",
                                                                                "refused"]


def test_the_header_reads_feedback_as_damiao_motor(driver: Path) -> None:
    rng = random.Random(4311)
    frames = [bytes([1, *rng.randbytes(7)]) for _ in range(N)]  # status 0 (disabled), node id 1
    ours = run(driver, [f"f {data.hex()}" for data in frames])
    for data, line in zip(frames, ours, strict=True):
        theirs = dm.DaMiaoMotor(1, 0x11, CaptureBus(), motor_type="4310").decode_sensor_feedback(  # type: ignore[arg-type]
            data)
        assert [float(x) for x in line.split()] == [theirs["pos"], theirs["vel"], theirs["torq"]], data.hex()


ODRIVE_DRIVER = r"""
#define NETCFG_FLOAT_ACCESSORS
#include "host.h"
#include <stdio.h>

/* "p POS VEL_FF TORQUE_FF": Set_Input_Pos; "v VEL TORQUE_FF": Set_Input_Vel; packed, in hex, or "refused" */
int main(void)
{
    char kind;
    while (scanf(" %c", &kind) == 1) {
        double a, b, c;
        if (kind == 'p') {
            struct msg_axis_set_input_pos m;
            uint8_t d[MSG_AXIS_SET_INPUT_POS_SIZE];
            if (scanf("%lf %lf %lf", &a, &b, &c) != 3) {
                return 2;
            }
            memset(&m, 0, sizeof m);
            m.input_pos = (float)a;
            if (!(msg_axis_set_input_pos_vel_ff_set(&m, b) && msg_axis_set_input_pos_torque_ff_set(&m, c)
                  && msg_axis_set_input_pos_pack(d, &m))) {
                printf("refused\n");
                continue;
            }
            print_frame(d, MSG_AXIS_SET_INPUT_POS_SIZE);
        } else {
            struct msg_axis_set_input_vel m;
            uint8_t d[MSG_AXIS_SET_INPUT_VEL_SIZE];
            if (scanf("%lf %lf", &a, &b) != 2) {
                return 2;
            }
            m.input_vel = (float)a;
            m.input_torque_ff = (float)b;
            if (!msg_axis_set_input_vel_pack(d, &m)) {
                printf("refused\n");
                continue;
            }
            print_frame(d, MSG_AXIS_SET_INPUT_VEL_SIZE);
        }
    }
    return 0;
}
"""


def odrive_spec(node: int) -> dict[str, object]:
    axis = {"name": "axis", "node_id": node, "buses": ["can0"], "device": "odrive-cansimple",
            "actuator": {"commands": [{"message": "set_input_pos", "rate": "100 Hz"},
                                      {"message": "set_input_vel", "rate": "100 Hz"}]}}
    return {"system": "odrive_c", "buses": [{"name": "can0", "protocol": "can", "bitrate": "1 Mbit/s"}],
            "nodes": [{"name": "host", "role": "master", "buses": ["can0"]}, axis]}


def test_the_header_packs_odrive_commands_as_the_vendor_dbc(tmp_path: Path) -> None:
    node = 3
    spec = tmp_path / "odrive.yaml"
    spec.write_text(yaml.safe_dump(odrive_spec(node), sort_keys=False))
    exe = compiled(tmp_path, spec, ODRIVE_DRIVER)
    db = cantools.database.load_file(str(Path(odrive_can.__file__).parent / "dbc" / "odrive-cansimple-0.6.10.dbc"))
    assert isinstance(db, cantools.database.can.Database)
    pos, vel = db.get_message_by_name(f"Axis{node}_Set_Input_Pos"), db.get_message_by_name(f"Axis{node}_Set_Input_Vel")
    rng = random.Random(37)
    lines, theirs = [], []
    for i in range(N):
        a, b, c = rng.uniform(-100, 100), rng.uniform(-32.7, 32.7), rng.uniform(-32.7, 32.7)  # int16 * 0.001: +-32.767
        a32 = struct.unpack("<f", struct.pack("<f", a))[0]  # the float the frame carries
        if i % 2 == 0:
            lines.append(f"p {a!r} {b!r} {c!r}")
            theirs.append(pos.encode({"Input_Pos": a32, "Vel_FF": b, "Torque_FF": c}).hex())
        else:
            b32 = struct.unpack("<f", struct.pack("<f", b))[0]
            lines.append(f"v {a!r} {b!r}")
            theirs.append(vel.encode({"Input_Vel": a32, "Input_Torque_FF": b32}).hex())
    assert run(exe, lines) == theirs


MOTEUS_DRIVER = r"""
#include "host.h"
#include <stdio.h>

/* "POS VEL FF_TORQUE KP_SCALE KD_SCALE MAX_TORQUE" (the profile's units, revolutions): the position command with
   its query, packed as one CAN FD frame, in hex, or "refused" */
int main(void)
{
    double x[6];
    while (scanf("%lf %lf %lf %lf %lf %lf", &x[0], &x[1], &x[2], &x[3], &x[4], &x[5]) == 6) {
        struct msg_joint_position_query m;
        uint8_t d[MSG_JOINT_POSITION_QUERY_FRAME_SIZE];
        m.position = (float)x[0];
        m.velocity = (float)x[1];
        m.feedforward_torque = (float)x[2];
        m.kp_scale = (float)x[3];
        m.kd_scale = (float)x[4];
        m.maximum_torque = (float)x[5];
        if (!msg_joint_position_query_pack(d, &m)) {
            printf("refused\n");
            continue;
        }
        print_frame(d, MSG_JOINT_POSITION_QUERY_FRAME_SIZE);
    }
    return 0;
}
"""


def test_the_header_packs_moteus_position_commands_as_moteus(tmp_path: Path) -> None:
    """moteus's register subframes (write the mode, write six float32 registers from 0x020, read back) are constant
    fields of the profile's message and its padding 0x50 the protocol's no-op: the header's pack starts from that
    frame and writes the six floats into it, as moteus's Controller.make_position(query=True) frames it."""
    import moteus
    from test_actuator_vendors import _moteus_frame

    node, host = 1, 0
    joint = {"name": "joint", "node_id": node, "buses": ["fd0"], "device": "moteus",
             "actuator": {"commands": [{"message": "position_query", "rate": "100 Hz"}]}}
    spec = tmp_path / "moteus.yaml"
    spec.write_text(yaml.safe_dump({
        "system": "moteus_c",
        "buses": [{"name": "fd0", "protocol": "can-fd", "bitrate": "1 Mbit/s", "data_bitrate": "5 Mbit/s"}],
        "nodes": [{"name": "host", "role": "master", "buses": ["fd0"]}, joint]}, sort_keys=False))
    exe = compiled(tmp_path, spec, MOTEUS_DRIVER)
    rng = random.Random(4)
    lines, theirs = [], []
    for i in range(N):
        x = [rng.uniform(-100, 100) if i % 20 else math.nan, rng.uniform(-50, 50), rng.uniform(-20, 20),
             rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0, 30)]  # NaN: hold the present position
        lines.append(" ".join(repr(v) for v in x))
        cmd = moteus.Controller(id=node, source_can_id=host).make_position(
            position=x[0], velocity=x[1], feedforward_torque=x[2], kp_scale=x[3], kd_scale=x[4],
            maximum_torque=x[5], query=True)
        theirs.append(_moteus_frame(cmd)[2].hex())
    assert run(exe, lines) == theirs


RMD_DRIVER = r"""
#define NETCFG_FLOAT_ACCESSORS
#include "host.h"
#include <stdio.h>

/* "MAX_SPEED ANGLE" (deg/s, an integer; deg): the RMD-X position command (0xA4) packed, in hex, or "refused" */
int main(void)
{
    unsigned int speed;
    double angle;
    while (scanf("%u %lf", &speed, &angle) == 2) {
        struct msg_joint_position_command m;
        uint8_t d[MSG_JOINT_POSITION_COMMAND_SIZE];
        m.max_speed = (uint16_t)speed;
        if (!(msg_joint_position_command_angle_set(&m, angle) && msg_joint_position_command_pack(d, &m))) {
            printf("refused\n");
            continue;
        }
        print_frame(d, MSG_JOINT_POSITION_COMMAND_SIZE);
    }
    return 0;
}
"""


def test_the_header_writes_an_rmd_command_code(tmp_path: Path) -> None:
    """MyActuator RMD-X V3 (the protocol document the profile names): the absolute position command is 0xA4 in
    byte 0, maxSpeed uint16 in bytes 2-3 (1 dps/LSB), angleControl int32 in bytes 4-7 (0.01 degree/LSB), little-endian.
    By hand, 500 dps to 90.00 degrees: A4 00 F4 01 28 23 00 00 (500 = 0x01F4, 9000 = 0x2328). No vendor package
    is among the dependencies, so 1,000 random commands are held against netcfg's Python codec, in the document's
    units."""
    joint = {"name": "joint", "node_id": 1, "buses": ["can0"], "device": "myactuator-rmd-x8",
             "actuator": {"commands": [{"message": "position_command", "rate": "100 Hz"}]}}
    spec = tmp_path / "rmd.yaml"
    spec.write_text(yaml.safe_dump({
        "system": "rmd_c", "buses": [{"name": "can0", "protocol": "can", "bitrate": "1 Mbit/s"}],
        "nodes": [{"name": "host", "role": "master", "buses": ["can0"]}, joint]}, sort_keys=False))
    exe = compiled(tmp_path, spec, RMD_DRIVER)
    assert run(exe, ["500 90"]) == ["a400f40128230000"]
    codec = ActuatorCodec(builtin_actuator_profile("myactuator-rmd-x8").plain, node_id=1)
    rng = random.Random(8)
    commands = [(rng.randrange(0, 65536), rng.randrange(-36_000_000, 36_000_000) / 100) for _ in range(N)]
    ours = run(exe, [f"{s} {a!r}" for s, a in commands])
    assert ours == [codec.encode("position_command", max_speed=s, angle=a, units="wire").data.hex()
                    for s, a in commands]
