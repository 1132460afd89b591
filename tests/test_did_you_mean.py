"""A misspelt name gets a "did you mean" wherever a name is looked up, and schema errors name the item.

Each case takes one valid spec, misspells one name the way people do (a dropped or swapped letter, a wrong case),
and expects the intended name back in the error. The intended names are the spec's own, written here by hand.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from netcfg.spec.suggest import closest
from tests.conftest import check_data

BASE: dict[str, Any] = {
    "system": "t",
    "buses": [{"name": "can0", "protocol": "can", "bitrate": "500 kbit/s"}],
    "nodes": [
        {"name": "sensor", "buses": ["can0"], "tasks": [{"name": "sample", "period": "10 ms", "wcet": "1 ms"}]},
        {"name": "motor", "buses": ["can0"], "tasks": [{"name": "drive", "on_message": "odometry", "wcet": "1 ms"}]},
    ],
    "messages": [
        {"name": "heartbeat_x", "producer": "sensor", "consumers": ["motor"], "id": 0x101, "size": 1,
         "period": "100 ms"},
        {"name": "odometry", "producer": "sensor", "consumers": ["motor"], "id": 0x100, "size": 2, "period": "10 ms"},
    ],
    "flows": [{"name": "loop", "chain": ["sensor.sample", "odometry", "motor.drive"]}],
}


def _set(path: tuple[Any, ...], value: Any) -> Callable[[dict[str, Any]], None]:
    def apply(spec: dict[str, Any]) -> None:
        node: Any = spec
        for part in path[:-1]:
            node = node[part]
        node[path[-1]] = value

    return apply


def _rename_key(path: tuple[Any, ...], old: str, new: str) -> Callable[[dict[str, Any]], None]:
    def apply(spec: dict[str, Any]) -> None:
        node: Any = spec
        for part in path:
            node = node[part]
        node[new] = node.pop(old)

    return apply


# case -> (mutation, expected code, the name that must be suggested)
CASES: dict[str, tuple[Callable[[dict[str, Any]], None], str, str]] = {
    "key": (_rename_key(("messages", 1), "period", "perod"), "extra-forbidden", "period"),
    "nested key": (_rename_key(("nodes", 0, "tasks", 0), "wcet", "wecet"), "extra-forbidden", "wcet"),
    "enum value": (_set(("buses", 0, "protocol"), "canopn"), "literal-error", "canopen"),
    "producer": (_set(("messages", 1, "producer"), "senser"), "unknown-node", "sensor"),
    "consumer, case": (_set(("messages", 1, "consumers"), ["Motor"]), "unknown-node", "motor"),
    "node's bus": (_set(("nodes", 1, "buses"), ["can_0"]), "unknown-bus", "can0"),
    "message's bus": (_set(("messages", 1, "bus"), "cam0"), "unknown-bus", "can0"),
    "on_message": (_set(("nodes", 1, "tasks", 0, "on_message"), "odometr"), "unknown-message", "odometry"),
    "flow message step": (_set(("flows", 0, "chain", 1), "odometyr"), "unknown-message", "odometry"),
    "flow task step": (_set(("flows", 0, "chain", 0), "sensor.smaple"), "unknown-task", "sensor.sample"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_misspelt_name_gets_a_suggestion(case: str, tmp_path: Path) -> None:
    mutate, code, intended = CASES[case]
    spec = copy.deepcopy(BASE)
    mutate(spec)
    report = check_data(tmp_path, spec)
    hits = [e for e in report["errors"] if e["code"] == code]
    assert hits, report["errors"]
    assert f"did you mean '{intended}'?" in hits[0]["message"], hits[0]["message"]
    # one mistake, one error: what refers to the misspelt item is not reported again
    assert len(report["errors"]) == 1, [e["message"] for e in report["errors"]]


def test_the_unchanged_base_spec_is_valid(tmp_path: Path) -> None:
    """So every failure above comes from the one misspelling."""
    report = check_data(tmp_path, copy.deepcopy(BASE))
    assert report["errors"] == []


def test_nothing_is_suggested_when_nothing_is_close() -> None:
    assert closest("ghost", ["sensor", "motor"]) is None
    assert closest("motor", ["motor"]) is None  # the name itself is not a suggestion


def test_schema_errors_name_the_item_not_its_index(tmp_path: Path) -> None:
    """'message 'odometry'' as the cross-reference errors say it, never 'messages[1]'."""
    spec = copy.deepcopy(BASE)
    spec["messages"][1]["size"] = "two"
    spec["nodes"][0]["tasks"][0]["wcet"] = "1 parsec"
    errors = check_data(tmp_path, spec)["errors"]
    messages = [e["message"] for e in errors]
    assert any(m.startswith("size of message 'odometry':") for m in messages), messages
    assert any(m.startswith("wcet of node 'sensor' task 'sample':") for m in messages), messages
    assert not any("messages[" in m or "nodes[" in m for m in messages), messages


def test_simulator_fault_targets_get_a_suggestion() -> None:
    """Names on the command line are looked up the same way: a node, a message (ALLEX-2's SYNC is can0_SYNC)."""
    from tests.conftest import cli

    proc = cli("simulate", "specs/allex2.yaml", "--duration", "100ms", "--fault", "lose:can0_SYNK@10ms")
    assert proc.returncode == 2 and "did you mean 'can0_SYNC'?" in proc.stderr, proc.stderr  # 2: usage
    proc = cli("simulate", "specs/allex2.yaml", "--duration", "100ms", "--fault", "crash:knee_1@10ms")
    assert proc.returncode == 2 and "did you mean 'knee_" in proc.stderr, proc.stderr
