"""The actuator codecs against the vendors' own code, byte for byte: ODrive's DBC (shipped in odrive-can) through
cantools, damiao-motor's encoder and decoder, moteus' own frame builder and parser, and robstride's client.

Each comparison draws 1,000 seeded random in-range commands (and as many replies), encodes them with netcfg's codec
and with the vendor's code, and compares identifiers, frame formats and payload bytes; replies are decoded both ways.
Values are drawn in SI units; a vendor taking revolutions is given the SI value divided by 2π, the conversion the
codec makes, so the two see the same number. No vendor package needs hardware here: each builds its frames before
handing them to a bus, which is a capture object (or moteus' Transport with no device) in these tests.
"""

from __future__ import annotations

import io
import math
import random
import struct
from pathlib import Path
from typing import Any

import can
import cantools
import damiao_motor.core.motor as dm
import moteus
import moteus.multiplex as mp
import odrive_can
import pytest
import robstride.client as rs
from moteus.protocol import Register, Writer, parse_registers
from moteus.transport_device import TransportDevice

from netcfg.devices.actuator_profile import builtin_actuator_profile
from netcfg.runtime.actuators import ActuatorCodec

N = 1000
TURN = 2 * math.pi  # rad per revolution: the vendors' unit of position for ODrive and moteus
# SI per vendor unit, for the units the ODrive DBC uses with revolutions in them
PER_TURN = {"rev": TURN, "rev/s": TURN, "rev/s^2": TURN, "Nm/(rev/s)": 1 / TURN, "Nm/rev": 1 / TURN,
            "Nm/(rev/s^2)": 1 / TURN}


class CaptureBus:
    """A python-can bus stand-in: keeps what the vendor's driver sends and answers recv() from a queue."""

    def __init__(self) -> None:
        self.sent: list[can.Message] = []
        self.replies: list[can.Message] = []

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.sent.append(msg)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        return self.replies.pop(0) if self.replies else None


# -- ODrive: the DBC the vendor ships, read by cantools
@pytest.fixture(scope="module")
def odrive_dbc() -> cantools.database.can.Database:
    path = Path(odrive_can.__file__).parent / "dbc" / "odrive-cansimple-0.6.10.dbc"
    return cantools.database.load_file(str(path))


def _dbc_message(db: cantools.database.can.Database, node: int, name: str) -> Any:
    wanted = f"axis{node}_{name}"
    return next(m for m in db.messages if m.name.lower() == wanted)


def _signal(msg: Any, field: str) -> Any:
    return next(s for s in msg.signals if s.name.lower() == field)


def test_odrive_profile_is_the_dbc(odrive_dbc: Any) -> None:
    """Every payload message of the profile is the DBC's message of that name: identifier, length, and each field's
    start bit, width, byte order, signedness, float type and scaling."""
    plain = builtin_actuator_profile("odrive-cansimple").plain
    checked = 0
    for m in plain["messages"]:
        if m.get("remote"):
            continue
        for node in (0, 5):
            dbc = _dbc_message(odrive_dbc, node, m["name"])
            codec = ActuatorCodec(plain, node_id=node).message(m["name"])
            assert codec.base_id == dbc.frame_id and not dbc.is_extended_frame
            assert m["size"] == dbc.length, m["name"]
            assert {f["name"] for f in m["fields"]} == {s.name.lower() for s in dbc.signals}, m["name"]
            for f in m["fields"]:
                s = _signal(dbc, f["name"])
                assert (s.start, s.length, s.byte_order) == (f["start_bit"], f["bits"], "little_endian")
                assert s.is_float == (f["type"] == "float") and s.is_signed == (f["type"] == "signed")
                assert (s.scale, s.offset) == (f.get("scale", 1.0), f.get("offset", 0.0))
            checked += 1
    assert checked == 2 * 24


def _odrive_random(rng: random.Random, field: dict[str, Any]) -> tuple[Any, Any]:
    """(SI value for netcfg, the same value in the DBC's unit for cantools)."""
    factor = PER_TURN.get(field["unit"], 1.0)
    if field["type"] == "float":
        si = rng.uniform(-1e3, 1e3)
    elif field["type"] == "signed":
        top = (2 ** (field["bits"] - 1) - 1) * field.get("scale", 1.0)
        si = rng.uniform(-top, top) * factor
    else:
        choices = [raw for raw, _ in field.get("choices", [])]
        return (v := rng.choice(choices) if choices else rng.randrange(2 ** field["bits"])), v
    return si, si / factor if factor != 1.0 else si


def test_odrive_commands_byte_for_byte(odrive_dbc: Any) -> None:
    plain = builtin_actuator_profile("odrive-cansimple").plain
    commands = [m for m in plain["messages"] if m["from"] == "host" and not m.get("remote") and m["fields"]]
    rng = random.Random(37)
    for _ in range(N):
        m = rng.choice(commands)
        node = rng.randrange(8)  # the DBC's axes
        values, vendor = {}, {}
        for f in m["fields"]:
            values[f["name"]], vendor[_signal(_dbc_message(odrive_dbc, node, m["name"]), f["name"]).name] = (
                _odrive_random(rng, f))
        ours = ActuatorCodec(plain, node_id=node).encode(m["name"], values)
        dbc = _dbc_message(odrive_dbc, node, m["name"])
        assert (ours.arbitration_id, ours.is_extended, ours.fd) == (dbc.frame_id, False, False)
        assert ours.data == dbc.encode(vendor, scaling=True, padding=False, strict=True), (m["name"], values)


def test_odrive_replies_both_ways(odrive_dbc: Any) -> None:
    plain = builtin_actuator_profile("odrive-cansimple").plain
    device = [m for m in plain["messages"] if m["from"] == "device"]
    rng = random.Random(38)
    for _ in range(N):
        m = rng.choice(device)
        node = rng.randrange(8)
        dbc = _dbc_message(odrive_dbc, node, m["name"])
        vendor = {}
        for f in m["fields"]:
            if f["type"] == "float":
                vendor[_signal(dbc, f["name"]).name] = struct.unpack("<f", struct.pack("<f", rng.uniform(-1e3, 1e3)))[0]
            else:
                vendor[_signal(dbc, f["name"]).name] = rng.randrange(2 ** f["bits"])
        data = dbc.encode(vendor, strict=False)
        got = ActuatorCodec(plain, node_id=node).decode(dbc.frame_id, False, data)
        assert got is not None and got.message == m["name"]
        theirs = dbc.decode(data, decode_choices=False)
        for f in m["fields"]:
            factor = PER_TURN.get(f["unit"], 1.0)
            want = theirs[_signal(dbc, f["name"]).name]
            assert got.values[f["name"]] == (want * factor if factor != 1.0 else want), (m["name"], f["name"])
        assert got == ActuatorCodec(plain, node_id=node).decode(dbc.frame_id, False, data)  # the codec is stateless
        # netcfg's own encoding of the device frame (the simulator's) is what cantools reads back
        assert ActuatorCodec(plain, node_id=node).encode(m["name"], got.values).data == data


def test_odrive_heartbeat_errors_and_state(odrive_dbc: Any) -> None:
    dbc = _dbc_message(odrive_dbc, 3, "heartbeat")
    data = dbc.encode({"Axis_Error": 0x01001000, "Axis_State": 8, "Procedure_Result": 0, "Trajectory_Done_Flag": 1})
    got = ActuatorCodec(builtin_actuator_profile("odrive-cansimple").plain, node_id=3).decode(dbc.frame_id, False, data)
    assert got is not None
    assert got.errors == ("CURRENT_LIMIT_VIOLATION", "WATCHDOG_TIMER_EXPIRED")
    assert got.states == {"axis_state": "CLOSED_LOOP_CONTROL", "procedure_result": "SUCCESS"}
    # the names are the DBC's own value table
    table = _signal(dbc, "axis_error").choices
    assert {str(table[1 << 12]), str(table[1 << 24])} == set(got.errors)


# -- Damiao: damiao-motor's DaMiaoMotor, its frames captured from a stand-in bus
def _damiao(node: int, bus: CaptureBus, motor_type: str = "4310") -> dm.DaMiaoMotor:
    return dm.DaMiaoMotor(node, 0x00, bus, motor_type=motor_type)  # type: ignore[arg-type]


@pytest.mark.parametrize("motor_type", ["4310", "4340"])
def test_damiao_mit_commands_byte_for_byte(motor_type: str) -> None:
    """send_cmd_mit (through encode_cmd_msg), send_cmd_pos_vel and send_cmd_vel against the profile; DM-J4340's
    ranges are the profile's parameters p_max/v_max/t_max set as its registers would be."""
    plain = builtin_actuator_profile("damiao-dm-j4310").plain
    preset = dm.MOTOR_TYPE_PRESETS[motor_type]
    limits = {"p_max": preset["p_max"], "v_max": preset["v_max"], "t_max": preset["t_max"]}
    rng = random.Random(310)
    for i in range(N):
        node = rng.randrange(1, 16)
        bus = CaptureBus()
        motor = _damiao(node, bus, motor_type)
        codec = ActuatorCodec(plain, node_id=node, **limits)
        pos, vel = rng.uniform(-limits["p_max"], limits["p_max"]), rng.uniform(-limits["v_max"], limits["v_max"])
        kp, kd, torque = rng.uniform(0, 500), rng.uniform(0, 5), rng.uniform(-limits["t_max"], limits["t_max"])
        kind = i % 3
        if kind == 0:
            motor.send_cmd_mit(target_position=pos, target_velocity=vel, stiffness=kp, damping=kd,
                               feedforward_torque=torque)
            ours = codec.encode("mit_command", position=pos, velocity=vel, kp=kp, kd=kd, torque=torque)
        elif kind == 1:
            motor.send_cmd_pos_vel(target_position=pos, velocity_limit=abs(vel))
            ours = codec.encode("pos_vel_command", position=pos, velocity_limit=abs(vel))
        else:
            motor.send_cmd_vel(target_velocity=vel)
            ours = codec.encode("vel_command", velocity=vel)
        (sent,) = bus.sent
        assert (ours.arbitration_id, ours.is_extended, bytes(sent.data)) == (
            sent.arbitration_id, sent.is_extended_id, ours.data), (kind, pos, vel, kp, kd, torque)


def test_damiao_special_frames() -> None:
    plain = builtin_actuator_profile("damiao-dm-j4310").plain
    codec = ActuatorCodec(plain, node_id=4)
    for ours, call in (("enable", "enable"), ("disable", "disable"), ("save_zero", "set_zero_position"),
                       ("clear_error", "clear_error")):
        bus = CaptureBus()
        getattr(_damiao(4, bus), call)()
        frame = codec.encode(ours)
        assert (frame.arbitration_id, frame.data) == (bus.sent[0].arbitration_id, bytes(bus.sent[0].data))


def test_damiao_feedback_both_ways() -> None:
    plain = builtin_actuator_profile("damiao-dm-j4310").plain
    rng = random.Random(311)
    statuses = list(dm._STATE_NAME_MAP)
    for _ in range(N):
        node, master = rng.randrange(1, 16), rng.randrange(0x7FF)
        data = bytes([rng.choice(statuses) << 4 | node, *rng.randbytes(7)])
        theirs = _damiao(node, CaptureBus()).decode_sensor_feedback(data)
        got = ActuatorCodec(plain, node_id=node, master_id=master).decode(master, False, data)
        assert got is not None and got.message == "feedback"
        assert (got.values["position"], got.values["velocity"], got.values["torque"]) == (
            theirs["pos"], theirs["vel"], theirs["torq"])
        assert (got.values["t_mos"], got.values["t_rotor"]) == (theirs["t_mos"], theirs["t_rotor"])
        assert got.states["status"] == theirs["status"]
        assert bool(got.errors) == (theirs["status_code"] >= 8)
        # another motor's feedback on the same master id is not this one's
        assert ActuatorCodec(plain, node_id=node % 15 + 1, master_id=master).decode(master, False, data) is None


# -- moteus: Controller.make_position / make_query / make_stop and its Transport's frame, parse_registers for replies
def _moteus_frame(cmd: Any) -> tuple[int, bool, bytes]:
    frame = moteus.Transport([])._command_to_frame(cmd)
    size = TransportDevice._round_up_dlc(None, len(frame.data))  # type: ignore[arg-type]
    return frame.arbitration_id, frame.is_extended_id, bytes(frame.data) + b"\x50" * (size - len(frame.data))


def test_moteus_position_commands_byte_for_byte() -> None:
    plain = builtin_actuator_profile("moteus").plain
    rng = random.Random(4)
    names = ("position", "velocity", "feedforward_torque", "kp_scale", "kd_scale", "maximum_torque")
    for i in range(N):
        node, host = rng.randrange(1, 128), rng.randrange(0, 128)
        si = {"position": rng.uniform(-100, 100) * TURN if i % 20 else math.nan,  # NaN: hold the present position
              "velocity": rng.uniform(-50, 50) * TURN, "feedforward_torque": rng.uniform(-20, 20),
              "kp_scale": rng.uniform(0, 1), "kd_scale": rng.uniform(0, 1), "maximum_torque": rng.uniform(0, 30)}
        vendor = {k: si[k] / TURN if k in ("position", "velocity") else si[k] for k in names}
        cmd = moteus.Controller(id=node, source_can_id=host).make_position(**vendor, query=True)
        ours = ActuatorCodec(plain, node_id=node, host_id=host).encode("position_query", si)
        assert (ours.arbitration_id, ours.is_extended, ours.data) == _moteus_frame(cmd)
        assert ours.fd and ours.brs


def test_moteus_query_and_stop() -> None:
    plain = builtin_actuator_profile("moteus").plain
    for node, host in ((1, 0), (127, 5), (42, 127)):
        controller = moteus.Controller(id=node, source_can_id=host)
        codec = ActuatorCodec(plain, node_id=node, host_id=host)
        for ours, cmd in (("query", controller.make_query()), ("stop", controller.make_stop())):
            frame = codec.encode(ours)
            assert (frame.arbitration_id, frame.is_extended, frame.data) == _moteus_frame(cmd)


def _moteus_reply(rng: random.Random) -> tuple[bytes, dict[str, Any]]:
    """A query reply laid out by moteus' own WriteCombiner (reply subframes, base 0x20) from random values."""
    values = {"mode": rng.randrange(16), "position": rng.uniform(-100, 100), "velocity": rng.uniform(-50, 50),
              "torque": rng.uniform(-30, 30), "voltage": rng.randrange(-127, 128) * 0.5,
              "temperature": float(rng.randrange(-127, 128)), "fault": rng.choice([0, 0, 0, *range(32, 44)])}
    buf = io.BytesIO()
    w = Writer(buf)
    c1 = mp.WriteCombiner(w, 0x20, int(Register.MODE), [mp.INT8, mp.F32, mp.F32, mp.F32])
    if c1.maybe_write():
        w.write_int(values["mode"], mp.INT8)
    for name in ("position", "velocity", "torque"):
        if c1.maybe_write():
            w.write_mapped(values[name], 1.0, 1.0, 1.0, mp.F32)
    c2 = mp.WriteCombiner(w, 0x20, int(Register.VOLTAGE), [mp.INT8, mp.INT8, mp.INT8])
    if c2.maybe_write():
        w.write_voltage(values["voltage"], mp.INT8)
    if c2.maybe_write():
        w.write_temperature(values["temperature"], mp.INT8)
    if c2.maybe_write():
        w.write_int(values["fault"], mp.INT8)
    data = buf.getvalue()
    size = TransportDevice._round_up_dlc(None, len(data))  # type: ignore[arg-type]
    return data + b"\x50" * (size - len(data)), values


def test_moteus_replies_both_ways() -> None:
    plain = builtin_actuator_profile("moteus").plain
    rng = random.Random(5)
    for _ in range(N):
        node, host = rng.randrange(1, 128), rng.randrange(0, 128)
        codec = ActuatorCodec(plain, node_id=node, host_id=host)
        data, _ = _moteus_reply(rng)
        reply_id = node << 8 | host
        got = codec.decode(reply_id, reply_id > 0x7FF, data)
        assert got is not None and got.message == "query_result"
        theirs = parse_registers(data).response
        assert got.values["position"] == theirs[Register.POSITION] * TURN
        assert got.values["velocity"] == theirs[Register.VELOCITY] * TURN
        assert got.values["torque"] == theirs[Register.TORQUE]
        assert (got.values["voltage"], got.values["temperature"]) == (theirs[Register.VOLTAGE],
                                                                      theirs[Register.TEMPERATURE])
        assert (got.values["mode"], got.values["fault"]) == (theirs[Register.MODE], theirs[Register.FAULT])
        if theirs[Register.MODE] in {m.value for m in moteus.Mode}:
            assert got.states["mode"] == moteus.Mode(theirs[Register.MODE]).name
        # the simulator's side: netcfg's encoding of the reply is what moteus parses, and moteus' transport takes
        # its identifier as the answer to a query sent to this node from this host
        again = codec.encode("query_result", got.values)
        assert parse_registers(again.data).response == theirs and again.data == data
        accepts = moteus.Transport([])._make_response_filter(moteus.Controller(id=node, source_can_id=host)
                                                             .make_query())
        assert accepts(can.Message(arbitration_id=again.arbitration_id, data=again.data, is_fd=True))


# -- RobStride: the robstride package's Client over a stand-in bus
def _rs_feedback(rng: random.Random, node: int, host: int, faults: int, mode: int) -> can.Message:
    arbitration_id = 2 << 24 | mode << 22 | faults << 16 | node << 8 | host
    return can.Message(arbitration_id=arbitration_id, data=rng.randbytes(8), is_extended_id=True)


def test_robstride_commands_byte_for_byte() -> None:
    """enable, stop (the client's disable), write_param of float parameters and of run_mode, read_param: the frames
    the client sends, against the profile's."""
    plain = builtin_actuator_profile("robstride-rs03").plain
    rng = random.Random(3)
    floats = [index for name, index in rs.params if name != "run_mode"]
    for i in range(N):
        node, host = rng.randrange(128), rng.randrange(256)
        bus = CaptureBus()
        client = rs.Client(bus, host_can_id=host)  # type: ignore[arg-type]
        codec = ActuatorCodec(plain, node_id=node, host_id=host)
        bus.replies.append(_rs_feedback(rng, node, host, 0, 2))
        kind = i % 5
        if kind == 0:
            client.enable(node)
            ours = codec.encode("enable")
        elif kind == 1:
            client.disable(node)
            ours = codec.encode("stop")
        elif kind == 2:
            index, value = rng.choice(floats), struct.unpack("<f", struct.pack("<f", rng.uniform(-100, 100)))[0]
            client.write_param(node, index, value)
            ours = codec.encode("write_param", index=index, value=value)
        elif kind == 3:
            mode = rng.choice(list(rs.RunMode))
            client.write_param(node, "run_mode", mode)
            ours = codec.encode("write_run_mode", run_mode=mode.value)
        else:
            index = rng.choice(floats)
            reply = can.Message(arbitration_id=17 << 24 | node << 8 | host, is_extended_id=True,
                                data=struct.pack("<HHf", index, 0, rng.uniform(-10, 10)))
            bus.replies[0] = reply
            value = client.read_param(node, index)
            ours = codec.encode("read_param", index=index)
            answer = codec.decode(reply.arbitration_id, True, bytes(reply.data))
            assert answer is not None and answer.message == "param_value"
            assert answer.values == {"index": index, "value": value}
        (sent,) = bus.sent
        assert (ours.arbitration_id, ours.is_extended, ours.data) == (sent.arbitration_id, sent.is_extended_id,
                                                                     bytes(sent.data)), kind


# robstride 0.1.0 reads model 1 (RS01/RS02) and any other model with RS04's ranges; RS03's are not in it, so the
# decoding is compared with the profile's range parameters set to those two models'
MODELS = {1: {"v_max": 44.0, "t_max": 17.0}, 2: {"v_max": 15.0, "t_max": 120.0}}


@pytest.mark.parametrize("model", sorted(MODELS))
def test_robstride_feedback_both_ways(model: int) -> None:
    """The client's _parse_feedback_resp against the profile's feedback. The two compute raw·span/65535 + lo in a
    different order, so values agree to binary64 rounding (1e-12 of the span), not bit for bit. The client reads
    faults from identifier bits 16-20 and the mode from bit 22 alone, where the RS03 manual puts faults in bits
    16-21 and the mode in bits 22-23: the comparison covers what it reads (faults below bit 5, modes 0 and 1) and
    test_robstride_manual_bits pins the rest to the manual."""
    plain = builtin_actuator_profile("robstride-rs03").plain
    feedback = next(m for m in plain["messages"] if m["name"] == "feedback")
    bits = {name: bit for bit, name in next(f for f in feedback["fields"] if f["name"] == "faults")["flags"]}
    rng = random.Random(30 + model)
    for _ in range(N):
        node, host = rng.randrange(128), rng.randrange(256)
        msg = _rs_feedback(rng, node, host, rng.randrange(32), rng.randrange(2))
        theirs = rs.Client(CaptureBus(), host_can_id=host)._parse_feedback_resp(msg, node, model)  # type: ignore[arg-type]
        got = ActuatorCodec(plain, node_id=node, host_id=host, **MODELS[model]).decode(
            msg.arbitration_id, True, bytes(msg.data))
        assert got is not None and got.message == "feedback"
        for ours, their, span in (("position", theirs.angle, 8 * math.pi), ("velocity", theirs.velocity,
                                  2 * MODELS[model]["v_max"]), ("torque", theirs.torque, 2 * MODELS[model]["t_max"])):
            assert got.values[ours] == pytest.approx(their, abs=1e-12 * span)
        assert got.values["temperature"] == pytest.approx(theirs.temp, abs=1e-12)
        assert {bits[name] for name in got.errors} == {e.value.bit_length() - 1 for e in theirs.errors}
        assert got.values["mode"] == theirs.mode.value


def test_robstride_manual_bits() -> None:
    plain = builtin_actuator_profile("robstride-rs03").plain
    codec = ActuatorCodec(plain, node_id=9, host_id=0xFD)
    got = codec.decode(2 << 24 | 2 << 22 | 0b100001 << 16 | 9 << 8 | 0xFD, True, bytes(8))
    assert got is not None and got.states["mode"] == "RUN" and set(got.errors) == {"UNDERVOLTAGE", "UNCALIBRATED"}


def test_robstride_operation_control() -> None:
    """Operation control (type 1) has no encoder in robstride 0.1.0. Its identifier is checked with the client's
    frame builder (_rs_msg with the torque's raw value as the data area), and its values by reading the frame's
    16-bit fields with the client's own feedback scaling (the same ranges; RS01's, model 1): each must come back
    at most one count below the commanded value (the packing truncates)."""
    plain = builtin_actuator_profile("robstride-rs03").plain
    rng = random.Random(301)
    ranges = {**MODELS[1], "kp_max": 500.0, "kd_max": 5.0}
    client = rs.Client(CaptureBus(), host_can_id=0)  # type: ignore[arg-type]
    for _ in range(N):
        node = rng.randrange(128)
        codec = ActuatorCodec(plain, node_id=node, host_id=0, **ranges)
        cmd = {"position": rng.uniform(-4 * math.pi, 4 * math.pi), "velocity": rng.uniform(-44, 44),
               "torque": rng.uniform(-17, 17), "kp": rng.uniform(0, 500), "kd": rng.uniform(0, 5)}
        frame = codec.encode("operation_control", cmd)
        torque_raw = frame.arbitration_id >> 8 & 0xFFFF
        built = client._rs_msg(rs.MotorMsg.Control, torque_raw, node, list(frame.data))
        assert (built.arbitration_id, built.is_extended_id, bytes(built.data)) == (frame.arbitration_id, True,
                                                                                   frame.data)
        as_feedback = can.Message(arbitration_id=2 << 24 | node << 8, is_extended_id=True,
                                  data=frame.data[:4] + torque_raw.to_bytes(2, "big") + b"\x00\x00")
        read = client._parse_feedback_resp(as_feedback, node, 1)
        for name, value, span in (("position", read.angle, 8 * math.pi), ("velocity", read.velocity, 88.0),
                                  ("torque", read.torque, 34.0)):
            count = span / 65535
            assert cmd[name] - count - 1e-9 <= value <= cmd[name] + 1e-9, name
