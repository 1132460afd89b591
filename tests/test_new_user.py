"""A second new-user pass (issue 21): two specs written from the schema with the mistakes people make. Each mistake
must give one error, at its file:line:column, that names the fix, and nothing that follows from it; the unit
grammar is the same in the spec as on the command line (`500k`, `1M`).

The references: the README's unit table and CiA 301 (node ids 1..127, default PDO COB-IDs 0x180/0x200 + node id).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.conftest import ROOT, check_data

CANOPEN: dict[str, Any] = {
    "system": "arm",
    "buses": [{"name": "can1", "protocol": "canopen", "bitrate": "1 Mbit/s", "canopen": {"sync_period": "10 ms"}}],
    "nodes": [
        {"name": "pc", "role": "master", "node_id": 127, "buses": ["can1"]},
        {"name": "shoulder", "node_id": 1, "device": "epos4", "buses": ["can1"], "heartbeat": "100 ms"},
    ],
    "messages": [
        {"name": "shoulder_cmd", "producer": "pc", "consumers": ["shoulder"], "period": "10 ms",
         "pdo": {"rpdo": 1, "transmission": 255, "map": [0x60FF]}},
        {"name": "shoulder_fb", "producer": "shoulder", "consumers": ["pc"],
         "pdo": {"tpdo": 1, "transmission": 1, "map": [0x6064, 0x606C]}},
    ],
}

CAN: dict[str, Any] = {
    "system": "rover",
    "buses": [{"name": "can0", "protocol": "can", "bitrate": "500 kbit/s"}],
    "nodes": [
        {"name": "brain", "buses": ["can0"]},
        {"name": "motor", "buses": ["can0"], "tasks": [{"name": "ctrl", "period": "1 ms", "wcet": "100 us"}]},
    ],
    "messages": [
        {"name": "cmd", "id": 0x100, "producer": "brain", "consumers": ["motor"], "size": 4, "period": "10 ms",
         "offset": "2 ms"},
    ],
    "flows": [{"name": "steer", "chain": ["cmd", "motor.ctrl"]}],
}


def _set(path: tuple[Any, ...], value: Any) -> Callable[[dict[str, Any]], None]:
    def apply(spec: dict[str, Any]) -> None:
        node: Any = spec
        for part in path[:-1]:
            node = node[part]
        if value is None:
            del node[path[-1]]
        else:
            node[path[-1]] = value

    return apply


# case -> (base, mutation, error code, words the one error must say)
CASES: dict[str, tuple[dict[str, Any], Callable[[dict[str, Any]], None], str, str]] = {
    "misspelt device": (CANOPEN, _set(("nodes", 1, "device"), "epos"), "unknown-device", "did you mean 'epos4'?"),
    "device node on a misspelt bus": (
        CANOPEN, _set(("nodes", 1, "buses"), ["can_1"]), "unknown-bus", "did you mean 'can1'?"
    ),
    "node id beyond CANopen's 127": (CANOPEN, _set(("nodes", 1, "node_id"), 130), "node-id", "1..127"),
    "no node id": (CANOPEN, _set(("nodes", 1, "node_id"), None), "node-id", "needs a node_id"),
    "time unit msec": (CAN, _set(("messages", 0, "offset"), "2 msec"), "value-error", "did you mean 'ms'?"),
    "time unit sec": (CAN, _set(("messages", 0, "period"), "1 sec"), "value-error", "did you mean 's'?"),
    "bit-rate unit kbits": (CAN, _set(("buses", 0, "bitrate"), "500 kbits"), "value-error", "did you mean 'kbit/s'?"),
    "bit-rate unit kbaud": (CAN, _set(("buses", 0, "bitrate"), "500 kbaud"), "value-error", "did you mean 'kbit/s'?"),
    "a consumer not in a list": (
        CAN, _set(("messages", 0, "consumers"), "motor"), "list-type", "write it as a list, e.g. [motor]"
    ),
    # 1 / 100 Hz = 10 ms
    "a period in Hz": (CAN, _set(("messages", 0, "period"), "100 Hz"), "value-error", "frequency, not a time: "
                       "write '10 ms', or 'rate: 100 Hz'"),
    "9 bytes on classical CAN": (CAN, _set(("messages", 0, "size"), 9), "payload", "'protocol: can-fd'"),
    "flow step on a node without tasks": (
        CAN, _set(("flows", 0, "chain"), ["brain.plan", "cmd", "motor.ctrl"]), "unknown-task",
        "node 'brain' has no tasks: declare 'plan' under its tasks:",
    ),
    "flow step on a node with other tasks": (
        CAN, _set(("flows", 0, "chain"), ["cmd", "motor.control"]), "unknown-task", "node 'motor' has the tasks ctrl",
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_one_mistake_one_error_that_names_the_fix(case: str, tmp_path: Path) -> None:
    base, mutate, code, says = CASES[case]
    spec = copy.deepcopy(base)
    mutate(spec)
    report = check_data(tmp_path, spec)
    assert [e["code"] for e in report["errors"]] == [code], [e["message"] for e in report["errors"]]
    error = report["errors"][0]
    assert says in error["message"], error["message"]
    assert error["file"].endswith("spec.yaml") and error["line"] > 1 and error["column"] >= 1


@pytest.mark.parametrize("base", [CAN, CANOPEN], ids=["can", "canopen"])
def test_the_unchanged_bases_are_valid(base: dict[str, Any], tmp_path: Path) -> None:
    """So every failure above comes from its one mistake."""
    assert check_data(tmp_path, copy.deepcopy(base))["errors"] == []


@pytest.mark.parametrize(("written", "bits"), [("500k", 500_000), ("500 k", 500_000), ("1M", 1_000_000)])
def test_short_bit_rates_read_in_the_spec_as_on_the_command_line(written: str, bits: int, tmp_path: Path) -> None:
    """`--bitrate 500k` worked and `bitrate: 500k` did not: one grammar now (k = 10^3, M = 10^6 bit/s)."""
    spec = copy.deepcopy(CAN)
    spec["buses"][0]["bitrate"] = written
    report = check_data(tmp_path, spec)
    assert report["errors"] == [] and report["buses"][0]["bitrate"] == bits


def test_transmit_queue_and_clock_tolerance_on_ethernet_are_named_as_without_effect(tmp_path: Path) -> None:
    """Both belong to the CAN analysis: on an Ethernet bus or a node on no CAN bus they change nothing, which a
    warning says (an Ethernet bus's `errors:` is refused outright, it has no model to apply there)."""
    data = yaml.safe_load((ROOT / "specs" / "ntua_sahr.yaml").read_text(encoding="utf-8"))
    data["buses"][0]["clock_tolerance"] = 50
    data["nodes"][0]["tx_queue"] = "fifo"
    report = check_data(tmp_path, data)
    texts = [w["message"] for w in report["warnings"]]
    assert any("'clock_tolerance' is counted by the CAN analysis" in t for t in texts)
    assert any("is on no CAN bus: its tx_queue has no effect" in t for t in texts)
