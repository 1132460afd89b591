"""The live CANopen master (netcfg.runtime.canopen_master) against simulated drives (netcfg.runtime.drives) that are
real CANopen peers: canopen.LocalNode objects built from the generated EDS files, on python-can's `virtual` bus.

Everything about the network comes from generated/allex2/runtime.json and the EDS/DCF files beside it. Numbers:
- 6 drives, node ids 1-6, 2 synchronous TxPDOs each (12 frames per cycle), SYNC every T = 20 ms, 10 ms read window:
  specs/allex2.yaml, after seed 000 section 4.4.2 ("collecting all the 12 frames or until the time slot for reading
  (10 ms) runs out").
- 400 cycles = 8 s gait cycle / 20 ms (seed 000 section 4.4.2: "the gait cycle lasts 8 s; thus, there are 400
  samples").
- PDO configuration values: runtime.json itself (the read-back must equal it); COB-ID flag bits and transmission type
  meaning: CiA 301 (bit 31 = PDO not valid, bit 30 = no RTR; type n = every n-th SYNC; 255 = on receipt).
- Interpolation time period 0x60C2 = (20, -3): CiA 402, value * 10^index s = the 20 ms SYNC period; runtime.json
  states it as node.sdo_init.
- Expected identity: runtime.json's node.identity, vendor 0x000000FB (maxon: [DeviceInfo] VendorNumber of maxon's
  EPOS4 EDS, netcfg/devices/profiles/epos4.yaml), product code unknown (the built-in profile covers every variant).
- PDO counts: 4 RPDOs and 4 TPDOs (the EPOS4's 0x1400-0x1403 / 0x1800-0x1803, runtime.json node.rpdo_count/tpdo_count).
- SDO abort codes: CiA 301 table 22 (0x06040041 object cannot be mapped, 0x08000022 refused in present state).
- SDO request COB-ID 0x600 + node id: CiA 301 pre-defined connection set (client to server).
- "Transmit buffer full": the can.CanOperationError text of python-can's socketcan bus when the send queue is full.
- 1000 kbit/s: the bus bit rate in specs/allex2.yaml (runtime.json bus.bitrate).
"""

from __future__ import annotations

import csv
import heapq
import itertools
import json
import threading
import uuid
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import can
import canopen
import pytest
from can.interfaces.virtual import VirtualBus
from canopen.sdo import SdoAbortedError
from conftest import ROOT

import netcfg.runtime as rt
from netcfg import cia301
from netcfg.runtime.canopen_master import (
    MasterCycle,
    TimeStats,
    configure_network,
    identities_from_dir,
    identity_from_eds,
    identity_from_runtime,
    interpolation_period,
)
from netcfg.runtime.clock import SystemClock
from netcfg.runtime.drives import DriveBench, ResponseScheduler, SimulatedDrive

pytestmark = pytest.mark.usefixtures("no_leaked_threads")  # conftest.py

GENERATED = ROOT / "generated" / "allex2"
CANOPEN_DIR = GENERATED / "canopen"
JOINTS = ("hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r")  # specs/allex2.yaml, node ids 1..6
CYCLES = 400  # seed 000 section 4.4.2: 8 s gait cycle / 20 ms
FRAMES_PER_CYCLE = 12  # seed 000 section 4.4.2: 6 drives x 2 TxPDOs


@pytest.fixture(scope="module")
def cfg() -> rt.RuntimeConfig:
    return rt.load(GENERATED / "runtime.json")




@pytest.fixture
def channel(request: pytest.FixtureRequest) -> str:
    """A virtual CAN channel no other test shares."""
    return f"netcfg-{request.node.name}-{uuid.uuid4().hex[:8]}"


@pytest.fixture
def master_bus(channel: str) -> Iterator[can.BusABC]:
    bus = can.Bus(interface="virtual", channel=channel)
    yield bus
    bus.shutdown()


def pdo_config(
    cfg: rt.RuntimeConfig, node: str
) -> dict[tuple[str, int], tuple[int, int, tuple[tuple[int, int, int], ...]]]:
    """{(kind, number): (CAN id, transmission type, mapping)} of a node's PDOs as runtime.json gives them."""
    return {
        (m.pdo.kind, m.pdo.number): (m.id, m.pdo.transmission, tuple((e.index, e.sub, e.bits) for e in m.pdo.entries))
        for m in cfg.messages
        if m.pdo is not None and m.pdo.node == node
    }


def read_back_with_canopen(channel: str, node_id: int, eds: Path) -> dict[tuple[str, int], Any]:
    """Read a node's PDO configuration with canopen's own PDO reader (RemoteNode.tpdo/rpdo.read(), over SDO),
    an implementation independent of the master's read-back."""
    network = canopen.Network()
    network.NOTIFIER_CYCLE = 0.05  # so disconnect() does not wait a second for the Notifier
    network.connect(interface="virtual", channel=channel)
    try:
        node = network.add_node(node_id, str(eds))
        node.rpdo.read()
        node.tpdo.read()
        return {
            (kind, number): (p.cob_id, p.enabled, p.trans_type, tuple((v.index, v.subindex, v.length) for v in p.map))
            for kind, maps in (("rpdo", node.rpdo), ("tpdo", node.tpdo))
            for number, p in maps.map.items()
        }
    finally:
        network.disconnect()


def gait_commands(i: int, samples: Mapping[str, Mapping[str, float]]) -> dict[str, dict[str, int]]:
    """Cycle i, joint j: target velocity 100 j + i, velocity offset -j (values that differ per joint and cycle, so a
    frame sent to the wrong drive or answered in the wrong cycle shows)."""
    return {f"{joint}_cmd": {"target_velocity": 100 * j + i, "velocity_offset": -j} for j, joint in enumerate(JOINTS)}


def test_master_configures_six_drives_and_runs_400_cycles(
    cfg: rt.RuntimeConfig, channel: str, master_bus: can.BusABC, tmp_path: Path
) -> None:
    with DriveBench(cfg, CANOPEN_DIR, channel=channel) as bench:
        assert sorted(bench.drives) == sorted(JOINTS)
        # factory state: nothing configured, so every value below comes from the master's SDO writes
        assert all(not valid for _, _, _, valid, _, _ in bench["hip_l"].pdo_slots())

        # the expected identities, COB-IDs, PDO counts and start-up writes: runtime.json alone
        report = configure_network(cfg, master_bus)
        print(report)
        assert report.ok, str(report)
        for joint in JOINTS:
            setup = report.node(joint)
            assert setup.started
            assert setup.identity is not None and setup.identity[0] == 0x000000FB  # checked against node.identity
            assert setup.interpolation == (20, -3)  # CiA 402 0x60C2 for the 20 ms SYNC period
            # node.sdo_init, read back: the 100 ms heartbeat (0x1017), then 0x60C2
            assert setup.start_up == ((0x1017, 0, 100), (0x60C2, 1, 20), (0x60C2, 2, -3))
            assert bench[joint].value(0x60C2, 1) == 20 and bench[joint].value(0x60C2, 2) == -3
            want = pdo_config(cfg, joint)
            # the master's own read-back
            got = {(p.kind, p.number): (p.can_id, p.transmission, p.entries) for p in setup.pdos}
            assert got == want
            assert all(p.valid for p in setup.pdos)
            # canopen's independent read-back over SDO: the configured PDOs enabled as runtime.json says, the
            # predefined ones the spec does not use (RPDO3/4, TPDO3/4) disabled
            node_id = cfg.node(joint).node_id
            assert node_id is not None
            seen = read_back_with_canopen(channel, node_id, CANOPEN_DIR / f"{joint}.eds")
            for key, (can_id, transmission, entries) in want.items():
                assert seen[key] == (can_id, True, transmission, entries), (joint, key)
            assert {key for key, (_, enabled, _, _) in seen.items() if enabled} == set(want)

        # the 400 cycles in virtual time: the same drives, fed each frame as it is sent, so a loaded host cannot
        # push an answer past the read window (the wall-clock timing has its own test below, with a share)
        clock = VirtualClock()
        lockstep = LockstepBus(clock, bench, channel)
        try:
            run = MasterCycle(cfg, lockstep, clock, commands=gait_commands).run(CYCLES)
        finally:
            lockstep.shutdown()

    print()
    print(run.summary())

    assert run.cycles == CYCLES
    assert len(run.expected) == FRAMES_PER_CYCLE
    assert run.missing == 0, run.missing_by_message()
    assert run.missing_by_node() == dict.fromkeys(JOINTS, 0)
    assert {joint: run.complete_samples(joint) for joint in JOINTS} == dict.fromkeys(JOINTS, CYCLES)
    assert run.late == 0
    # end to end: RxPDO1 (type 255, applied on receipt) goes out before the SYNC in Figure 7's order, so the TxPDO1
    # answering cycle i's SYNC carries cycle i's command: velocity actual = target + offset (drives.follow_velocity)
    for rec in run.records:
        for j, joint in enumerate(JOINTS):
            assert rec.values[f"{joint}_state"]["velocity_actual_value"] == 100 * j + rec.index - j

    path = run.write_csv(tmp_path / "gait.csv")
    with path.open(newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == CYCLES
    assert list(rows[0]) == run.columns()
    value_columns = [f"{m}.{f}" for m in run.expected for f in run.fields[m]]
    assert value_columns[:2] == ["hip_l_state.position_actual_value", "hip_l_state.velocity_actual_value"]
    for rec, row in zip(run.records, rows):
        assert int(row["cycle"]) == rec.index
        assert row["missing"] == ""
        for m in run.expected:
            for f in run.fields[m]:
                assert int(row[f"{m}.{f}"]) == rec.values[m][f]


def test_setup_errors_are_per_node_and_leave_the_others_alone(
    cfg: rt.RuntimeConfig, channel: str, master_bus: can.BusABC
) -> None:
    """hip_l has the wrong identity, knee_l never answers, ankle_l aborts SDO writes to 0x1A01 (TPDO2 mapping)."""
    faults = {
        "hip_l": {"identity": (0x12345678, 0x00000042)},
        "knee_l": {"silent": True},
        "ankle_l": {"abort_writes": {0x1A01: 0x06040041}},
    }
    with DriveBench(cfg, CANOPEN_DIR, channel=channel, options=faults) as bench:
        report = configure_network(cfg, master_bus, sdo_timeout_s=0.2)
        print(report)
        assert [n.node for n in report.failed] == ["hip_l", "knee_l", "ankle_l"]

        wrong = report.node("hip_l")
        assert wrong.step == "identity" and wrong.identity == (0x12345678, 0x42)
        assert wrong.error is not None
        assert "wrong device" in wrong.error and "0x12345678" in wrong.error and "0x000000FB" in wrong.error
        assert "from runtime.json" in wrong.error  # where the expectation came from
        assert "node id" in wrong.error  # what to do
        assert bench["hip_l"].sdo_writes == []  # nothing written to the wrong device

        silent = report.node("knee_l")
        assert silent.step == "identity" and silent.error is not None
        assert "no answer" in silent.error and "node id 2" in silent.error and "1000 kbit/s" in silent.error
        assert bench["knee_l"].sdo_writes == []

        aborted = report.node("ankle_l")
        assert aborted.abort_code == 0x06040041 and aborted.error is not None
        assert "0x1A01" in aborted.error and "TPDO2" in aborted.error and "PRE-OPERATIONAL" in aborted.error
        slots = {(kind, number): valid for kind, number, _, valid, _, _ in bench["ankle_l"].pdo_slots()}
        assert slots[("rpdo", 1)] and slots[("rpdo", 2)] and slots[("tpdo", 1)]  # written before the abort
        assert not slots[("tpdo", 2)]  # disabled by the master, then the mapping write aborted
        assert bench["ankle_l"].node.nmt.state == "PRE-OPERATIONAL"

        for joint in ("hip_r", "knee_r", "ankle_r"):
            assert report.node(joint).ok and report.node(joint).started
            assert bench[joint].node.nmt.state == "OPERATIONAL"

        # the failed nodes were never started: their TxPDOs are counted missing, every cycle, and not filled in
        run = MasterCycle(cfg, master_bus, SystemClock()).run(5)
    print(run.summary())
    assert run.missing_by_node() == {"hip_l": 10, "knee_l": 10, "ankle_l": 10, "hip_r": 0, "knee_r": 0, "ankle_r": 0}
    assert all("hip_l_state" not in rec.values for rec in run.records)
    assert all(row[run.columns().index("hip_l_state.velocity_actual_value")] == "" for row in run.rows())
    assert [run.complete_samples(j) for j in ("hip_r", "knee_r", "ankle_r")] == [5, 5, 5]


SDO_REQUEST = 0x600  # CiA 301: SDO client -> server COB-ID is 0x600 + node id


class FailingBus(VirtualBus):
    """A virtual bus that fails as a real interface does on a broken bus: send() raises can.CanOperationError for
    frames to `refuse_id` ("Transmit buffer full", socketcan's text when nothing acknowledges), and with
    `receive_broken` every recv() raises too (an interface that went down)."""

    def __init__(self, channel: str, *, refuse_id: int | None = None, receive_broken: bool = False) -> None:
        super().__init__(channel=channel)
        self.refuse_id, self.receive_broken = refuse_id, receive_broken
        self.refused = 0

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.arbitration_id == self.refuse_id:
            self.refused += 1
            raise can.CanOperationError("Transmit buffer full")
        super().send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if self.receive_broken:
            raise can.CanOperationError("Failed to receive: Network is down")
        return super()._recv_internal(timeout)


def test_a_frame_the_interface_refuses_fails_that_node_only(cfg: rt.RuntimeConfig, channel: str) -> None:
    """The interface refuses every frame to knee_l's SDO server (COB-ID 0x602, node id 2): knee_l fails at its first
    SDO request with what to check, nothing is written to it, and the five other drives are configured and started."""
    knee_l = cfg.node("knee_l").node_id
    assert knee_l == 2
    bus = FailingBus(channel, refuse_id=SDO_REQUEST + knee_l)
    try:
        with DriveBench(cfg, CANOPEN_DIR, channel=channel) as bench:
            report = configure_network(cfg, bus, sdo_timeout_s=0.2)
            print(report)
            states = {joint: bench[joint].node.nmt.state for joint in JOINTS}
            writes = bench["knee_l"].sdo_writes
    finally:
        bus.shutdown()
    assert [n.node for n in report.failed] == ["knee_l"]
    failed = report.node("knee_l")
    assert failed.step == "identity" and failed.identity is None and not failed.started
    assert failed.error is not None
    for words in ("refused to send", "CanOperationError: Transmit buffer full", "termination", "powered"):
        assert words in failed.error, words
    assert "1000 kbit/s" in failed.error and "Nothing was written to it" in failed.error
    assert bus.refused >= 1
    assert writes == [] and states["knee_l"] == "PRE-OPERATIONAL"
    others = [j for j in JOINTS if j != "knee_l"]
    assert all(report.node(j).ok and report.node(j).started for j in others)
    assert [states[j] for j in others] == ["OPERATIONAL"] * len(others)


@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")  # the Notifier thread's death
def test_a_receive_failure_is_reported_on_each_node(cfg: rt.RuntimeConfig, channel: str) -> None:
    """An interface whose every recv() raises stops canopen's receive thread; canopen re-raises that error on the next
    send. Each node reports it (the SDO requests still go out, no answer can come back) instead of the set-up
    raising, and none is started."""
    bus = FailingBus(channel, receive_broken=True)
    try:
        with DriveBench(cfg, CANOPEN_DIR, channel=channel, nodes=["hip_l", "knee_l"]):
            report = configure_network(cfg, bus, nodes=["hip_l", "knee_l"], sdo_timeout_s=0.2)
    finally:
        bus.shutdown()
    print(report)
    assert [n.node for n in report.failed] == ["hip_l", "knee_l"]
    for setup in report.nodes:
        assert setup.step == "identity" and not setup.started and setup.error is not None
        assert "receiving from the CAN interface stopped" in setup.error and "Network is down" in setup.error


def test_read_back_catches_a_drive_that_keeps_other_values(
    cfg: rt.RuntimeConfig, channel: str, master_bus: can.BusABC
) -> None:
    """A drive that acknowledges the write of TPDO1's transmission type (1 in runtime.json) but keeps 255: the
    master's read-back reports the difference, and the node is not started."""
    with DriveBench(cfg, CANOPEN_DIR, channel=channel, nodes=["hip_l"]) as bench:
        node = bench["hip_l"].node
        store = node.set_data

        def stubborn(index: int, subindex: int, data: bytes, check_writable: bool = False) -> None:
            store(index, subindex, bytes([255]) if (index, subindex) == (0x1800, 2) else data, check_writable)

        node.set_data = stubborn  # type: ignore[method-assign]
        report = configure_network(cfg, master_bus, nodes=["hip_l"])
        assert node.nmt.state == "PRE-OPERATIONAL"
    setup = report.node("hip_l")
    assert not setup.ok and not setup.started and setup.step == "read-back"
    assert setup.error is not None and "TPDO1 (hip_l_state) transmission type reads 255, 1 written" in setup.error


def test_transmission_type_n_answers_every_nth_sync(
    cfg: rt.RuntimeConfig, channel: str, master_bus: can.BusABC
) -> None:
    """A config whose hip_l_effort has transmission type 2: CiA 301 sends it at every 2nd SYNC, so over 6 cycles
    the master expects it at SYNCs 2, 4, 6 only, and the drive sends 6 state + 3 effort frames."""
    data = json.loads((GENERATED / "runtime.json").read_text(encoding="utf-8"))
    for msg in data["messages"]:
        if msg["name"] == "hip_l_effort":
            msg["pdo"]["transmission"] = 2
    cfg2 = rt.parse(data)
    with DriveBench(cfg2, CANOPEN_DIR, channel=channel, nodes=["hip_l"]) as bench:
        report = configure_network(cfg2, master_bus, nodes=["hip_l"])
        assert report.ok, str(report)
        run = MasterCycle(cfg2, master_bus, SystemClock(), nodes=["hip_l"]).run(6)
        sent = bench["hip_l"].tpdos_sent
    assert [rec.due for rec in run.records] == [
        ("hip_l_state",),
        ("hip_l_state", "hip_l_effort"),
        ("hip_l_state",),
        ("hip_l_state", "hip_l_effort"),
        ("hip_l_state",),
        ("hip_l_state", "hip_l_effort"),
    ]
    assert run.missing == 0 and run.late == 0
    assert sent == 6 + 3


def test_drive_slower_than_the_read_window_is_counted_missing(
    cfg: rt.RuntimeConfig, channel: str, master_bus: can.BusABC
) -> None:
    """A drive that answers 15 ms after the SYNC misses the 10 ms read window (specs/allex2.yaml) every cycle: its
    2 TxPDOs are missing in each of 3 cycles, and found queued - late - before the next SYNC."""
    with DriveBench(cfg, CANOPEN_DIR, channel=channel, nodes=["hip_l"], response_delay_s=0.015):
        assert configure_network(cfg, master_bus, nodes=["hip_l"]).ok
        run = MasterCycle(cfg, master_bus, SystemClock(), nodes=["hip_l"]).run(3)
    assert [rec.missing for rec in run.records] == [("hip_l_state", "hip_l_effort")] * 3
    assert [rec.late for rec in run.records] == [0, 2, 2]
    assert run.complete_samples("hip_l") == 0


RESPONSE_DELAY_S = 0.003  # the review's example: every drive answers 3 ms after the SYNC
READ_WINDOW_S = 0.010  # specs/allex2.yaml, seed 000 section 4.4.2: the 10 ms time slot for reading
TIMING_CYCLES = 50  # enough cycles for a share; 1 s of bus time at T = 20 ms
COMPLETE_SHARE = 0.95  # cycles that must be complete; the rest is left to the shared machine's scheduling


def test_drive_response_delays_do_not_add_up(cfg: rt.RuntimeConfig, channel: str, master_bus: can.BusABC) -> None:
    """Six drives that each answer 3 ms after the SYNC answer together, as six separate devices do.

    Hand calculation: the bench serves all six drives from one thread. If each drive waited out its delay on that
    thread, drive k (k = 1..6 in dispatch order) would answer about k x 3 ms after the SYNC: 3, 6, 9, 12, 15, 18 ms.
    Drives 4-6 (12, 15, 18 ms > 10 ms) would miss the read window in every cycle, so no cycle would be complete, and
    the last drive's answer would come 5 x 3 = 15 ms after the first one's. Scheduled from the SYNC, every drive
    answers 3 ms after it plus the scheduling latency, 7 ms inside the window. The machine is shared and noisy, so no
    time is asserted, only structure: all 12 TxPDOs in the read window in at least 95 % of 50 cycles, and the last
    drive's median answer less than one response delay after the first drive's."""
    with DriveBench(cfg, CANOPEN_DIR, channel=channel, response_delay_s=RESPONSE_DELAY_S) as bench:
        assert configure_network(cfg, master_bus).ok
        run = MasterCycle(cfg, master_bus, SystemClock()).run(TIMING_CYCLES)
        sent = {joint: bench[joint].tpdos_sent for joint in JOINTS}
    assert run.read_window_s == READ_WINDOW_S and len(run.expected) == FRAMES_PER_CYCLE
    after_sync = {
        joint: sorted(
            t - rec.sync_sent for rec in run.records for m, t in rec.arrivals.items() if run.producers[m] == joint
        )
        for joint in JOINTS
    }
    for joint, times in after_sync.items():
        if not times:
            print(f"{joint}: no TxPDO within the read window")
            continue
        median, worst = times[len(times) // 2], times[-1]
        print(
            f"{joint}: {len(times)} TxPDOs in the window, {1e3 * median:.3f} ms after the SYNC (median), "
            f"{1e3 * worst:.3f} ms at worst"
        )
    spreads = sorted(max(rec.arrivals.values()) - rec.sync_sent for rec in run.records if rec.arrivals)
    print(
        f"SYNC -> last TxPDO over {run.cycles} cycles: min {1e3 * spreads[0]:.3f} ms, median "
        f"{1e3 * spreads[len(spreads) // 2]:.3f} ms, max {1e3 * spreads[-1]:.3f} ms "
        f"(one delay {1e3 * RESPONSE_DELAY_S:g} ms; in series the last drive would answer at "
        f"{1e3 * len(JOINTS) * RESPONSE_DELAY_S:g} ms)"
    )
    complete = sum(1 for rec in run.records if not rec.missing)
    print(run.summary())
    assert complete >= COMPLETE_SHARE * TIMING_CYCLES, run.missing_by_node()
    first, last = (after_sync[j][len(after_sync[j]) // 2] for j in (JOINTS[0], JOINTS[-1]))
    assert last - first < RESPONSE_DELAY_S
    assert sent == dict.fromkeys(JOINTS, 2 * TIMING_CYCLES)  # every SYNC answered with both TxPDOs


def test_response_scheduler_runs_by_due_time_and_closes_cleanly() -> None:
    """An action added later but due earlier runs first (the thread waiting for the later one is woken); close()
    drops what is still pending and ends the thread. Delays are only orderings here: 50 ms > 5 ms, and 60 s is far
    beyond the test."""
    idle = ResponseScheduler()
    idle.close()  # never used: no thread was started
    ran: list[str] = []
    done = threading.Event()
    scheduler = ResponseScheduler()
    try:
        scheduler.call_later(0.050, lambda: (ran.append("later"), done.set()))
        scheduler.call_later(0.005, lambda: ran.append("sooner"))
        assert done.wait(timeout=10.0)
        assert ran == ["sooner", "later"]
        scheduler.call_later(60.0, lambda: ran.append("never"))
        assert scheduler.pending == 1
    finally:
        scheduler.close()
    scheduler.call_later(0.0, lambda: ran.append("after close"))  # ignored
    assert scheduler.dropped == 1 and scheduler.pending == 0 and ran == ["sooner", "later"]


def test_drive_refuses_mapping_a_valid_pdo(cfg: rt.RuntimeConfig, channel: str) -> None:
    """CiA 301: a PDO's mapping may change only while the PDO is disabled (bit 31 of its COB-ID) and sub-index 0 is
    0; otherwise the device aborts (0x08000022). An object that is not PDO-mappable (0x1018:1, PDOMapping=0 in the
    EDS) aborts with 0x06040041."""
    drive = SimulatedDrive(1, CANOPEN_DIR / "hip_l.eds", name="hip_l", clear_pdos=False)
    drive_bus = can.Bus(interface="virtual", channel=channel)
    drive.attach(drive_bus)
    network = canopen.Network()
    network.NOTIFIER_CYCLE = 0.05
    network.connect(interface="virtual", channel=channel)
    try:
        node = network.add_node(1, canopen.ObjectDictionary())
        # hip_l.eds: TPDO1 enabled (0x40000181) with two entries
        with pytest.raises(SdoAbortedError) as exc:
            node.sdo.download(0x1A00, 1, (0x60640020).to_bytes(4, "little"))
        assert exc.value.code == 0x08000022
        node.sdo.download(0x1800, 1, (0xC0000181).to_bytes(4, "little"))  # disable
        node.sdo.download(0x1A00, 0, b"\x00")
        with pytest.raises(SdoAbortedError) as exc:
            node.sdo.download(0x1A00, 1, (0x10180120).to_bytes(4, "little"))
        assert exc.value.code == 0x06040041
        node.sdo.download(0x1A00, 1, (0x60640020).to_bytes(4, "little"))  # position actual value: mappable
    finally:
        network.disconnect()
        drive.detach()
        drive_bus.shutdown()
    assert drive.errors == []


def test_expected_identity_and_interpolation_period(cfg: rt.RuntimeConfig) -> None:
    """hip_l.dcf [DeviceInfo]: VendorNumber 0x000000FB (maxon, netcfg/devices/profiles/epos4.yaml) and
    ProductNumber 0 (the profile leaves the variant's code open), so only the vendor is checked. runtime.json's
    node.identity says the same, and identities_from_dir takes it from there when it is present."""
    ident = identity_from_eds(CANOPEN_DIR / "hip_l.dcf")
    assert (ident.vendor_id, ident.product_code) == (0x000000FB, None)
    stated = identity_from_runtime(cfg, cfg.node("hip_l"))
    assert stated is not None and (stated.vendor_id, stated.product_code) == (ident.vendor_id, ident.product_code)
    assert identities_from_dir(cfg, CANOPEN_DIR)["hip_l"] == stated
    assert Path(stated.source).name == "runtime.json"
    assert interpolation_period is rt.interpolation_period  # the emitter's sdo_init and this fallback agree
    # CiA 402 0x60C2: value * 10^index s
    assert interpolation_period(20_000_000) == (20, -3)
    assert interpolation_period(2_500_000) == (25, -4)
    assert interpolation_period(500_000_000) == (50, -2)
    assert interpolation_period(20_000_001) is None


def without_added_keys(data: dict[str, Any]) -> dict[str, Any]:
    """A runtime.json as written before node.identity/eds/dcf/sdo_init/rpdo_count/tpdo_count and pdo.cob_id."""
    for node in data["nodes"]:
        for key in ("identity", "eds", "dcf", "sdo_init", "rpdo_count", "tpdo_count"):
            del node[key]
    for msg in data["messages"]:
        if msg["pdo"] is not None:
            del msg["pdo"]["cob_id"]
    return data


def test_an_older_runtime_json_still_configures_the_drives(channel: str, master_bus: can.BusABC) -> None:
    """Without the device facts the master falls back: identity from hip_l.dcf, COB-ID flag bits derived (the same
    values, CiA 301: TPDO1 0x40000181 with 'no RTR', RPDO1 0x201), PDOs 1-4 (the pre-defined connection set),
    0x60C2 from the 20 ms SYNC period."""
    old = rt.parse(without_added_keys(json.loads((GENERATED / "runtime.json").read_text(encoding="utf-8"))))
    assert old.node("hip_l").identity is None and old.node("hip_l").sdo_init is None
    identities = identities_from_dir(old, CANOPEN_DIR, "can0")
    assert Path(identities["hip_l"].source).name == "hip_l.dcf"
    with DriveBench(old, CANOPEN_DIR, channel=channel, nodes=["hip_l"]) as bench:
        report = configure_network(old, master_bus, nodes=["hip_l"], identities=identities)
        assert report.ok, str(report)
        assert bench["hip_l"].value(0x60C2, 1) == 20 and bench["hip_l"].value(0x60C2, 2) == -3
    setup = report.node("hip_l")
    assert setup.interpolation == (20, -3) and setup.start_up == ()
    cobs = {(p.kind, p.number): p.cob_id for p in setup.pdos}
    assert cobs[("tpdo", 1)] == 0x40000181 and cobs[("rpdo", 1)] == 0x201


def test_master_writes_what_runtime_json_states(channel: str, master_bus: can.BusABC) -> None:
    """The master takes 0x60C2 from node.sdo_init and the COB-ID from pdo.cob_id, not from its own derivation: a
    config stating 0x60C2:1 = 10 and TPDO1 without the 'no RTR' bit (0x181) gets exactly that into the drive."""
    data = json.loads((GENERATED / "runtime.json").read_text(encoding="utf-8"))
    for node in data["nodes"]:
        if node["name"] == "hip_l":
            next(w for w in node["sdo_init"] if w["index"] == 0x60C2 and w["sub"] == 1)["value"] = 10
    for msg in data["messages"]:
        if msg["name"] == "hip_l_state":
            msg["pdo"]["cob_id"] = 0x181
    changed = rt.parse(data)
    with DriveBench(changed, CANOPEN_DIR, channel=channel, nodes=["hip_l"]) as bench:
        report = configure_network(changed, master_bus, nodes=["hip_l"])
        assert report.ok, str(report)
        assert bench["hip_l"].value(0x60C2, 1) == 10
    setup = report.node("hip_l")
    assert setup.interpolation == (10, -3) and setup.start_up == ((0x1017, 0, 100), (0x60C2, 1, 10), (0x60C2, 2, -3))
    assert {(p.kind, p.number): p.cob_id for p in setup.pdos}[("tpdo", 1)] == 0x181


def test_master_uses_the_stated_identity_and_pdo_counts(channel: str, master_bus: can.BusABC) -> None:
    """node.identity with a product code the drive does not hold (hip_l.eds has ProductNumber 0, so the simulated
    drive's 0x1018:2 is 0) fails the identity check; node.tpdo_count 5 makes the master disable TPDO5, which the
    EPOS4 lacks: SDO abort 0x06020000 (CiA 301 table 22, object does not exist)."""
    data = json.loads((GENERATED / "runtime.json").read_text(encoding="utf-8"))
    for node in data["nodes"]:
        if node["name"] == "hip_l":
            node["identity"]["product_code"] = 0x61500000  # maxon's EDS: the EPOS4 50/5
        if node["name"] == "knee_l":
            node["tpdo_count"] = 5
    changed = rt.parse(data)
    with DriveBench(changed, CANOPEN_DIR, channel=channel, nodes=["hip_l", "knee_l"]):
        report = configure_network(changed, master_bus, nodes=["hip_l", "knee_l"])
    wrong = report.node("hip_l")
    assert wrong.step == "identity" and wrong.error is not None and "product 0x61500000" in wrong.error
    missing = report.node("knee_l")
    assert missing.step == "disabling unused TPDO5" and missing.abort_code == 0x06020000


def test_drive_bench_finds_the_eds_runtime_json_names(cfg: rt.RuntimeConfig, channel: str) -> None:
    with DriveBench(cfg, channel=channel, nodes=["hip_l"]) as bench:
        assert bench["hip_l"].has(0x60C2, 1)  # built from canopen/hip_l.eds beside runtime.json


def test_system_clock_never_returns_early() -> None:
    clock = SystemClock()
    for delay in (0.0, 0.0002, 0.002):
        target = clock.now() + delay
        clock.sleep_until(target)
        assert clock.now() >= target


class VirtualClock:
    """Virtual time for the master cycle: it moves only when the bus or a wait moves it."""

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def sleep_until(self, t: float) -> None:
        self.t = max(self.t, t)


class LockstepBus(can.BusABC):
    """The master's bus in virtual time, with a DriveBench's drives behind it: send() takes 0.1 ms and hands the
    frame to every drive at once (what the bench's dispatcher thread does on the virtual bus); their answers, sent
    on the bench's virtual channel, are already in this bus's python-can virtual connection when send() returns
    (python-can's virtual bus queues a frame for every other connection inside send()). recv(timeout) takes what
    is queued, else lets the timeout pass in virtual time. Heartbeats come from the drives' own threads in wall
    time and are skipped, so every run sees the same frames."""

    def __init__(self, clock: VirtualClock, bench: DriveBench, channel: str) -> None:
        super().__init__(channel=channel)
        self.clock, self.bench = clock, bench
        self.answers = can.Bus(interface="virtual", channel=channel)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.clock.t += 0.0001
        for drive in self.bench.drives.values():
            drive.on_frame(msg)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        while (msg := self.answers.recv(0)) is not None:
            if not 0x700 < msg.arbitration_id <= 0x77F:  # CiA 301 heartbeat: 0x700 + node id
                return msg
        self.clock.t += timeout or 0.0
        return None

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return None, False

    def shutdown(self) -> None:
        self.answers.shutdown()
        super().shutdown()


class ScriptedBus(can.BusABC):
    """A python-can bus in virtual time: each frame sent takes 0.1 ms, each SYNC is answered with the frames
    `answers(sync_number)` gives as (delay after the SYNC, frame), and recv(timeout) advances the clock. It overrides
    recv() itself: BusABC.recv() re-checks its timeout against the wall clock."""

    def __init__(self, clock: VirtualClock, answers: Callable[[int], list[tuple[float, can.Message]]]) -> None:
        super().__init__(channel="scripted")
        self.clock, self.answers = clock, answers
        self.queue: list[tuple[float, int, can.Message]] = []
        self.order = itertools.count()
        self.syncs = 0

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.clock.t += 0.0001
        if msg.arbitration_id == 0x80:
            self.syncs += 1
            for delay, frame in self.answers(self.syncs):
                heapq.heappush(self.queue, (self.clock.t + delay, next(self.order), frame))

    def recv(self, timeout: float | None = None) -> can.Message | None:
        wait = timeout or 0.0
        if self.queue and self.queue[0][0] <= self.clock.t + wait:
            t, _, frame = heapq.heappop(self.queue)
            self.clock.t = max(self.clock.t, t)
            return frame
        self.clock.t += wait
        return None

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return None, False


def test_cycle_in_virtual_time_keeps_eq1_and_counts_missing_frames(cfg: rt.RuntimeConfig) -> None:
    """The same MasterCycle on a bus and clock in virtual time (the simulator's contract). Every TxPDO answers
    0.5 ms + 0.1 ms x its rank after the SYNC, except: SYNC 3 gets no knee_r_effort (missing in cycle 2), and
    SYNC 5's hip_r_state comes after the 10 ms read window (missing in cycle 4, found queued - late - in cycle 5).
    With K = 1 ms, eq. (1) ends each iteration at start + T - K, so every period is exactly 19 ms. This is the
    paper's loop, the SYNC right after the writes (sync_lead_s=0), although ALLEX-2's master has a SYNC task."""
    tpdos = [m for m in cfg.messages if m.pdo is not None and m.pdo.kind == "tpdo"]

    def answers(sync: int) -> list[tuple[float, can.Message]]:
        out = []
        for rank, m in enumerate(tpdos):
            if sync == 3 and m.name == "knee_r_effort":
                continue
            delay = 0.012 if sync == 5 and m.name == "hip_r_state" else 0.0005 + 0.0001 * rank
            out.append((delay, m.to_can(**{f.name: rank for f in m.fields})))
        return out

    clock = VirtualClock()
    bus = ScriptedBus(clock, answers)
    run = MasterCycle(cfg, bus, clock, k_s=0.001, sync_lead_s=0.0).run(CYCLES)
    bus.shutdown()
    print(run.summary())
    assert [rec.missing for rec in run.records if rec.missing] == [("knee_r_effort",), ("hip_r_state",)]
    assert [rec.index for rec in run.records if rec.missing] == [2, 4]
    assert [rec.index for rec in run.records if rec.late] == [5]
    assert run.missing_by_node() == {**dict.fromkeys(JOINTS, 0), "knee_r": 1, "hip_r": 1}
    assert run.complete_samples("knee_r") == CYCLES - 1 and run.complete_samples("hip_l") == CYCLES
    for rec in run.records:
        assert rec.period_s == pytest.approx(0.019, abs=1e-9)
        assert rec.waiting_s == pytest.approx(0.020 - rec.processing_s - 0.001, abs=1e-9)
    assert run.period_stats().run_s == pytest.approx(CYCLES * 0.019, abs=1e-6)
    knee_r = [row[run.columns().index("knee_r_effort.torque_actual_value")] for row in run.rows()]
    assert knee_r[2] == "" and knee_r.count("") == 1


def test_acyclic_synchronous_tpdo_is_taken_but_never_waited_for(cfg: rt.RuntimeConfig) -> None:
    """hip_l_effort with transmission type 0 (CiA 301: sent at a SYNC only after its data changed) answers SYNC 2
    only: the live master stores it in cycle 1, never counts it due or missing, and keeps waiting for the others."""
    data = json.loads((GENERATED / "runtime.json").read_text(encoding="utf-8"))
    for msg in data["messages"]:
        if msg["name"] == "hip_l_effort":
            msg["pdo"]["transmission"] = 0
    cfg0 = rt.parse(data)
    tpdos = [m for m in cfg0.messages if m.pdo is not None and m.pdo.kind == "tpdo"]

    def answers(sync: int) -> list[tuple[float, can.Message]]:
        return [
            (0.0005 + 0.0001 * rank, m.to_can(**{f.name: rank for f in m.fields}))
            for rank, m in enumerate(tpdos)
            if m.name != "hip_l_effort" or sync == 2
        ]

    clock = VirtualClock()
    bus = ScriptedBus(clock, answers)
    run = MasterCycle(cfg0, bus, clock).run(4)
    bus.shutdown()
    assert "hip_l_effort" not in run.expected
    assert all("hip_l_effort" not in rec.due for rec in run.records)
    assert [rec.index for rec in run.records if "hip_l_effort" in rec.values] == [1]
    assert run.missing == 0 and run.late == 0


def test_time_stats_use_the_population_standard_deviation() -> None:
    """The run's values are all there is: std divides by n (numpy's default, netcfg.sim.stats.spread's too)."""
    stats = TimeStats.of([1.0, 3.0])
    assert stats.std_s == pytest.approx(1.0) and stats.mean_s == pytest.approx(2.0)
    assert TimeStats.of([0.5]).std_s == 0.0


def test_drive_bench_refuses_a_bus_that_is_not_canopen(channel: str) -> None:
    """The master and the drive bench pick their bus with one function: naming a bus of another protocol is an
    error for both (cambada's only bus, lowlevel, is FTT-CAN)."""
    cambada = rt.load(ROOT / "generated" / "cambada" / "runtime.json")
    with pytest.raises(ValueError, match="lowlevel' is a ftt-can bus, not CANopen"):
        DriveBench(cambada, channel=channel, bus_name="lowlevel")
    with pytest.raises(ValueError, match="0 CANopen buses"):
        DriveBench(cambada, channel=channel)


def test_cia301_pdo_rules() -> None:
    """netcfg.cia301, the one home of the PDO rules the DCFs, runtime.json, the master and the drives use (CiA 301
    7.5.2.35-38): COB-ID flag bits, mapping entries, parameter objects, dummy entries, SYNC-driven types."""
    assert cia301.pdo_cob_id("tpdo", 0x181) == 0x40000181  # bit 30: no RTR on TPDOs
    assert cia301.pdo_cob_id("rpdo", 0x201, valid=False) == 0x80000201
    assert cia301.pdo_cob_id("rpdo", 0x12345, extended=True) == 0x20012345
    assert cia301.pdo_can_id(0xC0000181) == (0x181, False)
    assert cia301.pdo_can_id(0xA0012345) == (0x12345, True)
    assert cia301.pack_mapping(0x6064, 0, 32) == 0x60640020
    assert cia301.unpack_mapping(0x30D10210) == (0x30D1, 2, 16)
    assert (cia301.pdo_comm_index("rpdo", 2), cia301.pdo_map_index("tpdo", 512)) == (0x1401, 0x1BFF)
    assert list(cia301.DUMMY_INDICES) == [1, 2, 3, 4, 5, 6, 7]
    assert cia301.is_dummy(0x0005, 0) and not cia301.is_dummy(0x0005, 1) and not cia301.is_dummy(0x0008, 0)
    assert [cia301.sync_every(t) for t in (0, 1, 2, 240, 241, 252, 254, 255)] == [1, 1, 2, 240, None, None, None, None]
    assert [i for i in (0x1004, 0x1005, 0x1007, 0x1017, 0x1400, 0x1BFF, 0x1C00) if cia301.configured_from_bus(i)] == [
        0x1005,
        0x1007,
        0x1017,
        0x1400,
        0x1BFF,
    ]
