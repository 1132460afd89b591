"""Where FTT-CAN's trigger message meets real stuffing: a real trigger message (TM) carries fewer stuff bits than
its worst case most of the time, so the tasks it triggers start earlier, by an amount that changes from EC to EC.

CAMBADA's lower-level bus (specs/cambada.yaml: 250 kbit/s, 5-byte TM, 11-bit identifier). ISO 11898-1's frame:
47 + 8 * 5 = 87 bits without stuff bits, 87 + (34 + 40 - 1) // 4 = 105 bits at worst: 348 us to 420 us, so a TM
may end up to 72 us before its worst-case end (the schedule's tm_early_ns). A flow from a triggered task to a
triggered task spans whole ECs from one TM's end to another's, so it may be 72 us shorter or longer:
odometry_integration (three ECs) is 15,000 - 72 .. 15,000 + 72 us.

Before the analysis took the TM's shorter lengths, `netcfg simulate specs/cambada.yaml --stuffing exact` (each
frame's stuff bits counted from its bits) measured odometry_integration at 14,996..15,012 us against an analysed
15,000..15,000 us, and motion from 27,280 us against an analysed minimum of 27,320 us.
"""

from __future__ import annotations

from pathlib import Path

from conftest import check, runtime_config

from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import summary
from netcfg.sim.scenario import SimOptions

SPEC = Path(__file__).resolve().parent.parent / "specs" / "cambada.yaml"
S = 1_000_000_000
TM_WORST_US, TM_SHORTEST_US = 105 * 4, 87 * 4  # bits at 250 kbit/s: 4 us each


def test_a_flow_between_triggered_tasks_spans_the_tms_shorter_lengths() -> None:
    report = check(SPEC)
    bus = next(b for b in report["buses"] if b["name"] == "lowlevel")
    assert bus["ftt"]["tm_us"] == TM_WORST_US
    flow = next(f for f in report["flows"] if f["name"] == "odometry_integration")["synchronised"]
    early = TM_WORST_US - TM_SHORTEST_US
    assert (flow["latency_min_us"], flow["latency_max_us"]) == (15_000 - early, 15_000 + early)


def test_flows_hold_with_exactly_stuffed_frames() -> None:
    result = summary(run_once(runtime_config(SPEC), SimOptions(duration_ns=2 * S, seed=0, stuffing="exact"))[1])
    assert [v for v in result["violations"] if v.startswith("flow")] == []


def test_the_trigger_message_is_a_standard_frame_on_a_29_bit_bus(tmp_path: Path) -> None:
    """netcfg.protocols.ftt.tm: the TM's identifier is standard on every bus, as seed 002's CAN 2.0A frame. On CAMBADA
    with 29-bit identifiers the analysis times the same 105-bit, 420 us frame as on the 11-bit bus (an extended
    identifier would add 20 bits before stuffing), and the simulator sends that frame: its TM takes 420 us at
    worst-case stuffing, the figure check reports."""
    from conftest import check_data, load_spec, runtime_config_of

    data = load_spec("cambada.yaml")
    bus_spec = next(b for b in data["buses"] if b["name"] == "lowlevel")
    bus_spec["id_bits"] = 29
    bus_spec["ftt"].pop("lsw", None)  # the longer extended frames need the whole EC after the TM
    report = check_data(tmp_path, data)
    bus = next(b for b in report["buses"] if b["name"] == "lowlevel")
    assert bus["ftt"]["tm_us"] == TM_WORST_US
    cfg = runtime_config_of(tmp_path / "cambada29.yaml", data)
    result = summary(run_once(cfg, SimOptions(duration_ns=S // 10, seed=0))[1])
    tm = next(m for m in result["messages"] if m["name"] == "lowlevel_TM")
    assert tm["response_us"]["max"] == TM_WORST_US
