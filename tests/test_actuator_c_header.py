"""The C header of an actuator bus against the vendor's own code, byte for byte: examples/arm_damiao.yaml's
controller.h, compiled with gcc -std=c99 -Wall -Wextra -Wpedantic -Werror, packs 1,000 random in-range MIT
commands as damiao-motor's DaMiaoMotor.send_cmd_mit sends them (and as netcfg's Python codec encodes them), and
reads 1,000 random feedback frames as its decode_sensor_feedback does.

The MIT packing is damiao-motor's float_to_uint, raw = int((x - lo) * (2^bits - 1) / (hi - lo)), truncated, in
binary64; its reading uint_to_float, raw * (hi - lo) / (2^bits - 1) + lo. The header's setters and getters of
MIT-packed signals compute the same operations in the same order (a DBC factor cannot say the truncation: a
rounding setter lands one count above for about half the values). Ranges: the DM-J4310's, position +-12.5 rad,
velocity +-30 rad/s, torque +-10 Nm, kp 0..500, kd 0..5 (the profile's defaults, damiao-motor's "4310" preset).
"""

from __future__ import annotations

import random
import shutil
import subprocess
from pathlib import Path

import damiao_motor.core.motor as dm
import pytest
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
            int i;
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
            for (i = 0; i < MSG_SHOULDER_MIT_COMMAND_SIZE; i++) {
                printf("%02x", d[i]);
            }
            printf("\n");
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


@pytest.fixture(scope="module")
def driver(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if shutil.which("gcc") is None:
        pytest.skip("gcc is not installed")
    out = tmp_path_factory.mktemp("arm_damiao")
    proc = cli("build", str(ROOT / "examples" / "arm_damiao.yaml"), "-o", str(out / "build"))
    assert proc.returncode == 0, proc.stderr
    (out / "driver.c").write_text(DRIVER)
    exe = out / "driver"
    gcc = subprocess.run([*GCC, "-I", str(out / "build" / "c"), str(out / "driver.c"), "-o", str(exe)],
                         capture_output=True, text=True)
    assert gcc.returncode == 0, gcc.stderr
    return exe


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
