"""netcfg tune: Audsley's assignment against deadline-monotonic, pins and ranges kept, the spec edited in place."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from conftest import ROOT, cli
from hypothesis import given, settings
from hypothesis import strategies as st

from netcfg.timing import can_rta
from netcfg.tuning import Item, NoAssignment, audsley

WRONG_ORDER = ROOT / "examples" / "wrong_order.yaml"
MS = 1_000_000
TAU = 1_000  # 1 Mbit/s


def _item(name: str, c: int, t: int, d: int, j: int = 0, ident: int = 0) -> Item:
    return Item(name, c, t, j, d, False, ident, "n", False, None)


def _schedulable(items: list[Item], ids: dict[str, int]) -> bool:
    frames = [can_rta.CanFrame(it.name, ids[it.name], False, it.c_ns, it.t_ns, it.j_ns, it.d_ns) for it in items]
    res = can_rta.analyse(frames, TAU)
    return all(res[f.name].schedulable(f.d_ns) for f in frames)


def test_audsley_succeeds_where_deadline_monotonic_fails() -> None:
    """Hand-worked (times in ms, tau 0.001): a (C 0.5, T = D 10, jitter 8.4), b (C 1, T = D 5), c (C 1, T = D 6).
    Deadline-monotonic puts b, c above a: R_a = J + w + C = 8.4 + (1 + 1) + 0.5 = 10.9 > 10.
    With a on top: R_a = 8.4 + B (1) + 0.5 = 9.9; b next: B 1 + a 0.5, R_b = 1.5 + 1 = 2.5 <= 5; c last:
    w = a 0.5 + b 1 = 1.5, R_c = 2.5 <= 6. Audsley finds this order (Davis et al. 2007, eqs. 10-14)."""
    items = [
        _item("a", MS // 2, 10 * MS, 10 * MS, j=8_400_000, ident=3),
        _item("b", MS, 5 * MS, 5 * MS, ident=1),
        _item("c", MS, 6 * MS, 6 * MS, ident=2),
    ]
    dm = {"b": 1, "c": 2, "a": 3}
    assert not _schedulable(items, dm)
    ids, _ = audsley(items, TAU)
    assert ids["a"] == 1 and _schedulable(items, ids)


@settings(max_examples=80, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(1, 20), st.integers(20, 400), st.integers(50, 100), st.integers(0, 30)),
        min_size=1,
        max_size=10,
    )
)
def test_audsley_finds_an_assignment_whenever_deadline_monotonic_does(raw: list[tuple[int, int, int, int]]) -> None:
    """Audsley's assignment is optimal for CAN's revised analysis (Davis and Burns 2009): whenever the
    deadline-monotonic order meets every deadline, Audsley's search finds an order that does too."""
    items = [
        _item(f"m{i}", c * 10_000, t * 100_000, t * 100_000 * dp // 100, j=j * 10_000, ident=i + 1)
        for i, (c, t, dp, j) in enumerate(raw)
    ]
    by_deadline = sorted(items, key=lambda it: (it.d_ns, it.name))
    dm = {it.name: k + 1 for k, it in enumerate(by_deadline)}
    try:
        ids, _ = audsley(items, TAU)
    except NoAssignment:
        assert not _schedulable(items, dm)
        return
    assert _schedulable(items, ids)
    assert sorted(ids.values()) == [it.id for it in items]  # the identifiers the bus already used, reordered


def test_pinned_identifier_and_id_range_are_kept() -> None:
    items = [
        Item("slow", MS, 100 * MS, 0, 100 * MS, False, 0x100, "a", True, None),  # pinned on top
        Item("fast", MS, 5 * MS, 0, 5 * MS, False, 0x101, "b", False, (0x101, 0x1FF)),
        Item("mid", MS, 10 * MS, 0, 10 * MS, False, 0x102, "c", False, None),
    ]
    ids, _ = audsley(items, TAU)
    assert ids == {"slow": 0x100, "fast": 0x101, "mid": 0x102}


def _spec_without(data: dict[str, Any], keys: tuple[str, ...]) -> dict[str, Any]:
    return {**data, "messages": [{k: v for k, v in m.items() if k not in keys} for m in data["messages"]]}


def test_wrong_order_bus_refused_then_accepted_after_tune(tmp_path: Path) -> None:
    """examples/wrong_order.yaml: 17 frames of 8 bytes at 500 kbit/s (135 bits, 270 us each), 78.3 % loaded, the
    longest periods on the smallest identifiers. ecu_pwm (1 ms) waits for all 16 others: 6210 us > 1000 us."""
    before = cli("check", str(WRONG_ORDER))
    assert before.returncode == 1 and "'ecu_pwm' can take 6210 us" in before.stderr
    out = tmp_path / "tuned.yaml"
    run = cli("tune", str(WRONG_ORDER), "-o", str(out))
    assert run.returncode == 0, run.stderr
    assert "deadline misses" in run.stdout and "ecu_pwm" in run.stdout
    assert cli("check", str(out)).returncode == 0
    old, new = WRONG_ORDER.read_text(), out.read_text()
    # comments and layout are the user's: every comment survives, and only ids and offsets changed
    assert all(line in new for line in old.splitlines() if line.strip().startswith("#"))
    assert "  - name: motor_speed         # feedback" in new
    drop = ("id", "offset")
    assert _spec_without(yaml.safe_load(old), drop) == _spec_without(yaml.safe_load(new), drop)
    # refuses to replace a file; nothing written when no assignment exists
    assert cli("tune", str(WRONG_ORDER), "-o", str(out)).returncode == 2


def test_no_assignment_is_a_clear_error(tmp_path: Path) -> None:
    spec = yaml.safe_load(WRONG_ORDER.read_text())
    spec["messages"].append(
        {"name": "flood", "id": 0x170, "producer": "ecu", "consumers": ["motor"], "size": 8, "period": "1200 us"}
    )
    src = tmp_path / "over.yaml"
    src.write_text(yaml.safe_dump(spec, sort_keys=False))
    out = tmp_path / "never.yaml"
    run = cli("tune", str(src), "-o", str(out))
    assert run.returncode == 1
    assert "no identifier assignment meets every deadline" in run.stderr and "nothing was written" in run.stderr
    assert "Traceback" not in run.stderr and not out.exists()


def test_robust_variant_states_the_errors_every_message_survives() -> None:
    """Davis and Burns 2009's robust assignment: six 250 us frames (tau 1 us) with periods = deadlines 2..7 ms.
    Each error costs 31 bit times plus the longest frame, 281 us; the order it returns meets every deadline and
    tolerates at least one error everywhere (the lowest message: 6 * 250 + 281 = 1781 us < 7 ms)."""
    items = [_item(f"m{i}", MS // 4, (i + 2) * MS, (i + 2) * MS, ident=i + 1) for i in range(6)]
    ids, tolerated = audsley(items, TAU, robust=True)
    assert _schedulable(items, ids) and tolerated is not None and tolerated >= 1


def test_tune_a_dbc(tmp_path: Path) -> None:
    """tune F.dbc -o OUT.dbc: the wrong-order bus as a DBC (the tuned spec's DBC, renumbered back to the original
    identifiers in its own text) is refused by check and accepted after tune; only BO_ numbers and the statements
    naming them change."""
    from netcfg.tuning import edit_dbc_ids

    tuned = tmp_path / "tuned.yaml"
    assert cli("tune", str(WRONG_ORDER), "-o", str(tuned)).returncode == 0
    assert cli("build", str(tuned), "-o", str(tmp_path / "out")).returncode == 0
    orig = {m["name"]: m["id"] for m in yaml.safe_load(WRONG_ORDER.read_text())["messages"]}
    new = {m["name"]: m["id"] for m in yaml.safe_load(tuned.read_text())["messages"]}
    good = (tmp_path / "out" / "dbc" / "body.dbc").read_text(encoding="latin-1")
    wrong = tmp_path / "wrong.dbc"
    wrong.write_text(edit_dbc_ids(good, {new[n]: orig[n] for n in orig}), encoding="latin-1")
    assert cli("check", str(wrong), "--bitrate", "500k").returncode == 1
    fixed = tmp_path / "fixed.dbc"
    run = cli("tune", str(wrong), "-o", str(fixed), "--bitrate", "500k")
    assert run.returncode == 0, run.stderr
    assert cli("check", str(fixed), "--bitrate", "500k").returncode == 0
    changed = [
        (a, b)
        for a, b in zip(wrong.read_text("latin-1").splitlines(), fixed.read_text("latin-1").splitlines())
        if a != b
    ]
    assert changed and all(a.split()[0] == b.split()[0] for a, b in changed)
    assert cli("tune", str(wrong), "-o", str(tmp_path / "x.yaml")).returncode == 2  # writes what it reads
