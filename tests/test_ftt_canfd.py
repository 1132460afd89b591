"""FTT-CAN over the CAN FD link (`link: can-fd`): the trigger message and every frame of the elementary cycle timed
at the link's two rates, the trigger message a CAN FD frame with bit-rate switch (netcfg.protocols.ftt.tm).

Every figure below is a hand calculation of ISO 11898-1:2015 frame bits with the worst-case stuffing netcfg.links
.canfd's frames are timed with (netcfg.timing.frames.canfd_frame_bits): a CAN FD base-format frame of L data bytes
(L a valid data length) has 17 arbitration bits (SOF .. BRS), 5 control bits after the switch (ESI, DLC), 8L data
bits, the 4-bit stuff count and a CRC of 17 bits (L <= 16) or 21, 1 + (4 + CRC) / 4 fixed stuff bits, then the CRC
delimiter and 12 tail bits (ACK slot and delimiter, EOF, intermission). Worst-case dynamic stuffing adds
(17 + 5 + 8L - 1) // 4 bits, of which (17 - 1) // 4 = 4 fall in the arbitration phase; with bit-rate switch the
arbitration phase, its stuff bits, the CRC delimiter and the tail go at the nominal rate, the rest at the data rate.

  L = 2  (the trigger message of tm_size 2): nominal 17 + 4 + 1 + 12 = 34; data 5 + 16 + 4 + 17 + 6 = 48 plus
         (38 - 1) // 4 - 4 = 5 stuff bits = 53.
  L = 16:                                   nominal 34;                 data 5 + 128 + 4 + 17 + 6 = 160 plus
         (150 - 1) // 4 - 4 = 33 = 193.
  A classical 6-byte base frame (fd: false): 47 + 48 = 95 bits plus (34 + 48 - 1) // 4 = 20 stuff bits = 115, all
  at the nominal rate.

At 500 kbit/s (2000 ns a bit) and 2 Mbit/s (500 ns): TM 34 * 2000 + 53 * 500 = 94,500 ns; the 16-byte frame
34 * 2000 + 193 * 500 = 164,500 ns; the classical frame 115 * 2000 = 230,000 ns. The same TM as a classical frame
(the bus over link: can) would be 47 + 16 + (34 + 16 - 1) // 4 = 75 bits = 150,000 ns.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cantools
from conftest import check_data, runtime_config_of

from netcfg.sim.montecarlo import run_once
from netcfg.sim.scenario import SimOptions
from netcfg.timing.frames import canfd_frame_bits

MS = 1_000_000


def _spec(link: str = "can-fd") -> dict[str, Any]:
    bus: dict[str, Any] = {"name": "bus", "protocol": "ftt-can", "link": link, "bitrate": "500 kbit/s",
                           "ftt": {"ec": "5 ms", "tm_size": 2}}
    if link == "can-fd":
        bus["data_bitrate"] = "2 Mbit/s"
    return {
        "system": "fd_ec",
        "buses": [bus],
        "nodes": [{"name": "master", "role": "master", "buses": ["bus"]}, {"name": "a", "buses": ["bus"]},
                  {"name": "b", "buses": ["bus"]}],
        "messages": [
            {"name": "wide", "ftt_id": 1, "producer": "a", "consumers": ["b"], "size": 16, "period": "1 EC"},
            {"name": "narrow", "ftt_id": 2, "producer": "b", "consumers": ["a"], "size": 6, "period": "1 EC",
             **({"fd": False} if link == "can-fd" else {})},
        ],
    }


def test_the_fd_frames_bits_at_the_two_rates() -> None:
    assert (canfd_frame_bits(2).nominal, canfd_frame_bits(2).data) == (34, 53)
    assert (canfd_frame_bits(16).nominal, canfd_frame_bits(16).data) == (34, 193)
    assert canfd_frame_bits(16).ns(500_000, 2_000_000) == 164_500


def test_an_elementary_cycle_of_fd_frames(tmp_path: Path) -> None:
    """The EC of 5 ms: the TM (94.5 us) opens it; both synchronous messages are due in every EC, so its
    synchronous window is 164.5 + 230 = 394.5 us and closes the EC (async-first): it opens at 5000 - 394.5 =
    4605.5 us, 'wide' (the lower identifier, sync_id_base 0x100 + 1) ends at 4770 us and 'narrow' at 5000 us. The
    asynchronous window between is 5000 - 94.5 - 394.5 = 4511 us, and the LSW by default the EC after the TM,
    4905.5 us."""
    report = check_data(tmp_path, _spec())
    assert report["ok"], report["errors"]
    bus = report["buses"][0]
    ftt = bus["ftt"]
    assert (ftt["tm_us"], ftt["tm_bits"], ftt["lsw_us"]) == (94.5, 34 + 53, 4905.5)
    assert ftt["worst_ec"]["sync_us"] == 394.5
    assert ftt["ecs"][0]["async_us"] == 4511.0
    rows = {m["name"]: m for m in bus["messages"]}
    assert (rows["wide"]["frame_us_worst"], rows["wide"]["frame_bits_worst"]) == (164.5, 34 + 193)
    assert (rows["narrow"]["frame_us_worst"], rows["narrow"]["frame_bits_worst"]) == (230.0, 115)
    assert (rows["wide"]["wcrt_us"], rows["narrow"]["wcrt_us"]) == (4770.0, 5000.0)


def test_the_same_cycle_over_classical_can_has_the_classical_trigger_message(tmp_path: Path) -> None:
    """link: can: the TM is a 75-bit classical frame, 150 us at 500 kbit/s (the module docstring)."""
    spec = _spec("can")
    spec["messages"][0]["size"] = 8  # a classical frame carries at most 8 bytes
    report = check_data(tmp_path, spec)
    assert report["ok"], report["errors"]
    assert (report["buses"][0]["ftt"]["tm_us"], report["buses"][0]["ftt"]["tm_bits"]) == (150.0, 75)


def test_the_simulated_cycle_sends_the_frames_the_analysis_timed(tmp_path: Path) -> None:
    """The simulator's master sends the TM as a CAN FD frame with bit-rate switch: with worst-case stuffing each
    TM takes the hand-calculated 94.5 us, and no frame's response leaves its bound."""
    cfg = runtime_config_of(tmp_path / "spec.yaml", _spec())
    for seed in range(3):
        _, res = run_once(cfg, SimOptions(duration_ns=100 * MS, seed=seed))
        tm = res.response["bus_TM"]
        assert len(tm) == 20 and int(tm.min()) == int(tm.max()) == 94_500
        for name in ("wide", "narrow"):
            r = res.response[name]
            assert len(r) and int(r.max()) <= res.wcrt[name], (seed, name)


def test_the_dbc_declares_the_trigger_message_an_fd_frame(tmp_path: Path) -> None:
    """cantools reads the DBC's trigger message as a CAN FD frame (its VFrameFormat), as the bus sends it."""
    from conftest import cli

    path = tmp_path / "spec.yaml"
    runtime_config_of(path, _spec())  # writes the spec
    out = tmp_path / "out"
    proc = cli("build", str(path), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    db = cantools.database.load_file(str(out / "dbc" / "bus.dbc"))
    frames = {m.name: m.is_fd for m in db.messages}
    assert frames == {"bus_TM": True, "wide": True, "narrow": False}


def test_the_c_headers_say_the_trigger_message_is_an_fd_frame(tmp_path: Path) -> None:
    """Each node's header names the TM's frame format, which the master's firmware sends it in, and gcc compiles it
    (-std=c99 -Wall -Wextra -Wpedantic -Werror). Rendered with this repository's templates (an editable install may
    map netcfg.templates to another checkout's), in a process of its own so the cached environment is this one's."""
    import shutil
    import subprocess
    import sys

    from conftest import ROOT

    path = tmp_path / "spec.yaml"
    runtime_config_of(path, _spec())
    out = tmp_path / "out"
    program = (
        "import sys; from pathlib import Path; import netcfg.templating as t; "
        f"t.templates_folder = lambda: Path({str(ROOT / 'templates')!r}); "
        "from netcfg.build import build; "
        f"build(Path({str(path)!r}), Path({str(out)!r}))"
    )
    proc = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr
    header = (out / "c" / "master.h").read_text(encoding="utf-8")
    assert "#define BUS_BUS_TM_FD 1" in header
    gcc = shutil.which("gcc")
    if gcc is not None:
        compiled = subprocess.run([gcc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-fsyntax-only",
                                   str(out / "c" / "master.h")], capture_output=True, text=True, timeout=60)
        assert compiled.returncode == 0, compiled.stderr
