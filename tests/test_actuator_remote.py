"""ODrive's remote-requested messages at a rate: a remote frame (RTR, no data field) and the data frame that answers
it share their identifier (ODrive CAN Simple, firmware 0.6.10: "Get_*" messages are sent on request by a remote frame
of their own identifier), which is the one case the duplicate-identifier check lets two messages of a bus share one.

Figures come from ISO 11898-1 (a frame's bits, the RTR bit in arbitration), the vendor's DBC in odrive-can (frame
lengths, identifiers), odrive-can's own client (the request frame it sends) and hand calculations beside each
assertion."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import can
import cantools
import odrive_can
import pytest
import yaml
from conftest import cli, runtime_config_of

from netcfg.devices.actuator_profile import builtin_actuator_profile
from netcfg.links.arbitration import frame_priority
from netcfg.runtime.actuators import ActuatorCodec

NODE = 1  # the axis' node id: identifiers node_id << 5 | command (CAN Simple)


def odrive_spec(**extra: Any) -> dict[str, Any]:
    """One ODrive axis at 1 Mbit/s: Set_Input_Vel at 100 Hz, and its encoder estimates and Iq each requested at 100 Hz
    by a remote frame (their own cyclic rates off: the profile refuses a message both cyclic and requested)."""
    axis: dict[str, Any] = {
        "name": "axis", "node_id": NODE, "buses": ["can0"], "device": "odrive-cansimple",
        "actuator": {"parameters": {"encoder_msg_rate_ms": 0},
                     "commands": [{"message": "set_input_vel", "rate": "100 Hz"},
                                  {"message": "request_encoder_estimates", "rate": "100 Hz"},
                                  {"message": "request_iq", "rate": "100 Hz"}]},
    }
    axis.update(extra)
    return {"system": "odrive_rtr", "buses": [{"name": "can0", "protocol": "can", "bitrate": "1 Mbit/s"}],
            "nodes": [{"name": "host", "role": "master", "buses": ["can0"]}, axis]}


def write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "odrive.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def odrive_dbc() -> Any:
    return cantools.database.load_file(str(Path(odrive_can.__file__).parent / "dbc" / "odrive-cansimple-0.6.10.dbc"))


def test_a_request_and_its_answer_share_the_identifier(tmp_path: Path) -> None:
    """The request is a remote frame on 0x029 (1 << 5 | 0x09, Get_Encoder_Estimates) with no data: by ISO 11898-1's
    frame layout, worst-case stuffed, 47 + 8 * 0 + floor((34 + 8 * 0 - 1) / 4) = 55 bits with the intermission,
    55 us at 1 Mbit/s; the answer, 8 bytes, 47 + 64 + floor(97 / 4) = 135 bits.

    Its worst-case response by hand (Davis et al. 2007, eq. 5-10): higher priority are the heartbeat (0x021) and,
    on 0x029 itself, the data frame that answers it (a data frame wins over a remote frame of its identifier); the
    longest lower-priority frame blocks it (135 bits). R = 135 + 135 + 135 + 55 = 460 us. Were the answer lower
    (equal identifiers taken in list order) the bound would be 325 us, short of what the bus can do to it."""
    from netcfg.check import analyse_spec

    model, report = analyse_spec(write(tmp_path, odrive_spec()))
    assert model is not None and report["ok"], report["errors"]
    req, ans = model.messages["axis_request_encoder_estimates"], model.messages["axis_get_encoder_estimates"]
    assert (req.id, req.remote, req.size, req.producer) == (0x029, True, 0, "host")
    assert (ans.id, ans.remote, ans.size, ans.producer) == (0x029, False, 8, "axis")
    rows = {r["name"]: r for r in report["buses"][0]["messages"]}
    assert (rows["axis_request_encoder_estimates"]["frame_bits_worst"], rows["axis_get_encoder_estimates"]
            ["frame_bits_worst"]) == (55, 135)
    assert rows["axis_request_encoder_estimates"]["wcrt_us"] == 460
    assert rows["axis_request_encoder_estimates"]["remote"] is True and "remote" not in rows["axis_get_iq"]
    text = cli("check", str(tmp_path / "odrive.yaml")).stdout.splitlines()
    assert [line.split()[:3] for line in text if " 0x29 " in line] == [
        ["axis_get_encoder_estimates", "0x29", "8"], ["axis_request_encoder_estimates", "0x29", "RTR"]]
    # the load: per 10 ms 3 data frames of 135 bits (Set_Input_Vel and the two answers) and 2 remote frames of 55,
    # and the heartbeat (135 bits every 100 ms), at 1 Mbit/s: (3 * 135 + 2 * 55) / 10,000 + 135 / 100,000 = 5.285 %
    assert report["buses"][0]["utilization"] == pytest.approx(0.05285, rel=1e-12)


def test_the_rtr_bit_orders_arbitration() -> None:
    """ISO 11898-1, 10.4.2.2 and 10.8.2: after the base identifier a standard data frame sends RTR dominant, a
    standard remote frame RTR recessive; an extended frame sends SRR and IDE recessive there, so a standard remote
    frame still wins over it (its IDE, the next bit, is dominant); an extended remote frame's RTR comes last."""
    order = [frame_priority(0x29, False, False), frame_priority(0x29, False, True),
             frame_priority(0x29 << 18, True, False), frame_priority(0x29 << 18, True, True),
             frame_priority(0x2A, False, False)]
    assert order == sorted(order) and len(set(order)) == len(order)


def test_the_simulated_bus_lets_the_data_frame_win() -> None:
    """The simulator's arbitration, by hand at 1 Mbit/s: a frame on 0x100 holds the bus 0..55 us; meanwhile a remote
    frame on 0x029 (queued at 5 us, first) and the 8-byte data frame on 0x029 (at 10 us) wait. The data frame wins
    (its RTR bit is dominant), 55..190 us; the remote frame follows, 190..245 us. Responses: 190 - 10 = 180 us and
    245 - 5 = 240 us (with equal keys the remote frame, queued first, would have gone first)."""
    from netcfg.sim.can_bus import CanBus
    from netcfg.sim.engine import Simulator

    sim = Simulator()
    bus = CanBus(sim, "can0", 1_000_000)
    first = bus.add_source("first", 0x100, False, 0, "n1")
    remote = bus.add_source("request", 0x029, False, 0, "host", remote=True)
    data = bus.add_source("answer", 0x029, False, 8, "axis")
    bus.start()
    sim.at(0, lambda _: bus.submit(first))
    sim.at(5_000, lambda _: bus.submit(remote))
    sim.at(10_000, lambda _: bus.submit(data, bytes(8)))
    sim.run_until(1_000_000)
    assert bus.record.msg == [first, data, remote]
    assert dict(zip(bus.record.msg, bus.record.response)) == {first: 55_000, data: 180_000, remote: 240_000}


def test_every_other_shared_identifier_is_still_refused(tmp_path: Path) -> None:
    """A data frame of the spec's own on 0x029 collides with the answer; so would two remote frames of one
    identifier, which a profile of the user's can ask for."""
    from conftest import check_data

    data = odrive_spec()
    data["messages"] = [{"name": "mine", "producer": "host", "consumers": ["axis"], "id": 0x029, "size": 8,
                         "period": "10 ms"}]
    codes = [(e["code"], e["message"]) for e in check_data(tmp_path, data)["errors"]]
    assert any(c == "duplicate-id" and "0x029" in m and "request" not in m for c, m in codes), codes
    profile = tmp_path / "two_requests.yaml"
    profile.write_text(yaml.safe_dump({
        "profile": "two-requests", "format": 1, "source": {"document": "a hand-made profile", "version": "1"},
        "parameters": {"node_id": {"min": 0, "max": 63}},
        "messages": {
            "ask_a": {"from": "host", "id": "node_id << 5 | 0x09", "size": 8, "remote": True,
                      "reply": {"message": "a", "delay_us": [0, 100], "basis": "assumed", "note": "a test"}},
            "ask_b": {"from": "host", "id": "node_id << 5 | 0x09", "size": 8, "remote": True,
                      "reply": {"message": "b", "delay_us": [0, 100], "basis": "assumed", "note": "a test"}},
            "a": {"from": "device", "id": "node_id << 5 | 0x09", "size": 8},
            "b": {"from": "device", "id": "node_id << 5 | 0x0A", "size": 8},
        },
    }), encoding="utf-8")
    data = odrive_spec(device={"actuator": str(profile)}, actuator={
        "commands": [{"message": "ask_a", "rate": "100 Hz"}, {"message": "ask_b", "rate": "100 Hz"}]})
    errs = [e for e in check_data(tmp_path, data)["errors"] if e["code"] == "duplicate-id"]
    assert [e["message"] for e in errs] == [
        "identifier 0x029 of 'axis_ask_b' collides with 'axis_ask_a'; pick a free one"]


def test_the_request_is_the_frame_odrive_can_sends(odrive_dbc: Any) -> None:
    """odrive-can's own client (ODriveCAN._send_message with rtr=True, which its _request awaits an answer to) sends
    every Get_* request the profile has as a standard remote frame on the Get_* message's identifier in the vendor's
    DBC; netcfg's codec sends the same, its DLC the length of that message (8, the DBC's), where odrive-can leaves
    python-can's default of 0 (a remote frame's DLC is that of the data frame it asks for: CAN 2.0 part B, 3.1.2)."""
    from odrive_can.odrive import ODriveCAN
    from test_actuator_vendors import CaptureBus as Capture

    class CaptureBus(Capture):
        def shutdown(self) -> None:  # ODriveCAN shuts its bus down when it goes
            pass

    plain = builtin_actuator_profile("odrive-cansimple").plain
    requests = [m for m in plain["messages"] if m.get("remote")]
    assert len(requests) == 6
    for node in (0, 5):
        capture = CaptureBus()
        client = ODriveCAN(axis_id=node, can_bus=capture)  # type: ignore[arg-type]
        codec = ActuatorCodec(plain, node_id=node)
        for m in requests:
            dbc = next(x for x in odrive_dbc.messages if x.name.lower() == f"axis{node}_{m['reply']}")
            client._send_message(dbc.name.split("_", 1)[1], rtr=True)
            theirs = capture.sent[-1]
            ours = codec.encode(m["name"])
            assert theirs.is_remote_frame and ours.is_remote and ours.data == b""
            assert (ours.arbitration_id, ours.is_extended) == (theirs.arbitration_id, theirs.is_extended_id)
            assert ours.arbitration_id == dbc.frame_id and ours.dlc == dbc.length == 8
            client._request_id = 0


def test_build_writes_the_request(tmp_path: Path, odrive_dbc: Any) -> None:
    """runtime.json: the request is a remote message of no data; the C header says so, with the DLC of its answer
    (the vendor DBC's 8), and compiles; the DBC leaves the remote frames out (a DBC has none) and says so, and
    cantools loads it with each identifier once."""
    spec = write(tmp_path, odrive_spec())
    out = tmp_path / "out"
    proc = cli("build", str(spec), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "remote frames (RTR) axis_request_encoder_estimates, axis_request_iq" in proc.stderr + proc.stdout
    doc = json.loads((out / "runtime.json").read_text())
    msgs = {m["name"]: m for m in doc["messages"]}
    assert (msgs["axis_request_iq"]["remote"], msgs["axis_request_iq"]["size"], msgs["axis_request_iq"]["id"]) == (
        True, 0, 0x034)
    assert "remote" not in msgs["axis_get_iq"]
    header = (out / "c" / "host.h").read_text()
    assert "#define MSG_AXIS_REQUEST_IQ_REMOTE 1\n#define MSG_AXIS_REQUEST_IQ_DLC 8\n" in header
    assert "MSG_AXIS_GET_IQ_REMOTE" not in header
    for name in ("host", "axis"):
        gcc = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-fsyntax-only", "-x",
                              "c", str(out / "c" / f"{name}.h")], capture_output=True, text=True)
        assert gcc.returncode == 0, gcc.stderr
    db = cantools.database.load_file(str(out / "dbc" / "can0.dbc"))
    assert sorted(m.name for m in db.messages if m.frame_id in (0x029, 0x034)) == ["axis_get_encoder_estimates",
                                                                                    "axis_get_iq"]


def test_the_simulation_stays_inside_the_bounds(tmp_path: Path) -> None:
    """The simulator runs runtime.json's remote frames as frames of no data: a request with nothing ahead of it
    takes its 55 bits, 55 us (the Set_Input_Vel at 0x02D is lower than 0x029; each 10 ms the requests find the bus
    free), and every measured response stays within its analysed bound (exit 0)."""
    proc = cli("simulate", str(write(tmp_path, odrive_spec())), "--duration", "2s", "--format", "json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    got = {m["name"]: m for m in doc["messages"]}
    assert got["axis_request_encoder_estimates"]["count"] == 200  # 2 s at 100 Hz
    assert got["axis_request_encoder_estimates"]["response_us"]["min"] == 55
    assert all(m["within_analysis"] for m in doc["messages"]), doc["messages"]


def test_run_requests_at_a_rate_and_verify_reads_the_log(tmp_path: Path) -> None:
    """50 cycles of 10 ms against the simulated ODrive: each request is answered with its Get_* frame (the profile's
    reply), so replies + missing = 2 * 50; the log holds the requests as remote frames ('029#R'), which verify counts
    as the request messages (50 each, no size violation) and the answers as their data messages, measured from their
    requests. What verify may find beyond: the host's latency ('late', 'host_late'; a period of the simulated axis's
    own heartbeat missing, 'gap', when the host stalled) and Set_Axis_State (0x027 = 1 << 5 | 0x07), the enable and
    safe stop, which the spec does not send at a rate."""
    spec, log = write(tmp_path, odrive_spec()), tmp_path / "run.log"
    for _ in range(3):  # again (at most 3 runs) only when the run reports its host missed a release
        proc = cli("run", str(spec), "--simulated-drives", "--cycles", "50", "--log", str(log), "--format", "json")
        assert proc.returncode == 0, proc.stderr
        doc = json.loads(proc.stdout)
        if not doc["sends"]["missed_releases"]:
            break
    axis = doc["actuators"]["axis"]
    assert axis["commands"] == 150 and axis["replies"] + axis["missing"] == 100
    assert axis["heard"]["get_encoder_estimates"] >= 1 and axis["heard"]["get_iq"] >= 1
    lines = log.read_text().splitlines()
    assert sum(line.split()[2] == "029#R" for line in lines) == 50
    got = json.loads(cli("verify", str(spec), str(log), "--format", "json").stdout)
    assert set(got["violations_by_kind"]) <= {"late", "host_late", "unknown_id", "gap"}, got["violations"]
    # the simulated axis is a thread of the same host: a stall of half its heartbeat's 100 ms leaves a period out
    assert {v["message"] for v in got["violations"] if v["kind"] == "gap"} <= {"axis_heartbeat"}, got["violations"]
    assert [u["id"] for u in got["unknown_ids"]] in ([], [0x027]), got["unknown_ids"]
    counts = {m["name"]: m for m in got["messages"]}
    assert counts["axis_request_encoder_estimates"]["count"] == counts["axis_request_iq"]["count"] == 50
    assert counts["axis_get_iq"]["response_from"] == "command"
    assert counts["axis_get_iq"]["count"] + counts["axis_get_encoder_estimates"]["count"] == axis["replies"]
    assert not [v for v in got["violations"] if v["kind"] == "size"]


def test_a_simulated_odrive_answers_a_remote_frame_of_any_dlc(tmp_path: Path) -> None:
    """odrive-can's client sends its requests with DLC 0, netcfg's with 8: the simulated axis answers both, as the
    vendor's mock does (it answers every remote frame of its axis)."""
    from netcfg.runtime.simulated_actuator import ActuatorBench

    cfg = runtime_config_of(tmp_path / "odrive.yaml", odrive_spec())
    channel = f"odrive-rtr-{id(tmp_path)}"
    with ActuatorBench(cfg, "can0", channel=channel) as bench, can.Bus(interface="virtual", channel=channel) as bus:
        assert bench["axis"] is not None
        answers = []
        for dlc in (0, 8):
            bus.send(can.Message(arbitration_id=NODE << 5 | 0x14, is_extended_id=False, is_remote_frame=True,
                                 dlc=dlc))
            msg = bus.recv(timeout=2.0)
            while msg is not None and msg.arbitration_id != NODE << 5 | 0x14:
                msg = bus.recv(timeout=2.0)
            answers.append(msg is not None and not msg.is_remote_frame and len(msg.data) == 8)
    assert answers == [True, True]


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))


def test_tune_keeps_the_pair_and_places_the_rest(tmp_path: Path) -> None:
    """`netcfg tune` keeps what the profile fixes and ranks the remote frame one level below its answer: a message
    of the spec's own with a 300 us deadline at 0x300 misses it behind the axis' frames (check refuses), and tune
    moves it to the top, where by hand its bound is its own 135 us plus the longest lower frame's 135 us, 270 us.
    Before the remote frame had a level of its own, the search lost one of the pair and refused the spec."""
    from conftest import check

    data = odrive_spec()
    data["nodes"][1]["actuator"]["commands"] = data["nodes"][1]["actuator"]["commands"][:2]
    data["messages"] = [
        {"name": "fast", "producer": "host", "consumers": ["axis"], "id": 0x300, "size": 8, "period": "1 ms",
         "deadline": "300 us"},
        {"name": "slow", "producer": "host", "consumers": ["axis"], "id": 0x010, "size": 8, "period": "50 ms"}]
    spec, out = write(tmp_path, data), tmp_path / "tuned.yaml"
    assert not check(spec)["ok"]
    proc = cli("tune", str(spec), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    report = check(out)
    assert report["ok"], report["errors"]
    rows = {r["name"]: r for r in report["buses"][0]["messages"]}
    assert (rows["fast"]["id"], rows["fast"]["wcrt_us"]) == (0x010, 270)
    assert rows["axis_request_encoder_estimates"]["id"] == rows["axis_get_encoder_estimates"]["id"] == 0x029


def test_run_reports_how_late_its_host_sent_each_command(tmp_path: Path) -> None:
    """The master measures each command's send against its release (t0 + k * 10 ms): on a clock that keeps time
    exactly but stalls once, 25 ms long, in the wait for the release at 40 ms, the releases at 40, 50 and 60 ms go
    out at 65 ms, 25, 15 and 5 ms late. Those at least a period (10 ms) late are missed releases: 2 per command, 6
    for the three commands; by hand the largest lateness is 25,000 us and the mean over the 3 * 10 sends of 10
    cycles (25 + 15 + 5) * 3 / 30 ms = 4,500 us."""
    from netcfg.runtime.actuator_master import ActuatorMaster, ActuatorRunPlan
    from netcfg.runtime.actuator_plan import plan_actuators

    class SteppedClock:
        t = 100.0

        def now(self) -> float:
            return self.t

        def sleep_until(self, t: float) -> None:
            self.t = max(self.t, t)

    clock = SteppedClock()

    class IdleBus(can.BusABC):  # a bus nobody answers on: each wait takes its timeout, one of them 25 ms more
        stalled = False

        def __init__(self) -> None:
            super().__init__(channel="idle")

        def send(self, msg: can.Message, timeout: float | None = None) -> None:
            pass

        def recv(self, timeout: float | None = None) -> None:
            clock.t += timeout or 0.0
            if not self.stalled and clock.t - master._t0 > 0.035:
                self.stalled, clock.t = True, clock.t + 0.025
            return None

        def _recv_internal(self, timeout: float | None) -> tuple[None, bool]:
            return None, False

    cfg = runtime_config_of(tmp_path / "odrive.yaml", odrive_spec())
    master = ActuatorMaster(plan_actuators(cfg, "can0"), "can0", clock=clock)
    bus = IdleBus()
    run = master.run(bus, ActuatorRunPlan(cycles=10))
    bus.shutdown()
    assert run.actuators["axis"].commands == 30
    assert run.missed_releases == 6
    assert round(run.send_late_us[0]) == 25_000 and round(run.send_late_us[1] / run.send_late_us[2]) == 4_500
