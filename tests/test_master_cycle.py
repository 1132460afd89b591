"""The CANopen master's cycle, modelled rather than assumed: the SYNC-cycle bound, the master's own timing from
the spec, and the simulator running the live master (netcfg.runtime.canopen_master.MasterCycle) on it."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import SHARED, check

REPRO = SHARED / "repro" / "soundness"


def repro(name: str) -> Path:
    path = REPRO / name
    if not path.is_file():
        pytest.skip("the shared soundness reproductions are not next to this checkout")
    return path


def test_sync_cycle_counts_other_messages_release_jitter() -> None:
    """Repro 09: 'other' (0x85, T = 1 ms, J = 900 us, 135 bits at 1 Mbit/s) beats the TPDO 0x181. Two of its
    instances can be released 100 us apart inside one cycle: W = B 135 + SYNC 55 + TPDO 135 + ceil((W + 900) /
    1000) x 135 = 325 + 2 x 135 = 595 us (the file's derivation), over the 500 us window."""
    report = check(repro("09-canopen-sync-jitter.yaml"))
    can0 = report["buses"][0]
    assert can0["sync"]["worst_completion_us"] == 595.0
    assert [e["code"] for e in report["errors"]] == ["sync-cycle"]
    assert "595 us after SYNC, 95 us too late" in report["errors"][0]["message"]
