"""FTT-CAN asynchronous window and CANopen SYNC cycles on small networks with hand-worked numbers."""

from __future__ import annotations

from pathlib import Path

import yaml
from conftest import bus, check_data, message

from netcfg.check import analyse_spec
from netcfg.emit import c_header


def ftt_spec() -> dict:
    return {
        "system": "ftt_small",
        "buses": [
            {
                "name": "f",
                "protocol": "ftt-can",
                "bitrate": "1 Mbit/s",
                "ftt": {"ec": "1 ms", "tm_size": 1, "lsw": "500 us"},
            }
        ],
        "nodes": [
            {"name": "m", "role": "master", "buses": ["f"]},
            {"name": "a", "buses": ["f"]},
            {"name": "b", "buses": ["f"]},
        ],
        "messages": [
            {"name": "s", "producer": "a", "consumers": ["b"], "size": 8, "period": "1 EC"},
            {"name": "x", "id": 0x200, "producer": "a", "consumers": ["b"], "size": 8, "min_interarrival": "100 ms"},
            {"name": "y", "id": 0x201, "producer": "b", "consumers": ["a"], "size": 8, "min_interarrival": "100 ms"},
        ],
    }


def test_asynchronous_window_response(tmp_path: Path) -> None:
    """EC 1 ms at 1 Mbit/s; TM of 1 byte = 65 bits = 65 us; synchronous 's' (8 B, 135 us) in every EC.
    Asynchronous window: 1000 - 65 - 135 = 800 us, of which 800 - 135 = 665 us usable (an asynchronous frame
    only starts if it ends before the synchronous window: up to one longest frame, 135 us, of idle time).
    'y' (lower priority) is released just too late for EC k's window (at 65 + 665 = 730 us into it) and needs
    its own 135 us plus one 'x' (135 us): served from 1065 us to 1335 us, a response of 605 us. 'x' needs its
    frame plus, conservatively, one lower-priority frame already started (135 + 135 = 270 us of demand): released
    at 730 us it waits for EC k+1's window at 1000 + 65 = 1065 us and is served by 1065 + 270 = 1335 us, a
    response of 1335 - 730 = 605 us as well.
    'x' and 'y' are sporadic with 100 ms: one instance each in that window."""
    report = check_data(tmp_path, ftt_spec())
    assert report["ok"], report["errors"]
    f = bus(report, "f")
    assert f["ftt"]["tm_us"] == 65.0
    assert message(f, "y")["wcrt_us"] == 605.0
    assert message(f, "x")["wcrt_us"] == 605.0
    assert message(f, "s")["wcrt_us"] == 1000.0  # the synchronous window closes the EC
    assert [ec["async_us"] for ec in f["ftt"]["ecs"]] == [800.0]


def test_trigger_message_capacity_and_lsw(tmp_path: Path) -> None:
    """A 1-byte TM announces FTT ids 0..7; an LSW longer than EC - TM cannot be."""
    spec = ftt_spec()
    spec["buses"][0]["ftt"]["lsw"] = "950 us"  # 950 + 65 > 1000
    report = check_data(tmp_path, spec)
    assert [e["code"] for e in report["errors"]] == ["lsw"]


def test_lsw_defaults_to_ec_minus_tm_everywhere(tmp_path: Path) -> None:
    """Without 'lsw' the synchronous window may fill the EC after the TM: 1000 - 65 = 935 us (the 65 us TM of
    test_asynchronous_window_response). The report says so also when the periods (7 and 11 ... 19 ECs, LCM
    323,323 above the table limit ftt.MAX_MACRO_CYCLE) give no table, and the node headers carry the value."""
    spec = ftt_spec()
    del spec["buses"][0]["ftt"]["lsw"]
    path = tmp_path / "ftt.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    model, report = analyse_spec(path)
    assert model is not None and report["ok"], report["errors"]
    assert bus(report, "f")["ftt"]["lsw_us"] == 935.0
    assert "#define BUS_F_LSW_NS UINT32_C(935000)" in c_header.emit(model, report)["c/a.h"].decode()
    spec["messages"] += [
        {"name": f"p{n}", "producer": "a", "consumers": ["b"], "size": 1, "period": f"{n} EC"}
        for n in (7, 11, 13, 17, 19)
    ]
    report = check_data(tmp_path, spec)
    assert [e["code"] for e in report["errors"]] == ["macro-cycle"]
    assert bus(report, "f")["ftt"]["lsw_us"] == 935.0


def canopen_spec() -> dict:
    return {
        "system": "co_small",
        "buses": [
            {
                "name": "c",
                "protocol": "canopen",
                "bitrate": "500 kbit/s",
                "canopen": {"sync_period": "10 ms", "sync_window": "5 ms"},
            }
        ],
        "nodes": [
            {"name": "master", "role": "master", "node_id": 100, "buses": ["c"]},
            {"name": "d1", "node_id": 1, "device": "epos4", "buses": ["c"]},
            {"name": "d2", "node_id": 2, "device": "epos4", "buses": ["c"]},
        ],
        "messages": [
            {
                "name": "d1_pos",
                "producer": "d1",
                "consumers": ["master"],
                "pdo": {"tpdo": 1, "transmission": 1, "map": [0x6064, 0x606C]},
            },
            {
                "name": "d2_pos",
                "producer": "d2",
                "consumers": ["master"],
                "pdo": {"tpdo": 1, "transmission": 2, "map": [0x6064, 0x606C]},
            },
            {
                "name": "d1_status",
                "producer": "d1",
                "consumers": ["master"],
                "pdo": {"tpdo": 2, "transmission": 255, "inhibit": "10 ms", "map": [0x6041]},
            },
        ],
    }


def test_sync_cycles_follow_transmission_types(tmp_path: Path) -> None:
    """At 500 kbit/s (2 us per bit): SYNC 55 bits = 110 us, an 8-byte TPDO 135 bits = 270 us, the 2-byte
    event-driven status (inhibit 10 ms: at most every 10 ms) 75 bits = 150 us; blocking by the longest frame, 270 us.
    Cycle 0 (d1_pos and d2_pos, type 1 and type 2): 270 + 110 + 2 x 270 + 150 = 1070 us.
    Cycle 1 (d1_pos only): 270 + 110 + 270 + 150 = 800 us. Both within the 5 ms window."""
    report = check_data(tmp_path, canopen_spec())
    assert report["ok"], report["errors"]
    c = bus(report, "c")
    assert [(cy["tpdos"], cy["completion_us"]) for cy in c["sync"]["cycles"]] == [(2, 1070.0), (1, 800.0)]
    assert message(c, "d2_pos")["period_us"] == 20_000.0  # every 2nd SYNC of 10 ms
    status = message(c, "d1_status")
    assert status["kind"] == "sporadic" and status["interval_us"] == 10_000.0  # the inhibit time bounds it


def test_tpdo_period_contradicting_the_transmission_type(tmp_path: Path) -> None:
    spec = canopen_spec()
    spec["messages"][1]["period"] = "10 ms"  # type 2 means every 2nd SYNC: 20 ms
    report = check_data(tmp_path, spec)
    err = report["errors"][0]
    assert err["code"] == "period" and "every 20 ms" in err["message"]
