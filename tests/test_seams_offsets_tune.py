"""Where features meet, and every command agrees: FTT-CAN's trigger message outranks every frame (seam 08), offsets on
CAN FD buses, offsets the analysis cannot use, and `netcfg tune` on CAN FD buses and DBCs (tune -> check)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml
from conftest import ROOT, SPECS, check, cli

SEAMS = ROOT / "tests" / "data" / "seams"
DBC = ROOT / "tests" / "data" / "dbc"


def _at(path: Path, needle: str, value: str, after: str | None = None) -> tuple[int, int]:
    """(line, column) of `value` on the first line of `path` holding `needle` (after the first line holding
    `after`), 1-based as netcfg reports them."""
    seen = after is None
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        seen = seen or after in line  # type: ignore[operator]
        if seen and needle in line:
            return number, line.index(value) + 1
    raise AssertionError(f"{needle!r} not in {path}")


def _wcrt(report: dict[str, Any]) -> dict[str, float | None]:
    return {m["name"]: m["wcrt_us"] for b in report["buses"] for m in b["messages"]}


def _write(tmp_path: Path, data: dict[str, Any], name: str = "spec.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


# -- 1. seam 08: an identifier that outranks FTT-CAN's trigger message ------------------------------------------
def test_seam_08_an_async_id_above_the_trigger_message_is_refused_at_its_id(tmp_path: Path) -> None:
    """Seam 08: x0 (id 0x010) outranks the TM (tm_id 0x050), wins arbitration at an EC's start and delays the TM by
    up to its own 540 us frame (8 bytes, 135 bits at 250 kbit/s): the flow f, analysed at exactly 2,000 us, measured
    1,460-2,540 us. check must refuse it, once, at x0's id, naming the rule and the fix."""
    spec = SEAMS / "08-ftt-tm-outranked-by-async.yaml"
    run = cli("check", str(spec))
    assert run.returncode == 1 and "Traceback" not in run.stderr
    report = check(spec)
    assert [e["code"] for e in report["errors"]] == ["ftt-tm-id"]
    err = report["errors"][0]
    assert (err["line"], err["column"]) == _at(spec, "name: x0", "0x010")
    assert "highest priority" in err["message"] and "above 0x050" in err["message"]
    # the same spec with x0 below the TM (0x060): accepted, and the simulated flow stays inside 2,000 .. 2,000 us
    fixed = tmp_path / "08-fixed.yaml"
    fixed.write_text(spec.read_text().replace("id: 0x010, window: async", "id: 0x060, window: async"))
    assert check(fixed)["ok"]
    sim = cli("simulate", str(fixed), "--duration", "2s", "--runs", "2", "--format", "json")
    assert sim.returncode == 0, sim.stdout[-2000:]
    flow = json.loads(sim.stdout)["flows"][0]
    assert flow["latency_us"]["min"] == flow["latency_us"]["max"] == 2000.0


def test_a_derived_synchronous_id_above_the_trigger_message_points_at_the_message(tmp_path: Path) -> None:
    """A synchronous message without an id takes sync_id_base (default 0x100) + its FTT id: with tm_id 0x150, s1's
    0x100 outranks the TM. The error points at the message (it has no id line) and names sync_id_base."""
    data = yaml.safe_load((SEAMS / "08-ftt-tm-outranked-by-async.yaml").read_text())
    data["buses"][0]["ftt"]["tm_id"] = 0x150
    data["messages"][1]["id"] = 0x160  # x0 below the TM
    path = _write(tmp_path, data)
    report = check(path)
    assert [e["code"] for e in report["errors"]] == ["ftt-tm-id"]
    err = report["errors"][0]
    assert err["line"] == _at(path, "name: s1", "name")[0] and "sync_id_base" in err["message"]
    assert "0x100" in err["message"]


def test_cambada_still_passes() -> None:
    """CAMBADA keeps the default tm_id 0 and its synchronous ids from 0x100: nothing outranks its TM."""
    report = check(SPECS / "cambada.yaml")
    assert report["ok"] and not [d for d in report["errors"] + report["warnings"] if d["code"] == "ftt-tm-id"]


# -- 2. offsets on CAN FD ---------------------------------------------------------------------------------------
THREE: dict[str, Any] = {
    "system": "three_offsets",
    "buses": [{"name": "bus", "protocol": "can-fd", "bitrate": "1 Mbit/s", "data_bitrate": "5 Mbit/s"}],
    "nodes": [{"name": "a", "buses": ["bus"]}, {"name": "b", "buses": ["bus"]}],
    "messages": [
        *(
            {"name": f"s{k}", "id": 0x10 * k, "producer": "a", "consumers": ["b"], "size": 8, "period": "15 ms",
             "offset": f"{5 * (k - 1)} ms"}
            for k in (1, 2, 3)
        ),
        {"name": "blk", "id": 0x300, "producer": "b", "consumers": ["a"], "size": 8, "min_interarrival": "100 ms"},
    ],
}


def test_offsets_count_on_can_fd_as_on_classical_can(tmp_path: Path) -> None:
    """Three 8-byte frames of node a at 0, 5 and 10 ms of 15 ms and node b's sporadic 8-byte blk below them.
    CAN FD 1M/5M, base format, worst case (ISO 11898-1:2015; the field counts of tests/test_frames_canfd.py):
    34 bits at the nominal rate (SOF..BRS 17 + 4 stuff bits + CRC delimiter + ACK, EOF, intermission 12) and
    5 + 64 + 4 + 17 + 6 + 17 = 113 bits at the data rate: C = 34 us + 22.6 us = 56.6 us.
    - With the offsets no two of s1..s3 are queued together (5 ms apart, each done within 113.2 us): each waits
      only for the longest lower-priority frame, B = 56.6 us, R = B + C = 113.2 us; blk (the lowest, B = 0) meets
      at most one of them in any window under 5 ms: R = 56.6 + 56.6 = 113.2 us.
    - Without them (the analysis before, on CAN FD): s1 = B + C = 113.2, s2 = B + C(s1) + C = 169.8,
      s3 = B + C(s1) + C(s2) + C = 226.4 us, and blk = 3 x 56.6 + 56.6 = 226.4 us.
    - Classical CAN at 500 kbit/s: an 8-byte frame is 135 bits (Davis et al. 2007, eq. 1), 270 us: 540 us each."""
    fd = _wcrt(check(_write(tmp_path, THREE, "fd.yaml")))
    assert fd == {"s1": 113.2, "s2": 113.2, "s3": 113.2, "blk": 113.2}
    plain = {**THREE, "messages": [{k: v for k, v in m.items() if k != "offset"} for m in THREE["messages"]]}
    assert _wcrt(check(_write(tmp_path, plain, "fd_plain.yaml"))) == {
        "s1": 113.2,
        "s2": 169.8,
        "s3": 226.4,
        "blk": 226.4,
    }
    classical = {**THREE, "buses": [{"name": "bus", "protocol": "can", "bitrate": "500 kbit/s"}]}
    assert set(_wcrt(check(_write(tmp_path, classical, "can.yaml"))).values()) == {540.0}
    # the simulator, which releases each frame at its offset of a drifting clock, stays inside the bounds
    assert cli("simulate", str(tmp_path / "fd.yaml"), "--duration", "3s", "--runs", "2").returncode == 0


# -- 3. offsets the analysis cannot use -------------------------------------------------------------------------
def _unused(report: dict[str, Any]) -> list[dict[str, Any]]:
    return [w for w in report["warnings"] if w["code"] == "offset-unused"]


def test_an_offset_on_a_message_a_task_sends_is_a_warning_at_the_offset(tmp_path: Path) -> None:
    """cmd is the step after a.ctl in a flow: the task's end releases it, so its `offset: 2 ms` is written to
    runtime.json but no bound uses it. st, released from a's clock, keeps its offset silently."""
    data = {
        "system": "task_sent",
        "buses": [{"name": "bus", "protocol": "can", "bitrate": "500 kbit/s"}],
        "nodes": [
            {"name": "a", "buses": ["bus"], "tasks": [{"name": "ctl", "period": "10 ms", "wcet": "100 us"}]},
            {"name": "b", "buses": ["bus"], "tasks": [{"name": "use", "on_message": "cmd", "wcet": "100 us"}]},
        ],
        "messages": [
            {"name": "cmd", "id": 0x10, "producer": "a", "consumers": ["b"], "size": 8, "period": "10 ms",
             "offset": "2 ms"},
            {"name": "st", "id": 0x20, "producer": "a", "consumers": ["b"], "size": 8, "period": "10 ms",
             "offset": "5 ms"},
        ],
        "flows": [{"name": "f", "chain": ["a.ctl", "cmd", "b.use"]}],
    }
    path = _write(tmp_path, data)
    report = check(path)
    (w,) = _unused(report)
    assert (w["line"], w["column"]) == _at(path, "offset:", "2 ms", after="name: cmd")
    assert "'cmd'" in w["message"] and "a.ctl" in w["message"] and "give the task" in w["message"]
    assert report["ok"]  # a warning, not an error


def test_offsets_on_buses_whose_analysis_cannot_use_them(tmp_path: Path) -> None:
    """Each bus kind whose analysis takes every release at any phase says so at the offset: an FTT-CAN
    asynchronous message, a CANopen PDO (SYNC and the master's loop release it), an Ethernet message."""
    ftt = yaml.safe_load((SEAMS / "08-ftt-tm-outranked-by-async.yaml").read_text())
    ftt["messages"][1].update(id=0x060, type="periodic", period="10 ms", offset="3 ms")
    del ftt["messages"][1]["min_interarrival"]
    (w,) = _unused(check(_write(tmp_path, ftt, "ftt.yaml")))
    assert "asynchronous window" in w["message"] and "window: sync" in w["message"]

    allex = yaml.safe_load((SPECS / "allex2.yaml").read_text())
    allex["messages"][0]["offset"] = "1 ms"
    (w,) = _unused(check(_write(tmp_path, allex, "allex2.yaml")))
    assert allex["messages"][0]["name"] in w["message"] and "CANopen" in w["message"] and "SYNC" in w["message"]

    sahr = yaml.safe_load((SPECS / "ntua_sahr.yaml").read_text())
    sahr["messages"][0]["offset"] = "10 us"
    (w,) = _unused(check(_write(tmp_path, sahr, "sahr.yaml")))
    assert "Ethernet" in w["message"] and sahr["messages"][0]["name"] in w["message"]


def test_offsets_whose_hyperperiod_is_too_long_are_one_warning(tmp_path: Path) -> None:
    """Periods 1, 23 and 29 ms unroll into 667 + 29 + 23 = 719 releases over their 667 ms hyperperiod, more than
    the 512 the offset analysis follows (can_offsets.MAX_JOBS): the node's offsets are taken at any phase. One
    warning, at the first of them."""
    data = {
        "system": "long_hyper",
        "buses": [{"name": "bus", "protocol": "can-fd", "bitrate": "1 Mbit/s", "data_bitrate": "5 Mbit/s"}],
        "nodes": [{"name": "a", "buses": ["bus"]}, {"name": "b", "buses": ["bus"]}],
        "messages": [
            {"name": f"m{i}", "id": 0x10 * i, "producer": "a", "consumers": ["b"], "size": 8, "period": p,
             "offset": o}
            for i, (p, o) in enumerate((("1 ms", "0 ms"), ("23 ms", "500 us"), ("29 ms", "300 us")), 1)
        ],
    }
    (w,) = _unused(check(_write(tmp_path, data)))
    assert "'m1', 'm2', 'm3'" in w["message"] and "512" in w["message"]
    # the same periods on FTT-CAN's synchronous window: the master's schedule places every release, so no warning
    ftt = {
        "system": "ftt_long_hyper",
        "buses": [{"name": "b", "protocol": "ftt-can", "bitrate": "1 Mbit/s", "ftt": {"ec": "1 ms", "tm_size": 1}}],
        "nodes": [{"name": "master", "role": "master", "buses": ["b"]}, *({"name": n, "buses": ["b"]} for n in "ac")],
        "messages": [
            {"name": f"s{i}", "ftt_id": i, "producer": "a", "consumers": ["c"], "size": 8, "period": f"{p} EC",
             "offset": f"{i} EC"}
            for i, p in enumerate((1, 23, 29))
        ],
    }
    report = check(_write(tmp_path, ftt, "ftt.yaml"))
    assert report["ok"] and not _unused(report)


def test_the_shipped_specs_use_every_offset_they_give() -> None:
    for spec in sorted(SPECS.glob("*.yaml")):
        assert not _unused(check(spec)), spec.name


# -- 4. tune on CAN FD, and tune -> check -----------------------------------------------------------------------
def _tune(tmp_path: Path, source: Path, out: str, *extra: str) -> tuple[Path, dict[str, Any]]:
    target = tmp_path / out
    run = cli("tune", str(source), "-o", str(target), "--format", "json", *extra)
    assert run.returncode == 0, run.stderr
    return target, json.loads(run.stdout)


def test_tune_an_accepted_can_fd_spec_lengthens_no_bound(tmp_path: Path) -> None:
    """The closure rule on specs/arm_canfd.yaml, which check accepts: the tuned spec is accepted and no message's
    bound is longer than before. Every message already meets its deadline, so tune keeps the identifiers and says
    so (not FTT-CAN's reason)."""
    before = check(SPECS / "arm_canfd.yaml")
    out, doc = _tune(tmp_path, SPECS / "arm_canfd.yaml", "arm.yaml")
    after = check(out)
    assert before["ok"] and after["ok"]
    was, now = _wcrt(before), _wcrt(after)
    assert all(now[n] is not None and was[n] is not None and now[n] <= was[n] for n in was)  # type: ignore[operator]
    (bus,) = doc["buses"]
    assert "identifiers kept" in " ".join(bus["notes"]) and "synchronous window" not in " ".join(bus["notes"])


FD_WRONG: dict[str, Any] = {
    "system": "fd_wrong_order",
    "buses": [{"name": "bus", "protocol": "can-fd", "bitrate": "1 Mbit/s", "data_bitrate": "5 Mbit/s"}],
    "nodes": [{"name": n, "buses": ["bus"]} for n in ("a", "b", "c")],
    "messages": [
        {"name": "bulk_a", "id": 0x100, "producer": "a", "consumers": ["c"], "size": 64, "period": "10 ms"},
        {"name": "bulk_b", "id": 0x101, "producer": "b", "consumers": ["c"], "size": 64, "period": "10 ms"},
        {"name": "fast", "id": 0x200, "producer": "c", "consumers": ["a"], "size": 8, "period": "1 ms",
         "deadline": "300 us"},
        {"name": "c1", "id": 0x300, "producer": "c", "consumers": ["a"], "size": 8, "period": "10 ms"},
        {"name": "c2", "id": 0x301, "producer": "c", "consumers": ["a"], "size": 8, "period": "10 ms"},
    ],
}


def test_tune_reorders_a_can_fd_bus_that_misses_and_spreads_its_offsets(tmp_path: Path) -> None:
    """CAN FD 1M/5M (ISO 11898-1:2015, worst case): a 64-byte frame is 34 bits at 1 Mbit/s + 678 at 5 Mbit/s =
    169.6 us, an 8-byte one 34 + 113 / 5 = 56.6 us. fast (deadline 300 us) below the two 64-byte frames waits for
    one 8-byte frame of c1/c2 and both bulks: R = 56.6 + 2 x 169.6 + 56.6 = 452.4 us, a miss. On top it waits only
    for the blocking 64-byte frame: R = 169.6 + 56.6 = 226.2 us. Node c's fast, c1 and c2 are released from one
    clock; tune spreads them (c1 and c2 away from fast's 1 ms grid), so each bulk meets at most one of c's frames in
    the window it needs: bulk_b R = B 169.6 + 56.6 + 169.6 = 395.8 us, bulk_a (lowest) 169.6 + 56.6 + 169.6 =
    395.8 us."""
    source = _write(tmp_path, FD_WRONG)
    before = check(source)
    assert not before["ok"] and _wcrt(before)["fast"] == 452.4
    out, doc = _tune(tmp_path, source, "tuned.yaml")
    after = check(out)
    assert after["ok"]
    got = _wcrt(after)
    assert got["fast"] == 226.2 and got["bulk_a"] == got["bulk_b"] == 395.8
    (bus,) = doc["buses"]
    assert {x["name"] for x in bus["offsets"]} >= {"c1", "c2"}
    # and tuning what tune wrote changes nothing: it is accepted, so its identifiers stay
    again, doc2 = _tune(tmp_path, out, "again.yaml")
    assert again.read_text() == out.read_text() and not doc2["buses"][0]["ids"]


def test_tune_of_a_dbc_without_cycle_times_changes_nothing_and_says_so(tmp_path: Path) -> None:
    """toyota_prius_2010_pt.dbc has no GenMsgCycleTime: every message is on-demand, without a deadline, so nothing
    is analysed and nothing may change (tune used to reverse every identifier and report 'check: accepted')."""
    source = DBC / "toyota_prius_2010_pt.dbc"
    out, doc = _tune(tmp_path, source, "t.dbc", "--bitrate", "500k")
    assert out.read_bytes() == source.read_bytes()
    (bus,) = doc["buses"]
    assert not bus["ids"] and "nothing analysed" in " ".join(bus["notes"])


def test_tune_takes_checks_default_period(tmp_path: Path) -> None:
    """`tune F.dbc --default-period T` analyses the DBC as `check F.dbc --default-period T` does: the load tune
    reports before tuning is check's utilisation (every command agrees), and an accepted bus keeps its ids."""
    source = DBC / "toyota_prius_2010_pt.dbc"
    run = cli("check", str(source), "--bitrate", "500k", "--default-period", "100ms", "--format", "json")
    checked = json.loads(run.stdout)
    assert checked["ok"] and checked["buses"][0]["utilization"] > 0
    out, doc = _tune(tmp_path, source, "t100.dbc", "--bitrate", "500k", "--default-period", "100ms")
    (bus,) = doc["buses"]
    assert bus["before"]["load"] == checked["buses"][0]["utilization"] and not bus["ids"]
    assert out.read_bytes() == source.read_bytes()


def test_each_bus_kind_says_its_own_reason_to_keep_its_identifiers(tmp_path: Path) -> None:
    reasons = {}
    for name in ("cambada", "allex2", "ntua_sahr"):
        _, doc = _tune(tmp_path, SPECS / f"{name}.yaml", f"{name}.yaml")
        reasons[name] = " ".join(n for b in doc["buses"] for n in b["notes"])
    assert "synchronous window" in reasons["cambada"]
    assert "CiA 301" in reasons["allex2"] and "synchronous window" not in reasons["allex2"]
    assert "Ethernet" in reasons["ntua_sahr"] and "no priority" in reasons["ntua_sahr"]


def test_tune_a_can_fd_dbc_with_checks_bit_rates(tmp_path: Path) -> None:
    """The wrong-order CAN FD bus above as a DBC (the tuned spec's DBC renumbered back to the original identifiers):
    `check F.dbc --bitrate 1M --data-bitrate 5M` refuses it (fast 452.4 us > 300 us, as by hand above), `tune` with
    the same options renumbers it, and check accepts what it wrote (fast 226.2 us)."""
    from netcfg.tuning import edit_dbc_ids

    tuned, _ = _tune(tmp_path, _write(tmp_path, FD_WRONG), "tuned.yaml")
    assert cli("build", str(tuned), "-o", str(tmp_path / "out")).returncode == 0
    new = {m["name"]: m["id"] for m in yaml.safe_load(tuned.read_text())["messages"]}
    good = (tmp_path / "out" / "dbc" / "bus.dbc").read_text(encoding="latin-1")
    wrong = tmp_path / "wrong.dbc"
    wrong.write_text(edit_dbc_ids(good, {new[m["name"]]: m["id"] for m in FD_WRONG["messages"]}), encoding="latin-1")
    rates = ("--bitrate", "1M", "--data-bitrate", "5M")
    before = json.loads(cli("check", str(wrong), *rates, "--format", "json").stdout)
    assert not before["ok"] and _wcrt(before)["fast"] == 452.4
    fixed, _ = _tune(tmp_path, wrong, "fixed.dbc", *rates)
    after = json.loads(cli("check", str(fixed), *rates, "--format", "json").stdout)
    assert after["ok"] and _wcrt(after)["fast"] == 226.2


def test_tune_of_a_missing_file_is_one_line_and_exit_2(tmp_path: Path) -> None:
    for name in ("missing.yaml", "missing.dbc"):
        run = cli("tune", str(tmp_path / name), "-o", str(tmp_path / f"out{Path(name).suffix}"))
        assert run.returncode == 2 and "Traceback" not in run.stderr and "cannot read" in run.stderr
