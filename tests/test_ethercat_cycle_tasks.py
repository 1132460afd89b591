"""Tasks on an EtherCAT cycle (`sync: true`): the master's a fixed offset after each cycle's start, a DC slave's at
its SYNC0. A flow through them and the segment's PDOs is walked cycle by cycle (netcfg.protocols.ethercat.flow),
checked here against a hand calculation of that walk and against the simulator, which starts those tasks the same
way (netcfg.sim.ethercat); the resolver's errors for a task that has no cycle to run on."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest

from netcfg.sim.montecarlo import run_once
from netcfg.sim.results import summary
from netcfg.sim.scenario import SimOptions
from tests.conftest import check_data, runtime_config_of
from tests.test_ethercat import errors, spec

C = 0.7 * 299_792_458  # cables at 0.7 c (netcfg.timing.ethernet)
AXIS = [{"index": 0x1600, "map": [0x6040, 0x607A]}, {"index": 0x1A00, "map": [0x6041, 0x6064]}]  # 6 bytes each way
CYCLE, JITTER, SHIFT, DC = 1_000_000, 20_000, 500_000, 100  # DC: distributed clocks' precision, 100 ns
OFFSET, BCET, WCET = 100_000, 10_000, 50_000  # the master's control task


def loop_spec(tmp_path: Path, **control: Any) -> dict[str, Any]:
    """Two CiA 402 axes (no ESI: RJ45 slaves, 2 us each) on 10 m and 20 m of cable; d1's position to the master's
    control task on the cycle, its target back to d1, latched by d1's task at SYNC0."""
    slaves = [{"node": f"d{i}", "profile": "cia402", "pdos": copy.deepcopy(AXIS), "cable": m}
              for i, m in enumerate((10.0, 20.0))]
    data = spec(tmp_path, slaves, sync0_shift="500 us", master_jitter="20 us")
    nodes = {n["name"]: n for n in data["nodes"]}
    nodes["pc"]["tasks"] = [{"name": "control", "sync": True, "offset": "100 us", "bcet": "10 us", "wcet": "50 us",
                             **control}]
    nodes["d1"]["tasks"] = [{"name": "latch", "sync": True, "wcet": "10 us"}]
    data["messages"] = [
        {"name": "d1_pos", "bus": "ecat", "producer": "d1", "consumers": ["pc"], "pdo": {"tpdo": 1, "map": [0x6064]}},
        {"name": "d1_target", "bus": "ecat", "producer": "pc", "consumers": ["d1"],
         "pdo": {"rpdo": 1, "map": [0x607A]}},
    ]
    data["flows"] = [{"name": "loop", "chain": ["d1_pos", "pc.control", "d1_target", "d1.latch"]}]
    return data


# The walk by hand. The image is 12 bytes out, then 12 in (d1's inputs at logical 18); one frame, 84 bytes on the
# wire, 6,720 ns. Cables to d1: 30 m at 0.7 c, 142.95 ns.
CABLES = 30 / C * 1e9
READ = (8 + 14 + 2 + 10 + 18) * 80  # preamble and SFD, Ethernet, EtherCAT and datagram headers, 18 bytes: 4,160 ns
# d1's inputs are read between the read and the cables after the cycle's start and J and both slaves' 2 us later
TAKE_LO = READ + round(CABLES)  # 4,303
TAKE_HI = JITTER + TAKE_LO + 2 * 2000  # 28,303
IN_BEST = int(6720 - READ + CABLES)  # from the read: the rest of the frame and the cables back, 2,702
IN_WORST = JITTER + 6720 + 2 * 2000 + round(2 * CABLES)  # back at the master: 31,006
OUT_BEST = int(6720 + CABLES)  # the RxPDO from the send to d1: 6,862
OUT_WORST = round(JITTER + 6720 + 2 * 2000 + CABLES)  # the frame has passed d1: 30,863
RESPONSE = WCET  # alone on the master: its response from its activation is its WCET
# Cycle 0: the read starts the flow between TAKE_LO and TAKE_HI; at the master by 31.006 us, before the control
# task's earliest start (100 us): it runs in cycle 0, starts by 120 us (its offset and J), ends by 170 us. The next
# frame (cycle 1, sent at 1,000 us at the earliest) takes the target and delivers it by 1,030.863 us; d1's SYNC0
# comes at 1,500 us +- 0.1 us, when the latch takes it. At best the same cycles: the earliest SYNC0, less the
# latest read.
LATENCY = (CYCLE + SHIFT - DC - TAKE_HI, CYCLE + SHIFT + DC - TAKE_LO)  # 1,471.597 - 1,495.797 us
# the target at d1: from the latest read, the earliest send of cycle 1 (its data ready at 110 us) and the RxPDO's
# best; from the earliest read, cycle 1's latest delivery
DELIVERY = (CYCLE + OUT_BEST - TAKE_HI, CYCLE + OUT_WORST - TAKE_LO)  # 978.559 - 1,026.56 us


def test_the_walk_by_hand(tmp_path: Path) -> None:
    report = check_data(tmp_path, loop_spec(tmp_path))
    assert not report["errors"], report["errors"]
    (ecat,) = report["buses"]
    rows = {m["name"]: m for m in ecat["messages"]}
    assert rows["d1_pos"]["read_offset_ns"] == READ
    assert (rows["d1_pos"]["best_us"], rows["d1_pos"]["wcrt_us"]) == (IN_BEST / 1000, IN_WORST / 1000)
    assert (rows["d1_target"]["best_us"], rows["d1_target"]["wcrt_us"]) == (OUT_BEST / 1000, OUT_WORST / 1000)
    (flow,) = report["flows"]
    assert flow["mode"] == "synchronised"
    assert tuple(flow["latency_ns"]) == LATENCY == (1_471_597, 1_495_797)
    sync = flow["synchronised"]
    assert (sync["delivery_min_us"], sync["delivery_max_us"]) == (DELIVERY[0] / 1000, DELIVERY[1] / 1000)
    # free-running, the control task, the frame and the latch may each find the data just missed: over a cycle more
    assert flow["unsynchronised"]["latency_ns"][1] > LATENCY[1] + CYCLE


def test_the_tasks_jitter_is_their_cycles(tmp_path: Path) -> None:
    """The processor analysis activates a task on the cycle up to its cycle's jitter late: the master's send jitter
    (20 us), a DC slave's twice distributed clocks' precision (SYNC0 up to 100 ns either way)."""
    report = check_data(tmp_path, loop_spec(tmp_path))
    tasks = {(n["name"], t["name"]): t for n in report["nodes"] for t in n["tasks"]}
    assert tasks[("pc", "control")]["jitter_us"] == JITTER / 1000
    assert tasks[("pc", "control")]["wcrt_us"] == (JITTER + RESPONSE) / 1000
    assert tasks[("d1", "latch")]["jitter_us"] == 2 * DC / 1000
    assert tasks[("d1", "latch")]["interval_us"] == CYCLE / 1000


def simulated_loop(tmp_path: Path, mode: str = "auto") -> dict[str, Any]:
    cfg = runtime_config_of(tmp_path / "spec.yaml", loop_spec(tmp_path))
    (flow,) = summary(run_once(cfg, SimOptions(duration_ns=2_000_000_000, seed=3, mode=mode))[1])["flows"]
    return flow  # type: ignore[no-any-return]


def test_the_simulator_keeps_to_the_walk(tmp_path: Path) -> None:
    """The simulator starts the master's task a draw in [0, J] after its offset and d1's at its SYNC0 (its DC error
    within 100 ns): every latency it sees lies in the walk's range, and over 2,000 cycles they spread over most of
    it (the reads' and the starts' draws)."""
    flow = simulated_loop(tmp_path)
    lo, hi = flow["latency_us"]["min"] * 1000, flow["latency_us"]["max"] * 1000
    assert flow["within_analysis"] and LATENCY[0] <= lo <= hi <= LATENCY[1]
    assert hi - lo > 0.8 * (LATENCY[1] - LATENCY[0])


def test_unsynchronised_the_tasks_run_free(tmp_path: Path) -> None:
    """`--mode unsync`: the tasks run on their nodes' clocks at the cycle's period, held to the free-running bound."""
    flow = simulated_loop(tmp_path, "unsync")
    assert flow["within_analysis"]
    assert flow["analysis_us"]["max"] > (LATENCY[1] + CYCLE) / 1000


@pytest.mark.parametrize(
    ("change", "code", "words"),
    [
        ({"period": "2 ms"}, "task-period", "runs every EtherCAT cycle (1 ms); drop its period"),
        ({"offset": "1 ms"}, "offset", "smaller than the EtherCAT cycle period 1 ms"),
        ({"on_message": "d1_pos"}, "task-sync", "either on EtherCAT cycle or on a message"),
    ],
)
def test_a_master_task_on_the_cycle_is_checked(tmp_path: Path, change: dict[str, Any], code: str, words: str) -> None:
    found = errors(check_data(tmp_path, loop_spec(tmp_path, **change)))
    assert [(c, words in text) for c, text, _ in found] == [(code, True)], found


def test_a_slave_without_sync0_has_no_cycle_for_its_tasks(tmp_path: Path) -> None:
    data = loop_spec(tmp_path)
    data["buses"][0]["ethercat"]["slaves"][1]["assign_activate"] = 0  # free run: no SYNC0
    found = errors(check_data(tmp_path, data))
    assert [c for c, _, _ in found] == ["task-sync"]
    assert "an EtherCAT bus it is the master or a DC slave of (it is on 0)" in found[0][1]


def test_a_pdo_over_64_bits_reaches_the_simulator(tmp_path: Path) -> None:
    """An EtherCAT PDO is no CAN frame: runtime.json's loader takes d1's 80-bit TxPDO (statusword, position and
    velocity actual values: 16 + 32 + 32 bits), which it once refused as over CiA 301's 8 bytes."""
    data = loop_spec(tmp_path)
    data["buses"][0]["ethercat"]["slaves"][1]["pdos"][1]["map"] = [0x6041, 0x6064, 0x606C]
    cfg = runtime_config_of(tmp_path / "spec.yaml", data)
    pdo = next(m for m in cfg.messages if m.name == "d1_pos").pdo
    assert pdo is not None and sum(e.bits for e in pdo.entries) == 80


def test_the_best_case_does_not_follow_the_latest_read(tmp_path: Path) -> None:
    """The master's wake-up and its frame's send are drawn apart: with the control task at offset 0 and a BCET (30 us)
    over the jitter, a cycle whose frame left early and came back by ~10 us finds its task still to start (up to
    20 us late), which takes that cycle's position and ends in time for the next frame: d1's SYNC0 one cycle on. A
    walk from the latest read alone misses that cycle: it would have the best case a cycle later, 2,471.597 us (the
    defect a random segment showed). Both paths go from the earliest read; the best case is the earliest end less
    the latest read.

    By hand: read at 4.303 us, back by 7.005 at the earliest; the task may start then (its window 0-20 us), ends
    after 30 us; cycle 1's frame takes the target (sent at 1,000 us at the earliest); SYNC0 at 1,499.9 us. Less the
    latest read (28.303 us): 1,471.597 us. At worst the position is back at 31.006 us, after the task's latest start
    (20 us): cycle 1's task, ending by 1,070 us, after cycle 1's earliest send: cycle 2's frame, SYNC0 by 2,500.1 us,
    from the earliest read: 2,495.797 us."""
    data = loop_spec(tmp_path, offset="0 us", bcet="30 us")
    (flow,) = check_data(tmp_path, data)["flows"]
    assert tuple(flow["latency_ns"]) == (CYCLE + SHIFT - DC - TAKE_HI, 2 * CYCLE + SHIFT + DC - TAKE_LO)
    cfg = runtime_config_of(tmp_path / "spec.yaml", data)
    (run,) = summary(run_once(cfg, SimOptions(duration_ns=2_000_000_000, seed=3))[1])["flows"]
    assert run["within_analysis"]
    assert run["latency_us"]["min"] * 1000 < 2 * CYCLE + SHIFT - DC - TAKE_HI  # the cycle a latest-read walk misses


def test_a_slave_s_shift_lies_inside_the_sync0_cycle(tmp_path: Path) -> None:
    """As the bus's own shift must: a SYNC0 1.5 ms after a 1 ms SYNC0 cycle's start is no instant of that cycle."""
    data = loop_spec(tmp_path)
    data["buses"][0]["ethercat"]["slaves"][1]["sync0_shift"] = "1500 us"
    found = errors(check_data(tmp_path, data))
    words = "its SYNC0 shift must lie inside the SYNC0 cycle (1000 us)"
    assert [(c, words in t) for c, t, _ in found] == [("dc", True)]


def test_a_task_instant_past_the_cycle_takes_the_next_cycle_s_frame(tmp_path: Path) -> None:
    """The control task at offset 999 us starts up to 1,019 us after its cycle's start (J = 20 us): past the next
    cycle's start, so the frame of that next cycle, back by ~11 us when sent early, may bring it the position. The
    walk looks at the cycle before as well (a review found it did not, and put the best case at 970.697 us).

    By hand, from the earliest read (4.303 us): the position is at the master by 7.005 us, and the previous cycle's
    task may still start until 19 us: at best the position's own best, 2.702 us. At worst it is back at 31.006 us,
    after that task's earliest start (-1 us), so this cycle's task takes it, starting by 1,019 us: 1,014.697 us."""
    data = loop_spec(tmp_path, offset="999 us")
    data["flows"] = [{"name": "read", "chain": ["d1_pos", "pc.control"]}]
    (flow,) = check_data(tmp_path, data)["flows"]
    assert flow["mode"] == "synchronised"
    assert tuple(flow["latency_ns"]) == (IN_BEST, OFFSET_999 + JITTER - TAKE_LO) == (2_702, 1_014_697)
    cfg = runtime_config_of(tmp_path / "spec.yaml", data)
    (run,) = summary(run_once(cfg, SimOptions(duration_ns=2_000_000_000, seed=3))[1])["flows"]
    assert run["within_analysis"] and run["latency_us"]["min"] * 1000 < 970_697


OFFSET_999 = 999_000


def two_cycles(tmp_path: Path, sync: bool | str) -> list[tuple[str, str, int | None]]:
    """The master of the segment is also on a CANopen bus, whose SYNC is a second cycle for its tasks."""
    data = loop_spec(tmp_path, sync=sync, offset="300 us")  # after CANopen's read window, as its master needs
    data["buses"].append({"name": "co", "protocol": "canopen", "bitrate": "1 Mbit/s",
                          "canopen": {"sync_period": "10 ms", "read_window": "200 us"}})
    data["nodes"][0]["buses"].append("co")
    data["nodes"][0]["node_id"] = 1
    return errors(check_data(tmp_path, data))


def test_a_node_with_two_cycles_names_the_bus(tmp_path: Path) -> None:
    (found,) = two_cycles(tmp_path, True)
    assert found[0] == "task-sync" and "(it is on 2): name the bus ('sync: ecat')" in found[1]
    assert two_cycles(tmp_path, "ecat") == []
    # on CANopen's 10 ms SYNC the task runs, and the loop is walked free-running (its offset is CANopen's)
    assert two_cycles(tmp_path, "co") == []
    (found,) = two_cycles(tmp_path, "d1")
    assert found[0] == "task-sync" and "which has none for 'pc' (its buses with one: 'ecat', 'co')" in found[1]
