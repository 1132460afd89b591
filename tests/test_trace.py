"""Simulation traces: python-can reads back what we write, cantools decodes it with our DBC, output is reproducible."""

from __future__ import annotations

import datetime
import random
from pathlib import Path

import can
import cantools
import pytest
from conftest import ROOT

import netcfg.runtime
from netcfg.sim.trace import TraceFrame, write_trace

ALLEX2 = ROOT / "generated" / "allex2"
STATES = [(1000 * k - 3500, -250 * k + 17) for k in range(8)]  # (position, velocity) of hip_l_state


def make_frames() -> list[TraceFrame]:
    """200 frames over two channels: random 11- and 29-bit frames of 0..8 bytes, 8 hip_l_state frames from the
    ALLEX-2 runtime config, one error frame; times in ns with sub-microsecond parts."""
    rng = random.Random(2007)
    hip = netcfg.runtime.load(ALLEX2 / "runtime.json").message("hip_l_state")
    frames: list[TraceFrame] = []
    t_ns = 0
    for i in range(200):
        channel = "can0" if rng.random() < 0.7 else "can1"
        if i == 0:
            frames.append(TraceFrame(t_ns, "can1", 0x7FF, False, b"\xff"))  # can1 first: ASC numbers it 1
        elif i == 100:
            frames.append(TraceFrame(t_ns, channel, 0, False, b"", error=True))
        elif i % 25 == 3:
            position, velocity = STATES[i // 25]
            msg = hip.to_can(position_actual_value=position, velocity_actual_value=velocity)
            frames.append(TraceFrame(t_ns, "can0", msg.arbitration_id, msg.is_extended_id, bytes(msg.data)))
        else:
            extended = rng.random() < 0.5
            can_id = rng.randrange(1 << 29) if extended else rng.randrange(1 << 11)
            data = bytes(rng.randrange(256) for _ in range(rng.randrange(9)))
            frames.append(TraceFrame(t_ns, channel, can_id, extended, data))
        t_ns += rng.randrange(50_000, 2_000_000)  # 50 us .. 2 ms, any ns
    return frames


@pytest.mark.parametrize("suffix", [".log", ".asc"])
def test_python_can_reads_back_every_frame(tmp_path: Path, suffix: str) -> None:
    """Peer: can.LogReader. Both writers print seconds with 6 decimals (candump -L "(%f)", ASCWriter "{: 9.6f}"),
    so a time comes back within half a microsecond; 1 us allows for float rounding. ASC channels come back as
    python-can's 0-based int (it reads printed channel k as k - 1): can1 first seen -> 1 -> 0, can0 -> 2 -> 1."""
    frames = make_frames()
    path = tmp_path / f"trace{suffix}"
    assert write_trace(frames, path) == len(frames) == 200
    read = list(can.LogReader(path))
    assert len(read) == len(frames)
    asc_channel = {"can1": 0, "can0": 1}
    for sent, got in zip(frames, read):
        assert abs(got.timestamp - sent.t_ns / 1e9) <= 1e-6
        if suffix == ".asc":
            assert got.channel == asc_channel[sent.channel]
        elif not sent.error:
            assert got.channel == sent.channel
        assert got.is_error_frame == sent.error
        if not sent.error:
            assert (got.arbitration_id, got.is_extended_id) == (sent.can_id, sent.extended)
            assert (got.dlc, bytes(got.data)) == (len(sent.data), sent.data)
    assert sum(m.is_error_frame for m in read) == 1
    if suffix == ".log":
        # python-can's candump reader drops an error frame's interface name, so read it from the line: Linux
        # <linux/can.h>, <linux/can/error.h>: CAN_ERR_FLAG 0x20000000 | CAN_ERR_BUSERROR 0x80, no data.
        (error,) = (f for f in frames if f.error)
        assert f") {error.channel} 20000080#\n" in path.read_text(encoding="ascii")


def test_asc_numbers_channels_from_one(tmp_path: Path) -> None:
    """Vector ASC channels are 1-based: the first channel seen is printed 1, the second 2."""
    path = tmp_path / "trace.asc"
    write_trace(make_frames(), path)
    lines = path.read_text(encoding="ascii").splitlines()
    body = [line.split() for line in lines if line[:1] == " " and "Start of measurement" not in line]
    assert body[0][1] == "1"
    assert {fields[1] for fields in body} == {"1", "2"}
    assert sum("Start of measurement" in line for line in lines) == 1


@pytest.mark.parametrize("suffix", [".log", ".asc"])
def test_cantools_decodes_the_trace_with_our_dbc(tmp_path: Path, suffix: str) -> None:
    """Peer: cantools with generated/allex2/dbc/*.dbc decodes the read-back hip_l_state frames to the values we
    encoded through netcfg.runtime (STATES), in order."""
    (dbc,) = sorted(ALLEX2.glob("dbc/*.dbc"))
    db = cantools.database.load_file(str(dbc))
    hip = db.get_message_by_name("hip_l_state")
    path = tmp_path / f"trace{suffix}"
    write_trace(make_frames(), path)
    decoded = [
        hip.decode(bytes(m.data))
        for m in can.LogReader(path)
        if not m.is_error_frame and (m.arbitration_id, m.is_extended_id) == (hip.frame_id, hip.is_extended_frame)
    ]
    assert [(d["position_actual_value"], d["velocity_actual_value"]) for d in decoded] == STATES


@pytest.mark.parametrize("suffix", [".log", ".asc"])
def test_same_frames_same_bytes(tmp_path: Path, suffix: str) -> None:
    """DESIGN.md: output is deterministic. ASCWriter would stamp the wall clock into the header; ours is pinned,
    so today's year appears nowhere in the file."""
    first, second = tmp_path / f"a{suffix}", tmp_path / f"b{suffix}"
    write_trace(make_frames(), first)
    write_trace(make_frames(), second)
    assert first.read_bytes() == second.read_bytes()
    header = first.read_text(encoding="ascii").splitlines()[:5]
    assert not any(str(datetime.date.today().year) in line for line in header)


def test_format_by_name_and_bad_input(tmp_path: Path) -> None:
    frames = make_frames()[:3]
    assert write_trace(frames, tmp_path / "trace.txt", fmt="asc") == 3
    assert (tmp_path / "trace.txt").read_text(encoding="ascii").startswith("date ")
    assert write_trace(frames, tmp_path / "dump.txt", fmt="candump") == 3
    assert (tmp_path / "dump.txt").read_text(encoding="ascii").startswith("(0.000000) can1 7FF#FF")
    with pytest.raises(ValueError, match=r"\.log, \.asc"):
        write_trace(frames, tmp_path / "trace.blf")
    with pytest.raises(ValueError, match="time order"):
        write_trace(list(reversed(frames)), tmp_path / "late.log")
    with pytest.raises(ValueError, match="no spaces"):
        write_trace([TraceFrame(0, "can 0", 1, False, b"")], tmp_path / "space.log")
    with pytest.raises(ValueError):
        write_trace([TraceFrame(0, "can0", 0x800, False, b"")], tmp_path / "id.log")
