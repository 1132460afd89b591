"""CubeMars and MyActuator have no vendor Python package: their profiles' frames are checked against hand
calculations from the published documents, each worked out in the comment beside it.

CubeMars: AK Series Actuator Driver Manual V1.0.8, section 5.3 "MIT power mode communication protocol": the table
"Force control mode drive board receives data definition" (DATA[0..7]: position 16 bits, speed 12, KP 12, KD 12,
current 12, high bits first), the table "MIT power mode driver board sending data definition" (DATA[0] driver ID,
position 16, speed 12, current 12, DATA[6] temperature, DATA[7] error code), and the module range table (AK80-9:
P ±12.5 rad, V ±50 rad/s, T ±18 Nm, KP 0..500, KD 0..5). Packing: x_int = (int)((x - x_min) * (2^bits - 1) / span).

MyActuator: RMD-X V3 servo motor control protocol (CAN): the command tables of 0xA1 torque closed-loop (DATA[4..5]
iqControl int16, 0.01 A/LSB), 0xA2 speed closed-loop (DATA[4..7] speedControl int32, 0.01 dps/LSB), 0xA4 absolute
position (DATA[2..3] maxSpeed uint16 1 dps/LSB, DATA[4..7] angleControl int32 0.01 degree/LSB), their common reply
(DATA[1] temperature int8 1 °C, DATA[2..3] iq int16 0.01 A, DATA[4..5] speed int16 1 dps, DATA[6..7] degree int16
1 degree), and 0x9A read status 1 (DATA[1] temperature, DATA[3] brake, DATA[4..5] voltage uint16 0.1 V, DATA[6..7]
errorState bits); identifiers 0x140 + ID and 0x240 + ID. All little-endian.

The quadruped's leg bus (examples/quadruped_mit.yaml): the bounds of a command and the reply it causes, held as
one transaction (netcfg.timing.can_transactions), worked out from the frame times in the tests' docstrings; and
the simulator's measurements of the same buses inside them.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
import soundness
import yaml
from conftest import ROOT, check_data

from netcfg.devices.actuator_profile import builtin_actuator_profile
from netcfg.runtime.actuators import ActuatorCodec
from netcfg.runtime.codec import CodecError


def _ak(node: int = 1) -> ActuatorCodec:
    return ActuatorCodec(builtin_actuator_profile("cubemars-ak80-9-mit").plain, node_id=node)


@pytest.mark.parametrize(
    ("command", "data"),
    [
        # all zero: p = int(12.5 * 65535 / 25) = 32767 = 0x7FFF; v = int(50 * 4095 / 100) = 2047 = 0x7FF;
        # kp = kd = 0; t = int(18 * 4095 / 36) = 2047 = 0x7FF -> 7F FF | 7F F0 | 00 | 00 07 | FF
        ({"position": 0.0, "velocity": 0.0, "kp": 0.0, "kd": 0.0, "torque": 0.0}, "7FFF7FF0000007FF"),
        # the ranges' ends: p = 65535, v = 0, kp = kd = t = 4095 -> FF FF 00 0F FF FF FF FF
        ({"position": 12.5, "velocity": -50.0, "kp": 500.0, "kd": 5.0, "torque": 18.0}, "FFFF000FFFFFFFFF"),
        # p = int(13.5 * 65535 / 25) = int(35388.9) = 35388 = 0x8A3C; v = 0x7FF; kp = int(50 * 4095 / 500) =
        # int(409.5) = 409 = 0x199; kd = int(4095 / 5) = 819 = 0x333; t = int(16 * 4095 / 36) = 1820 = 0x71C
        # -> 8A 3C | 7F | F1 (v low nibble F, kp high nibble 1) | 99 | 33 | 37 (kd low 3, t high 7) | 1C
        ({"position": 1.0, "velocity": 0.0, "kp": 50.0, "kd": 1.0, "torque": -2.0}, "8A3C7FF19933371C"),
    ],
)
def test_cubemars_mit_command(command: dict[str, float], data: str) -> None:
    frame = _ak(3).encode("mit_command", command)
    assert (frame.arbitration_id, frame.is_extended, frame.data.hex().upper()) == (3, False, data)


def test_cubemars_special_codes_and_reply() -> None:
    codec = _ak(1)
    assert codec.encode("enter_mit").data.hex().upper() == "FFFFFFFFFFFFFFFC"
    assert codec.encode("exit_mit").data.hex().upper() == "FFFFFFFFFFFFFFFD"
    assert codec.encode("set_zero").data.hex().upper() == "FFFFFFFFFFFFFFFE"
    # reply: driver 1, position 0x8000, speed (0x80 << 4 | 0x0) = 0x800, current (0x7 << 8 | 0xFF) = 0x7FF,
    # temperature 0x28, error code 2 (over-current)
    got = codec.decode(0x000, False, bytes.fromhex("01800080" "07FF2802"))
    assert got is not None and got.message == "state"
    assert got.values["position"] == pytest.approx(32768 * 25 / 65535 - 12.5, abs=1e-12)
    assert got.values["velocity"] == pytest.approx(2048 * 100 / 4095 - 50, abs=1e-12)
    assert got.values["torque"] == pytest.approx(2047 * 36 / 4095 - 18, abs=1e-12)
    assert got.values["temperature"] == 40 and got.errors == ("OVER_CURRENT",)
    assert codec.decode(0x000, False, bytes.fromhex("0280008007FF2800")) is None  # driver 2's reply


def test_span_fields_refuse_or_saturate() -> None:
    codec = _ak(1)
    too_far = {"position": 13.0, "velocity": 0.0, "kp": 0.0, "kd": 0.0, "torque": 0.0}
    with pytest.raises(CodecError, match=r"position = 13\.0 is outside"):
        codec.encode("mit_command", too_far)
    assert codec.encode("mit_command", too_far, clamp=True).data[:2] == b"\xff\xff"


def _rmd(node: int = 1) -> ActuatorCodec:
    return ActuatorCodec(builtin_actuator_profile("myactuator-rmd-x8").plain, node_id=node)


@pytest.mark.parametrize(
    ("message", "values", "data"),
    [
        ("torque_command", {"iq": 1.0}, "A100000064000000"),  # 1.00 A = 100 = 0x0064, DATA[4] low byte
        ("torque_command", {"iq": -3.5}, "A1000000A2FE0000"),  # -350 = 0xFEA2
        ("speed_command", {"speed": 100.0}, "A200000010270000"),  # 100 dps = 10000 = 0x00002710
        ("position_command", {"max_speed": 500.0, "angle": 90.0}, "A400F40128230000"),  # 500 = 0x01F4; 9000 = 0x2328
        ("read_status_1", {}, "9A00000000000000"),
        ("motor_stop", {}, "8100000000000000"),
    ],
)
def test_rmd_commands(message: str, values: dict[str, float], data: str) -> None:
    frame = _rmd(1).encode(message, values, units="wire")
    assert (frame.arbitration_id, frame.is_extended, frame.data.hex().upper()) == (0x141, False, data)


def test_rmd_si_units_and_identifiers() -> None:
    # 100 dps given as rad/s: the codec converts back to 10000 counts of 0.01 dps
    assert _rmd(32).encode("speed_command", speed=100 * math.pi / 180).data.hex().upper() == "A200000010270000"
    assert _rmd(32).encode("motor_off").arbitration_id == 0x160


def test_rmd_replies() -> None:
    codec = _rmd(2)
    # A1 reply: temperature 0x32 = 50 °C, iq 0x0064 = 1.00 A, speed 0x01F4 = 500 dps, degree 0x002D = 45°
    got = codec.decode(0x242, False, bytes.fromhex("A1326400F4012D00"), units="wire")
    assert got is not None and got.message == "torque_reply"
    assert got.values == {"temperature": 50, "iq": 1.0, "speed": 500.0, "angle": 45.0}
    # the same bytes after an A4 command are the position reply; SI: 500 dps = 500π/180 rad/s
    got = codec.decode(0x242, False, bytes.fromhex("A4326400F4012D00"))
    assert got is not None and got.message == "position_reply"
    assert got.values["speed"] == pytest.approx(500 * math.pi / 180) and got.values["angle"] == pytest.approx(
        math.pi / 4)
    # 9A: temperature 40 °C, brake released, voltage 0x01E0 = 480 -> 48.0 V, errorState 0x0004: low voltage
    got = codec.decode(0x242, False, bytes.fromhex("9A280001E0010400"))
    assert got is not None and got.message == "status_1"
    assert got.values["voltage"] == pytest.approx(48.0) and got.errors == ("LOW_VOLTAGE",)
    assert got.states == {"brake": "BRAKE_RELEASED"}
    assert codec.decode(0x241, False, bytes.fromhex("A1326400F4012D00")) is None  # motor 1's


QUADRUPED = ROOT / "examples" / "quadruped_mit.yaml"


def quadruped(delay: tuple[int, int]) -> dict[str, Any]:
    """The example with every joint's reply delay measured as [delay[0], delay[1]] us."""
    data: dict[str, Any] = yaml.safe_load(QUADRUPED.read_text(encoding="utf-8"))
    data.setdefault("messages", [])
    for node in data["nodes"]:
        for command in node.get("actuator", {}).get("commands", ()):
            command["reply_delay"] = [f"{delay[0]} us", f"{delay[1]} us"]
    return data


def test_third_reply_on_a_leg_bus_by_hand(tmp_path: Any) -> None:
    """One leg bus of the quadruped, each reply measured within [0 us, 1 us] of its command's end.

    Frames (ISO 11898-1 bit stuffing: after five equal bits one of the other value; an 8-byte standard frame has
    34 + 64 bits that stuffing covers, at worst floor((34 + 64 - 1) / 4) = 24 stuff bits, Davis et al. 2007
    eq. 3): C = 47 + 64 + 24 = 135 bits with the 3-bit intermission, 135 us at 1 Mbit/s; without stuff bits
    C_best = 111 us. The control task (the example: BCET 50 us, WCET 150 us, alone on its processor) queues the
    three commands (ids 0x1-0x3) together as it ends: their nominal release is its BCET, their jitter
    J_c = 150 - 50 = 100 us. The replies are 0x11-0x13, below every command.

    Commands (Davis et al. 2007, eqs. 5, 12, 13; a lower-priority frame, a reply, may have just begun:
    B = 135 us): R_c1 = J_c + B + C = 370, R_c2 = 505, R_c3 = 640 us.

    Replies, as transactions with their commands (Palencia and Gonzalez Harbour 1998, WCDO): the offset of reply
    i is its command's earliest end, phi = C_best + 0 = 111 us after the commands' nominal release; its jitter
    the rest up to its command's worst end plus the longest delay: J_r3 = 640 + 1 - 111 = 530 us. The worst
    case starts with the commands at their latest release (100 us): they go back to back, 100 + 3 C = 505 us;
    each reply is queued by then (its command's end + at most 1 us) and waits for them; the replies follow in
    identifier order: r1 ends 640, r2 775, r3 910 us. From its nominal release at 111 us:

        R_r3 = 910 - 111 = 799 us
        R_r2 = 775 - 111 + 135 = 799 us      (r3 may block it: the analysis grants one lower frame, B = C)
        R_r1 = 640 - 111 + 135 = 664 us

    The bus's +-100 ppm clocks (clock_tolerance's default, netcfg.timing.clocks) let the 111 us between the
    commands' release and the replies' offset be as short as 111 000 - ceil(111 000 * 100 / 10^6) = 110 988 ns:
    each bound is 12 ns more. The holistic analysis alone gives r3 its command's whole response range and the
    delay as jitter (530 us) and every command again at any phase: its bound is not the one kept."""
    report = check_data(tmp_path, quadruped((0, 1)))
    assert report["ok"], report["errors"]
    c, c_best, tau = 135, 111, 1
    assert c == 47 + 64 + (34 + 64 - 1) // 4 and c_best == 47 + 64 and (55 + 10 * 8) * tau == c
    j_c, b = 150 - 50, c
    r_cmd = [j_c + b + k * c for k in (1, 2, 3)]
    end_cmds = j_c + 3 * c
    ends = [end_cmds + k * c for k in (1, 2, 3)]
    clock = (111_000 * 100 + 10**6 - 1) // 10**6 / 1000  # us: the offset taken short by the clocks' tolerance
    expected = {"hip_mit_command": r_cmd[0], "thigh_mit_command": r_cmd[1], "knee_mit_command": r_cmd[2],
                "hip_feedback": ends[0] - c_best + b + clock, "thigh_feedback": ends[1] - c_best + b + clock,
                "knee_feedback": ends[2] - c_best + clock}
    assert expected["knee_feedback"] == pytest.approx(799.012) and expected["hip_feedback"] == pytest.approx(664.012)
    for bus in report["buses"]:
        leg = bus["name"].split("_")[0]
        got = {r["name"].removeprefix(f"{leg}_"): r["wcrt_us"] for r in bus["messages"]}
        assert got == pytest.approx(expected, abs=1e-3)
        assert max(got.values()) < 1000  # every reply inside the 1 ms cycle: check accepts the spec


def test_the_assumed_reply_delay_puts_the_knee_reply_past_the_cycle(tmp_path: Any) -> None:
    """With the profile's assumed 0..500 us reply delay (the example as written) the knee's reply may be queued
    640 + 500 = 1140 us after the commands' nominal release, past the next cycle's commands (1000 us, of higher
    priority): measured from its nominal release (111 us) it ends no sooner than 1140 + C - 111 = 1164 us, past
    the 1 ms deadline whatever the analysis. With a measured delay of at most 336 us every reply fits."""
    report = check_data(tmp_path, yaml.safe_load(QUADRUPED.read_text(encoding="utf-8")))
    knee = {r["name"]: r["wcrt_us"] for r in report["buses"][0]["messages"]}["fl_knee_feedback"]
    assert knee >= 640 + 500 + 135 - 111 > 1000
    assert check_data(tmp_path, quadruped((0, 336)))["ok"]
    assert not check_data(tmp_path, quadruped((0, 337)))["ok"]
    # at 500 Hz (the Mini Cheetah's command rate, the example's header) the six 135-bit frames take 810 us of every
    # 2 ms, 40.5 %, and the assumed delay fits: the knee's reply is queued by 640 + 500 us, before the next commands
    text = QUADRUPED.read_text(encoding="utf-8").replace("rate: 1 kHz", "rate: 500 Hz")
    text = text.replace("period: 1 ms, bcet", "period: 2 ms, bcet")
    text = text.replace("period: 1 ms, offset: 900 us", "period: 2 ms, offset: 1900 us")
    report = check_data(tmp_path, yaml.safe_load(text))
    assert report["ok"], report["errors"]
    assert [b["utilization"] for b in report["buses"]] == pytest.approx([6 * 135 / 2000] * 4)


@pytest.mark.parametrize("delay", [(0, 1), (10, 50), (0, 300)])
def test_quadruped_simulated_inside_the_transaction_bounds(delay: tuple[int, int]) -> None:
    """The simulator (random phases and drift, and the critical instant: every clock at 0) measures every
    command and reply of the four leg buses inside the bounds check gives them (soundness.check_spec holds each
    figure to its bound); a reply is measured from its command's frame, as verify does."""
    out = soundness.check_spec(quadruped(delay), seed=1, duration_ns=500_000_000)
    assert out.accepted and out.violations == [], out.violations
    replies = [ratio for name, ratio in out.tightness.items() if name.endswith("_feedback")]
    assert len(replies) == 12 and 0 < max(replies) <= 1
