"""Figures the README quotes from a command's run are the ones the command prints now (they drifted before)."""

from __future__ import annotations

import json
import re

from conftest import ROOT, SPECS, cli

README = (ROOT / "README.md").read_text(encoding="utf-8")


def _num(text: str) -> float:
    return float(text.replace(",", ""))


def test_the_arm_simulation_figures_are_what_simulate_prints() -> None:
    """The CAN FD arm paragraph: the command's largest measured response, the joint closest to its bound, and the
    flow's measured range, from `netcfg simulate specs/arm_canfd.yaml --stuffing exact --runs 4 --duration 10s`."""
    text = " ".join(README.split())
    command = "netcfg simulate specs/arm_canfd.yaml --stuffing exact --runs 4 --duration 10s"
    assert command in text
    said = re.search(
        r"measured at most ([\d.,]+) us for the command .*?\(the closest: (\w+), ([\d.,]+) us against ([\d.,]+) us\)"
        r".*?the same runs measured ([\d.,]+)-([\d.,]+) us",
        text[text.index(command) :],
    )
    assert said is not None, "the README's arm paragraph changed shape: update this test with it"
    proc = cli(*command.split()[1:], "--format", "json")
    assert proc.returncode == 0, proc.stderr
    sim = json.loads(proc.stdout)
    bounds = {
        m["name"]: m["wcrt_us"]
        for b in json.loads(cli("check", str(SPECS / "arm_canfd.yaml"), "--format", "json").stdout)["buses"]
        for m in b["messages"]
    }
    measured = {m["name"]: m["response_us"]["max"] for m in sim["messages"]}
    assert round(measured["arm_command"], 1) == _num(said.group(1))
    joints = {n: v for n, v in measured.items() if n.endswith("_state")}
    closest = max(joints, key=lambda n: joints[n] / bounds[n])
    assert (closest, round(joints[closest], 1), bounds[closest]) == (
        said.group(2), _num(said.group(3)), _num(said.group(4))
    )
    flow = next(f for f in sim["flows"] if f["name"] == "joint1_loop")["latency_us"]
    assert (round(flow["min"], 1), round(flow["max"], 1)) == (_num(said.group(5)), _num(said.group(6)))
