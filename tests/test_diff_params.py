"""`netcfg diff` names what the user changed (offsets, identifiers) beside what it does, and each flow's verdict."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import SPECS, cli

CAMBADA = (SPECS / "cambada.yaml").read_text(encoding="utf-8")


def spec(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def with_deadline(text: str) -> str:
    """CAMBADA's motion flow with a 30 ms deadline (seed 002's Table 3 bounds it below that)."""
    assert "  - name: motion\n" in text
    return text.replace("  - name: motion\n", "  - name: motion\n    deadline: 30 ms\n", 1)


def test_an_offset_change_is_listed_with_the_flow_verdict_it_changes(tmp_path: Path) -> None:
    """motor_setpoints (M1) fixed at 1 EC instead of `offset: auto`: 1 EC is CAMBADA's 5 ms elementary cycle
    (seed 002), so diff lists its offset as 5,000 us on the new side, against the 5 EC = 25,000 us of Table 2's init
    time that `offset: auto` finds, and the motion flow through it: within its 30 ms deadline before (Table 3: at
    most 27.7 ms with FTT-CAN), and the verdict the change gives it after."""
    before = with_deadline(CAMBADA)
    line = next(x for x in before.splitlines() if "period: 6 EC, offset: auto" in x)
    after = before.replace(line, line.replace("offset: auto", "offset: 1 EC"))
    a, b = spec(tmp_path, "a", before), spec(tmp_path, "b", after)
    proc = cli("diff", str(a), str(b), "--format", "json")
    assert proc.returncode == 1, proc.stderr
    doc = json.loads(proc.stdout)
    (m,) = [x for x in doc["messages"] if x["name"] == "motor_setpoints"]
    assert m["a"]["offset_us"] == 25_000 and m["b"]["offset_us"] == 5_000
    flow = next(f for f in doc["flows"] if f["name"] == "motion")
    assert flow["a"]["meets_deadline"] is True
    text = cli("diff", str(a), str(b)).stdout
    assert "message motor_setpoints: offset us" in text
    for side in "ab":
        verdict = "meets" if flow[side]["meets_deadline"] else "MISSES"
        assert f"{verdict} its 30,000 us deadline" in text


def test_an_identifier_change_is_listed(tmp_path: Path) -> None:
    a = spec(tmp_path, "a", CAMBADA)
    line = next(x for x in CAMBADA.splitlines() if "name: encoder1, ftt_id: 1," in x)
    b = spec(tmp_path, "b", CAMBADA.replace(line, line.replace("ftt_id: 1,", "ftt_id: 30,")))
    text = cli("diff", str(a), str(b)).stdout
    assert "message encoder1: " in text and "; FTT id 1 -> 30;" in text, text
