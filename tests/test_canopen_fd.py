"""CANopen over the CAN FD link (`link: can-fd`, CANopen FD's process data, CiA 1301): PDOs of up to 64 bytes in
CAN FD frames, SYNC and heartbeats as CAN FD frames with bit-rate switch (netcfg.protocols.canopen.resolve
.fd_services), and what netcfg does not do of CANopen FD refused where a command meets it.

Hand calculation (ISO 11898-1:2015 field by field, worst-case stuffing as netcfg.links.canfd's frames are timed;
the field counts are in tests/test_ftt_canfd.py's docstring), at 1 Mbit/s (1000 ns a bit) and 5 Mbit/s (200 ns):

  SYNC, 0 data bytes:  nominal 17 + 4 + 1 + 12 = 34 bits; data 5 + 0 + 4 + 17 + 6 = 32 plus (22 - 1) // 4 - 4 = 1
                       stuff bit = 33; 34,000 + 33 * 200 = 40,600 ns.
  TPDO, 64 data bytes: nominal 34; CRC-21, so 1 + (4 + 21) // 4 = 7 fixed stuff bits; data 5 + 512 + 4 + 21 + 7 =
                       549 plus (17 + 5 + 512 - 1) // 4 - 4 = 129 = 678; 34,000 + 678 * 200 = 169,600 ns.

The SYNC cycle (netcfg.timing.canopen_sync: W = B + C_SYNC + max D + the TPDOs due + the others released
meanwhile): the one lower-priority frame that may be on the bus when SYNC is queued is the TPDO itself (169.6 us),
then SYNC (40.6 us), no tx_delay, the TPDO (169.6 us), nothing else on the bus: 169.6 + 40.6 + 169.6 = 379.8 us.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from conftest import check_data, cli, runtime_config_of

from netcfg.sim.montecarlo import run_once
from netcfg.sim.scenario import SimOptions

MS = 1_000_000


def _spec(link: str = "can-fd", entries: int = 8) -> dict[str, Any]:
    """A master and a sensor whose TPDO1 maps `entries` UNSIGNED64 objects of its own (8 of them: 64 bytes), the
    cia402 profile's 8 mapping entries at most."""
    objects = [{"index": 0x2100 + k, "name": f"Wide value {k}", "type": "UNSIGNED64", "access": "ro"} for k in range(8)]
    bus: dict[str, Any] = {"name": "can0", "protocol": "canopen", "link": link, "bitrate": "1 Mbit/s",
                           "canopen": {"sync_period": "10 ms", "sync_window": "5 ms"}}
    if link == "can-fd":
        bus["data_bitrate"] = "5 Mbit/s"
    return {
        "system": "co_fd",
        "buses": [bus],
        "nodes": [{"name": "master", "role": "master", "node_id": 127, "buses": ["can0"]},
                  {"name": "sensor", "node_id": 1, "buses": ["can0"],
                   "device": {"profile": "cia402", "objects": objects}}],
        "messages": [{"name": "sensor_state", "producer": "sensor", "consumers": ["master"],
                      "pdo": {"tpdo": 1, "transmission": 1, "map": [0x2100 + k for k in range(entries)]}}],
    }


def test_a_sync_window_with_a_64_byte_pdo(tmp_path: Path) -> None:
    report = check_data(tmp_path, _spec())
    assert report["ok"], report["errors"]
    bus = report["buses"][0]
    rows = {m["name"]: m for m in bus["messages"]}
    assert (rows["can0_SYNC"]["size"], rows["can0_SYNC"]["frame_us_worst"]) == (0, 40.6)
    assert (rows["sensor_state"]["size"], rows["sensor_state"]["frame_us_worst"]) == (64, 169.6)
    assert rows["sensor_state"]["frame_bits_worst"] == 34 + 678
    assert bus["sync"]["worst_completion_us"] == 379.8


def test_the_simulated_cycle_keeps_inside_it(tmp_path: Path) -> None:
    """The simulator runs the live master's cycle (in PDO mode) with the frames as the analysis timed them: with
    worst-case stuffing the SYNC takes 40.6 us and the TPDO 169.6 us, and no response leaves its bound."""
    cfg = runtime_config_of(tmp_path / "spec.yaml", _spec())
    _, res = run_once(cfg, SimOptions(duration_ns=200 * MS, seed=1))
    assert int(res.response["can0_SYNC"].min()) == 40_600
    tpdo = res.response["sensor_state"]
    assert len(tpdo) == 20 and int(tpdo.max()) <= res.wcrt["sensor_state"]


def test_a_classical_canopen_bus_still_holds_a_pdo_to_8_bytes(tmp_path: Path) -> None:
    """CiA 301 on classical CAN: the same map of 64 bytes is refused, the frame's 8 bytes and the map's 64 bits."""
    report = check_data(tmp_path, _spec("can"))
    errors = {e["code"]: e["message"] for e in report["errors"]}
    assert set(errors) == {"payload", "pdo-length"}
    assert "at most 8" in errors["payload"] and "512 bits; a CAN frame carries at most 64" in errors["pdo-length"]


def test_run_refuses_a_canopen_fd_bus_for_want_of_usdo(tmp_path: Path) -> None:
    """The live master configures devices by SDO; CANopen FD has USDO in its place, which netcfg does not
    implement: `run` (and simulate's SDO mode) say so, exit 1 (2: a simulate option), without a traceback."""
    path = tmp_path / "spec.yaml"
    runtime_config_of(path, _spec())
    proc = cli("run", str(path), "--interface", "virtual", "--simulated-drives", "--cycles", "3")
    assert proc.returncode == 1 and "USDO" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    proc = cli("simulate", str(path), "--canopen", "sdo", "--duration", "100ms")
    assert proc.returncode == 2 and "USDO" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr


def test_build_writes_the_64_byte_mapping_and_says_what_it_leaves_out(tmp_path: Path) -> None:
    """The DCF's TPDO1 mapping (0x1A00) holds the 8 entries, each index << 16 | sub << 8 | 64 bits (CiA 301
    7.5.2.36), as the canopen package reads them; build's notes name what the files leave out of CANopen FD."""
    import canopen

    path = tmp_path / "spec.yaml"
    runtime_config_of(path, _spec())
    out = tmp_path / "out"
    proc = cli("build", str(path), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    od = canopen.import_od(str(out / "canopen" / "sensor.dcf"), 1)
    assert od[0x1A00][0].default == 8
    assert [od[0x1A00][k].default for k in range(1, 9)] == [(0x2100 + k) << 16 | 0 << 8 | 64 for k in range(8)]
    assert "USDO" in proc.stderr and "CANopen FD" in proc.stderr


def test_a_drive_s_emcy_and_boot_up_are_can_fd_frames_too(tmp_path: Path) -> None:
    """A drill's EMCY (0x80 + node id, 8 bytes: error code 0x2310 little-endian, 10 23, error register 0x01, CiA 301
    7.2.7), a reboot's boot-up (0x700 + node id, one byte 0x00, CiA 301 7.2.8.3.2.1) and the master's NMT answer to
    the EMCY (id 0, enter pre-operational 0x80 and the node id) go as the bus's SYNC and heartbeats do: CAN FD with
    bit-rate switch, written '##1' in the log (python-can's candump format: '##', then the flags nibble, BRS = 1).
    The sensor sends no heartbeat, so its boot-up is a source of its own."""
    path, log = tmp_path / "spec.yaml", tmp_path / "sim.log"
    runtime_config_of(path, _spec())
    proc = cli("simulate", str(path), "--duration", "1s", "--fault", "emcy:sensor@300ms", "--fault",
               "reset:sensor@600ms+20ms", "--log", str(log))
    assert proc.returncode in (0, 1), proc.stderr
    frames = [line.split()[2] for line in log.read_text().splitlines()]
    assert "081##11023010000000000" in frames, [f for f in frames if f.startswith("081")]
    assert "701##100" in frames, [f for f in frames if f.startswith("701")]
    assert "000##18001" in frames, [f for f in frames if f.startswith("000")]
    assert not [f for f in frames if "##" not in f]  # not one classical frame on the CANopen FD bus
