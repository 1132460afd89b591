"""A bus's link said apart from its protocol (`link:`): raw CAN over the CAN FD link is the can-fd protocol, and a
pair netcfg does not model is refused at the `link:` key (tests/bad_specs/*_link.yaml hold those)."""

from __future__ import annotations

import json
import re
from pathlib import Path

from conftest import ROOT, cli_json

from netcfg.links import LINKS
from netcfg.protocols import PROTOCOLS, Protocol, over

SPEC = ROOT / "specs" / "arm_canfd.yaml"  # protocol: can-fd, one 56-byte command frame


def _check_json(path: Path) -> dict:
    code, doc = cli_json("check", str(path))
    assert code == 0
    return doc


def _without_positions(doc: dict) -> str:
    return re.sub(r'"(line|column)": \d+|"file": "[^"]*"', "", json.dumps(doc))


def test_raw_can_over_the_fd_link_is_the_can_fd_protocol(tmp_path: Path) -> None:
    text = SPEC.read_text(encoding="utf-8")
    assert text.count("    protocol: can-fd\n") == 1
    spelled = tmp_path / "arm.yaml"
    text = text.replace("    protocol: can-fd\n", "    protocol: can\n    link: can-fd\n")
    spelled.write_text(text, encoding="utf-8")
    ours, theirs = _check_json(spelled), _check_json(SPEC)
    assert ours["buses"][0]["protocol"] == "can-fd"
    assert _without_positions(ours) == _without_positions(theirs)  # the same figures, a line further down


def test_every_protocol_runs_over_its_own_link_and_says_why_not_elsewhere() -> None:
    for name, proto in PROTOCOLS.items():
        assert over(name, None) is proto
        assert over(name, proto.link.name) is proto
        for link in LINKS.values():
            chosen = proto.over(link)
            if isinstance(chosen, Protocol):
                assert chosen.link is link
            else:
                assert link.name in chosen, (name, link.name, chosen)
    assert over("can", "can-fd") is PROTOCOLS["can-fd"]
    assert over("can-fd", "can") is PROTOCOLS["can"]
