"""Rules held once, checked where they are held.

Sources of the numbers:
* CiA 301 v4.2, object 0x1800 (TPDO communication parameter): sub 2 transmission type (1-240: every n-th SYNC;
  0: acyclic synchronous, at most once per SYNC; 254/255: event-driven, on application events and on sub 5's
  timer, CiA 301 7.3.3), sub 3 inhibit time in units of 100 us (the least gap between two sends), sub 5 event timer
  in ms (due after that long without a send);
* seed 000: ALLEX-2's SYNC period of 20 ms;
* specs/ntua_sahr.yaml: mcu_hip.sample runs every 66,667 ns and the flow hip_loop chains it to hip_encoder, sent at
  15 kHz (seed 001 section 6.3.2), i.e. every round(1e9 / 15,000) = 66,667 ns: the same rate.
"""

from __future__ import annotations

from pathlib import Path
from typing import get_args

import yaml
from conftest import SPECS

from netcfg import cia301
from netcfg.check import analyse_spec
from netcfg.emit.runtime_json import runtime_document
from netcfg.resolve import RULES as PROTOCOLS
from netcfg.spec import schema

SYNC_NS = 20_000_000  # seed 000


def test_every_protocol_of_the_spec_language_has_a_resolver() -> None:
    protocols = get_args(schema.Bus.model_fields["protocol"].annotation)
    assert set(PROTOCOLS) == set(protocols)
    for name, rules in PROTOCOLS.items():
        assert rules.name == name


def test_tpdo_timing_by_transmission_type() -> None:
    """CiA 301 0x1800: type 3 every 3rd SYNC (60 ms); type 0 at most once per SYNC; type 254 with a 10 ms event
    timer: the timer adds sends to the application's, so only an inhibit time bounds it (50 x 100 us: every 5 ms;
    none: sporadic with no bound); type 255 without a timer but with an inhibit time of 50 x 100 us: at most every
    5 ms; type 255 with neither: nothing bounds it."""
    assert cia301.tpdo_timing(3, SYNC_NS, None, None) == ("periodic", 60_000_000, None)
    assert cia301.tpdo_timing(0, SYNC_NS, None, None) == ("sporadic", None, SYNC_NS)
    assert cia301.tpdo_timing(254, SYNC_NS, 10, None) == ("sporadic", None, None)
    assert cia301.tpdo_timing(254, SYNC_NS, 10, 50) == ("sporadic", None, 5_000_000)
    assert cia301.tpdo_timing(255, SYNC_NS, None, 50) == (None, None, 5_000_000)
    assert cia301.tpdo_timing(255, SYNC_NS, None, None) == (None, None, None)
    # a synchronous type fixes the period whatever was given; the inhibit time is a floor for event-driven ones
    assert cia301.tpdo_timing(3, SYNC_NS, None, None, period_ns=1) == ("periodic", 60_000_000, None)
    assert cia301.tpdo_timing(0, SYNC_NS, None, 300, kind="sporadic") == ("sporadic", None, 30_000_000)


def _sent_by(spec: Path) -> dict[str, list[str]]:
    model, report = analyse_spec(spec)
    assert model is not None, report["errors"]  # timing verdicts do not matter here
    return {m["name"]: m["sent_by"] for m in runtime_document(model, report)["messages"]}


def test_runtime_json_says_which_task_sends_a_message(tmp_path: Path) -> None:
    """hip_encoder goes out as mcu_hip.sample finishes (the same 66,667 ns); at 80 kHz the 15 kHz task no longer
    sends it and it runs free."""
    assert _sent_by(SPECS / "ntua_sahr.yaml")["hip_encoder"] == ["mcu_hip.sample"]
    spec = yaml.safe_load((SPECS / "ntua_sahr.yaml").read_text(encoding="utf-8"))
    for m in spec["messages"]:
        if m["name"] == "hip_encoder":
            m["rate"] = "80 kHz"
    path = tmp_path / "sahr80.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    assert _sent_by(path)["hip_encoder"] == []
