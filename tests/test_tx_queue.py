"""FIFO transmit queues (spec `tx_queue`): the analysis of Davis, Kollmann, Pollex and Slomka (ECRTS 2011), the
simulator's queue, the depth check and runtime.json.

Frame times in the hand calculations: a classical standard frame with 8 data bytes is 135 bits in the worst case
(Davis et al. 2007, eq. 1: C = (55 + 10 s) tau = 135 tau, inter-frame space included), 135 us at 1 Mbit/s; the bit
time tau is 1 us. Every interfering period in these specs is far longer than the windows analysed, so each
interferer counts once and a clock tolerance on the periods changes none of the figures.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import bus, check_data, cli, message

from netcfg.sim.can_bus import CanBus
from netcfg.sim.engine import Simulator
from netcfg.timing import can_fifo, can_rta

US = 1_000
C8 = 135 * US  # an 8-byte standard frame at 1 Mbit/s, worst case

# host sends `low` and `high` through one FIFO (high queued 1 us after low); drive's `mid` sits between them in
# priority; logger's `log` is below all of them
INVERSION: dict[str, Any] = {
    "system": "fifo_inversion",
    "buses": [{"name": "can0", "protocol": "can", "bitrate": "1 Mbit/s"}],
    "nodes": [
        {"name": "host", "buses": ["can0"], "tx_queue": "fifo"},
        {"name": "drive", "buses": ["can0"]},
        {"name": "logger", "buses": ["can0"]},
    ],
    "messages": [
        {"name": "low", "producer": "host", "consumers": ["drive"], "id": 0x300, "size": 8, "period": "10 ms"},
        {
            "name": "high",
            "producer": "host",
            "consumers": ["drive"],
            "id": 0x010,
            "size": 8,
            "period": "10 ms",
            "offset": "1 us",
        },
        {"name": "mid", "producer": "drive", "consumers": ["host"], "id": 0x100, "size": 8, "period": "997 us"},
        {"name": "log", "producer": "logger", "consumers": ["host"], "id": 0x400, "size": 8, "period": "701 us"},
    ],
}


def _spec(policy: Any = "fifo") -> dict[str, Any]:
    data = copy.deepcopy(INVERSION)
    data["nodes"][0]["tx_queue"] = policy
    return data


def test_fifo_bound_by_hand() -> None:
    """ECRTS 2011, section 4, for host's FIFO M = {high, low}, L = low (0x300), C_MIN = 135 us:
    B = the longest frame of another node below low: log, 135 us.
    w = B + (C_high + C_low) - C_MIN + I(w + tau), I = mid (0x100, the only other frame above low) once:
      w = 135 + 270 - 135 + 135 = 405 us; R = w + C_MIN = 540 us for both high and low.
    mid sees high with jitter J' = R - C = 405 us: w = B (135) + ceil((w + 405 + 1) / 10,000) 135 = 270, R = 405 us
    (the priority-queue analysis gives it 270 us: blocking and itself).
    log, the lowest: high, low, mid once each, no blocking: 405 + 135 = 540 us."""
    tau = US
    frames = [
        can_rta.CanFrame("low", 0x300, False, C8, 10_000 * US),
        can_rta.CanFrame("high", 0x010, False, C8, 10_000 * US),
        can_rta.CanFrame("mid", 0x100, False, C8, 997 * US),
        can_rta.CanFrame("log", 0x400, False, C8, 701 * US),
    ]
    res = can_fifo.analyse(frames, tau, {"low": "host", "high": "host"}, lambda fs: can_rta.analyse(fs, tau))
    q = res.queues["host"]
    assert (q.blocking_ns, q.queued_ns, q.c_min_ns, q.interference_ns, q.queue_ns) == (
        135 * US,
        270 * US,
        135 * US,
        135 * US,
        540 * US,
    )
    assert q.members == ("high", "low") and q.lowest == "low"
    assert res.effective_jitter_ns == {"low": 405 * US, "high": 405 * US}
    got = {name: r.wcrt_ns for name, r in res.responses.items()}
    assert got == {"low": 540 * US, "high": 540 * US, "mid": 405 * US, "log": 540 * US}


def test_an_unbounded_fifo_leaves_everything_below_it_unbounded() -> None:
    """FIFO A = {a1 0x010 every 300 us, a2 0x020}, FIFO B = {b1 0x030, b2 0x040}, priority node P = {hp 0x001,
    lp 0x100}; all 135 us frames. A: B_A = 135 (a frame below 0x020), w = 135 + 270 - 135 + hp (135, once) = 405,
    R = 540 us > a1's period of 300 us: two a1 frames can be queued, no bound. B's lowest (0x040) is below a1, which
    now reaches arbitration at no bounded time: no bound either; nor lp, below a1. hp, above both queues, keeps its
    bound: blocking by one frame + itself = 270 us."""
    tau = US
    frames = [
        can_rta.CanFrame("a1", 0x010, False, C8, 300 * US),
        can_rta.CanFrame("a2", 0x020, False, C8, 10_000 * US),
        can_rta.CanFrame("b1", 0x030, False, C8, 10_000 * US),
        can_rta.CanFrame("b2", 0x040, False, C8, 10_000 * US),
        can_rta.CanFrame("hp", 0x001, False, C8, 10_000 * US),
        can_rta.CanFrame("lp", 0x100, False, C8, 10_000 * US),
    ]
    fifo_of = {"a1": "A", "a2": "A", "b1": "B", "b2": "B"}
    res = can_fifo.analyse(frames, tau, fifo_of, lambda fs: can_rta.analyse(fs, tau))
    assert res.queues["A"].limit == "fifo" and res.queues["A"].interference_ns == 135 * US
    assert res.queues["B"].queue_ns is None and res.queues["B"].limit == "fifo"
    got = {name: r.wcrt_ns for name, r in res.responses.items()}
    assert got == {"a1": None, "a2": None, "b1": None, "b2": None, "hp": 270 * US, "lp": None}


def test_priority_inversion_that_the_priority_queue_analysis_misses(tmp_path: Path) -> None:
    """The spec analysed with a priority queue on host gives high B + C = 135 + 135 = 270 us (Davis et al. 2007:
    it can only wait for one lower-priority frame). Through the FIFO it can wait behind low, which loses to mid:
    the FIFO bound is 540 us (test_fifo_bound_by_hand). The simulator, host's frames queued in order, shows high
    above 270 us, and never above 540 us."""
    prio = check_data(tmp_path, _spec("priority"), "prio.yaml")
    fifo = check_data(tmp_path, _spec(), "fifo.yaml")
    assert message(bus(prio, "can0"), "high")["wcrt_us"] == 270.0
    assert message(bus(fifo, "can0"), "high")["wcrt_us"] == 540.0
    assert message(bus(fifo, "can0"), "high")["tx_queue"] == "fifo"
    proc = cli("simulate", str(tmp_path / "fifo.yaml"), "--duration", "5s", "--seed", "3", "--format", "json")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    doc = json.loads(proc.stdout)
    high = next(m for m in doc["messages"] if m["name"] == "high")
    assert 270.0 < high["response_us"]["max"] <= 540.0
    assert high["within_analysis"] is True
    assert doc["tx_queues"] == [
        {"bus": "can0", "node": "host", "depth": 10, "on_full": "block", "max_backlog": 2, "overflows": 0}
    ]


def _bus_with_fifo(depth: int, drop: bool) -> tuple[Simulator, CanBus, dict[str, int]]:
    sim = Simulator(0)
    can = CanBus(sim, "can0", 1_000_000)
    src = {
        "low": can.add_source("low", 0x300, False, 8, "host"),
        "high": can.add_source("high", 0x010, False, 8, "host"),
        "mid": can.add_source("mid", 0x100, False, 8, "drive"),
        "log": can.add_source("log", 0x400, False, 8, "logger"),
    }
    can.fifo_queue("host", depth, drop)
    return sim, can, src


def _at(sim: Simulator, can: CanBus, t: int, source: int) -> None:
    sim.at(t, lambda _: can.submit(source))


def test_simulated_fifo_order_by_hand() -> None:
    """log queued at 0 starts at once (135 us); low at 10 us, high at 11 us behind it, mid at 20 us. At 135 us the
    arbitration sees host's head (low) and mid: mid wins (135-270), then low (270-405), then high (405-540).
    high's response: 540 - 11 = 529 us, above its priority-queue bound of 270 us."""
    sim, can, src = _bus_with_fifo(10, False)
    for t, name in ((0, "log"), (10 * US, "low"), (11 * US, "high"), (20 * US, "mid")):
        _at(sim, can, t, src[name])
    can.start()
    sim.run_until(2_000 * US)
    names = [can.sources[i].name for i in can.record.msg]
    assert names == ["log", "mid", "low", "high"]
    assert dict(zip(names, can.record.response)) == {
        "log": 135 * US,
        "mid": 250 * US,
        "low": 395 * US,
        "high": 529 * US,
    }
    assert can.fifos[0].max_size == 2


def test_a_full_fifo_drops_or_blocks() -> None:
    """Depth 1: low is in the queue (waiting behind log's frame) when high comes. With drop, high is lost and
    counted; with block, its writer waits and high goes after low, in order."""
    for drop, sent in ((True, ["log", "low"]), (False, ["log", "low", "high"])):
        sim, can, src = _bus_with_fifo(1, drop)
        for t, name in ((0, "log"), (10 * US, "low"), (11 * US, "high")):
            _at(sim, can, t, src[name])
        can.start()
        sim.run_until(2_000 * US)
        assert [can.sources[i].name for i in can.record.msg] == sent
        assert can.fifos[0].overflows == 1
        assert can.dropped == ({src["high"]: 1} if drop else {})


def test_a_fifo_deeper_than_its_depth_is_flagged(tmp_path: Path) -> None:
    """host queues two messages; a depth of 1 can overflow: a blocked writer (which no task bound includes) is an
    error, and so is a dropped frame, whose message then has no response time. `low` states no offset, so it can
    be queued at any time: either message can find the other queued (test_seams_fifo keeps them apart)."""
    drop = check_data(tmp_path, _spec({"policy": "fifo", "depth": 1, "on_full": "drop"}), "drop.yaml")
    assert not drop["ok"] and [e["code"] for e in drop["errors"]] == ["tx-queue"]
    assert "up to 2 frames" in drop["errors"][0]["message"]
    assert "'high', 'low' can find it full" in drop["errors"][0]["message"]
    block = check_data(tmp_path, _spec({"policy": "fifo", "depth": 1}), "block.yaml")
    assert not block["ok"] and [e["code"] for e in block["errors"]] == ["tx-queue"]
    assert block["errors"][0]["line"] > 1


def test_a_fifo_member_slower_than_its_period_has_no_bound(tmp_path: Path) -> None:
    """high every 500 us: the FIFO bound of 540 us (test_fifo_bound_by_hand; mid still counts once, since
    ceil((405 + 1) / 997) = 1) exceeds its period, so two of its frames can be queued at once, against the paper's
    premise: no bound, said so."""
    data = _spec()
    data["messages"][1]["period"] = "500 us"
    report = check_data(tmp_path, data)
    high = message(bus(report, "can0"), "high")
    assert high["wcrt_us"] is None and high["unbounded"] == "fifo"
    assert any("FIFO transmit queue" in e["message"] for e in report["errors"])


def test_runtime_json_carries_the_queue(tmp_path: Path) -> None:
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(_spec({"policy": "fifo", "depth": 4, "on_full": "drop"})))
    proc = cli("build", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / "out" / "runtime.json").read_text())
    nodes = {n["name"]: n["tx_queue"] for n in doc["nodes"]}
    assert nodes["host"] == {"policy": "fifo", "depth": 4, "on_full": "drop"}
    assert nodes["drive"] == {"policy": "priority", "depth": 10, "on_full": "block"}


def test_explain_shows_the_queue_term(tmp_path: Path) -> None:
    """--explain high restates test_fifo_bound_by_hand: high and low in the queue (270 us), blocking by log (135),
    mid once (135): w = 135 + 270 - 135 + 135 = 405, R = 405 + 135 = 540 us. With a deadline of 300 us it misses,
    and the one change is the queue: by priority its bound is B + C = 270 us. --explain mid shows high as an
    interferer with the FIFO's jitter R - C = 405 us."""
    data = _spec()
    data["messages"][1]["deadline"] = "300 us"
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    proc = cli("check", str(tmp_path / "s.yaml"), "--explain", "high", "--format", "json")
    assert proc.returncode == 1, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["queue"]["node"] == "host" and doc["queue"]["lowest"] == "low"
    assert [x["name"] for x in doc["queue"]["frames"]] == ["high", "low"]
    assert (doc["queue"]["queued_us"], doc["queue"]["c_min_us"], doc["w_us"], doc["wcrt_us"]) == (270, 135, 405, 540)
    assert doc["blocking"] == {"by": "log", "us": 135.0}
    assert [(x["name"], x["hits"]) for x in doc["interferers"]] == [("mid", 1)]
    assert doc["fix"]["kind"] == "queue" and doc["fix"]["wcrt_us"] == 270.0
    text = cli("check", str(tmp_path / "s.yaml"), "--explain", "high").stdout
    assert "R = J + w + C_MIN = 0 + 405 + 135 = 540 us" in text
    mid = json.loads(cli("check", str(tmp_path / "s.yaml"), "--explain", "mid", "--format", "json").stdout)
    assert [(x["name"], x["jitter_us"]) for x in mid["interferers"]] == [("high", 405.0)]
    assert mid["wcrt_us"] == 405.0


def test_ftt_can_asynchronous_fifo_senders_are_refused(tmp_path: Path) -> None:
    """CAMBADA's kicker sends battery_status in the asynchronous window; the window analyses (Pedreiras and Almeida)
    order a node's frames by identifier, so a FIFO there is refused at the node's tx_queue rather than analysed
    wrongly."""
    from conftest import load_spec

    data = load_spec("cambada.yaml")
    kicker = next(n for n in data["nodes"] if n["name"] == "kicker")
    kicker["tx_queue"] = "fifo"
    report = check_data(tmp_path, data)
    assert [e["code"] for e in report["errors"]] == ["tx-queue"]
    assert "kicker" in report["errors"][0]["message"] and "battery_status" in report["errors"][0]["message"]


def test_can_fd_fifo_uses_the_same_bound(tmp_path: Path) -> None:
    """The inversion spec on a CAN FD bus (1 Mbit/s arbitration, 2 Mbit/s data, frames without bit-rate switch): the
    FIFO bound has the same terms, each frame at its CAN FD worst-case time (the report's tx_us, from the timing
    core): high = B (log) + C_high + C_low + C_mid (once), as in test_fifo_bound_by_hand."""
    data = _spec()
    data["buses"][0].update(protocol="can-fd", data_bitrate="2 Mbit/s")
    can0 = bus(check_data(tmp_path, data), "can0")
    c = {m["name"]: m["tx_us"] for m in can0["messages"]}
    assert message(can0, "high")["wcrt_us"] == c["log"] + c["high"] + c["low"] + c["mid"]
    assert message(can0, "low")["wcrt_us"] == message(can0, "high")["wcrt_us"]


def test_a_fifo_bound_with_bit_errors_by_hand() -> None:
    """test_fifo_bound_by_hand with at most one bit error per 10 ms (no burst): each error costs an error frame of 31
    bits (31 us at 1 Mbit/s) and the resending of the longest frame on the bus (135 us), and a window up to 10 ms
    holds ceil(t / 10 ms) = 1 of them: w = 135 + 270 - 135 + 135 (mid, once: ceil((571 + 1) / 997) = 1) + 166 =
    571 us, R = 571 + 135 = 706 us."""
    from netcfg.timing.can_errors import ErrorModel

    tau = US
    frames = [
        can_rta.CanFrame("low", 0x300, False, C8, 10_000 * US),
        can_rta.CanFrame("high", 0x010, False, C8, 10_000 * US),
        can_rta.CanFrame("mid", 0x100, False, C8, 997 * US),
        can_rta.CanFrame("log", 0x400, False, C8, 701 * US),
    ]
    errors = ErrorModel.for_bus(0, 10_000 * US, 1_000_000)
    res = can_fifo.analyse(
        frames, tau, {"low": "host", "high": "host"}, lambda fs: can_rta.analyse(fs, tau, 0, errors), 0, errors
    )
    assert res.queues["host"].queue_ns == 706 * US
    assert res.responses["high"].wcrt_ns == 706 * US


@pytest.mark.parametrize(
    ("queue", "expected"),
    [
        ({"depth": 16, "on_full": "drop"}, "depth and on_full describe a FIFO queue: add 'policy: fifo'"),
        ({"policy": "fifo", "depth": 0}, "greater than or equal to 1"),
        ("fifa", "did you mean 'fifo'?"),
    ],
)
def test_a_mistaken_tx_queue_gets_one_error(tmp_path: Path, queue: Any, expected: str) -> None:
    """Each mistake is named once: depth without a FIFO used to be ignored silently, and the word and the mapping
    forms each reported the same mistake."""
    data = {
        "system": "q",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": "500k"}],
        "nodes": [{"name": "a", "buses": ["can0"], "tx_queue": queue}, {"name": "b", "buses": ["can0"]}],
        "messages": [{"name": "m1", "id": 0x100, "producer": "a", "consumers": ["b"], "size": 8, "period": "1 ms"}],
    }
    (err,) = check_data(tmp_path, data)["errors"]
    assert expected in err["message"]


def test_a_fifo_bound_shows_its_error_term(tmp_path: Path) -> None:
    """ALLEX-2's master FIFO with one error burst and one error per 10 ms: the bound's terms are blocking 65 +
    the whole queue 1,315 + other nodes' frames above ankle_r_interp 1,500 (six 135 us TPDO1s, six 115 us
    TPDO2s) + E(w + C_MIN); with w + C_MIN = 3,212 us, E = (1 + ceil(3,212 / 10,000)) x (31 us error frame + the
    bus's longest frame, 135 us) = 2 x 166 = 332 us, so the bound is 65 + 1,315 + 1,500 + 332 = 3,212 us. The
    error term is its own figure (it was counted as other nodes' frames), and each member's row carries it."""
    data = yaml.safe_load((Path(__file__).parent.parent / "specs" / "allex2.yaml").read_text(encoding="utf-8"))
    data["buses"][0]["errors"] = {"burst": 1, "interval": "10 ms"}
    report = check_data(tmp_path, data)
    (q,) = bus(report, "can0")["tx_queues"]
    assert (q["blocking_us"], q["queued_us"], q["interference_us"], q["error_us"]) == (65, 1315, 1500, 332)
    assert q["queue_us"] == 3212
    assert message(bus(report, "can0"), "hip_l_cmd")["error_us"] == 332


def test_a_frame_below_an_unbounded_fifo_says_why(tmp_path: Path) -> None:
    """wrong_order.yaml with its ECU sending through a FIFO: the ECU's messages wait longer than their periods, so
    its queue has no bound (the paper's premise fails), and every frame below its highest-priority message can meet
    it any number of times. motor_status (0x101, from the motor) is such a frame: check says another node's FIFO is
    the cause and drops the figures of the discarded bound; --explain says the same instead of deriving a bound."""
    data = yaml.safe_load((Path(__file__).parent.parent / "examples" / "wrong_order.yaml").read_text(encoding="utf-8"))
    next(n for n in data["nodes"] if n["name"] == "ecu")["tx_queue"] = "fifo"
    spec = tmp_path / "wo.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    report = check_data(tmp_path, data)
    row = message(bus(report, "body"), "motor_status")
    assert (row["wcrt_us"], row["busy_period_us"], row["instances"], row["unbounded"]) == (None, None, 0, "fifo")
    text = next(e["message"] for e in report["errors"] if "'motor_status'" in e["message"])
    assert "another node's FIFO transmit queue" in text
    explained = cli("check", str(spec), "--explain", "motor_status")
    assert "another node's FIFO transmit queue with a message above it has no bound" in explained.stdout
