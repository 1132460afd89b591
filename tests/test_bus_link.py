"""A bus's link said apart from its protocol (`link:`): raw CAN over the CAN FD link is the can-fd protocol, and a
pair netcfg does not model is refused at the `link:` key (tests/bad_specs/*_link.yaml hold those). runtime.json
states each bus's link, which the runtime reads to tell CAN frames from datagrams; a file written before it loads
each bus over the one link its protocol then ran over."""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import pytest
from conftest import ROOT, cli_json

import netcfg.runtime as rt
from netcfg.links import LINKS
from netcfg.protocols import PROTOCOLS, Protocol, over
from netcfg.runtime import config as rt_config
from netcfg.runtime import schema as rt_schema

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


# --- the link as runtime.json states it ------------------------------------------------------------------------

# Each bus of the committed outputs and the link its spec's protocol runs over: CANopen is CiA 301's, on classical
# CAN (ISO 11898-1); FTT-CAN is classical CAN (seed 002); `can-fd` is the CAN FD link; ethernet-udp is switched
# Ethernet (seed 001); an EtherCAT segment is its own link (ETG.1000)
STATED = {
    "allex2": {"can0": "can"},
    "allex2_ethercat": {"ecat0": "ethercat"},
    "arm_canfd": {"arm": "can-fd"},
    "cambada": {"lowlevel": "can"},
    "large_plant": {"motion": "can", "plant": "can", "cell": "can"},
    "ntua_sahr": {"lan": "ethernet"},
    "ntua_treadmill": {"lan": "ethernet"},
}
# the protocols runtime.json named before its buses stated their link (netcfg.runtime.schema.PROTOCOLS then)
EARLIER_PROTOCOLS = {"can", "can-fd", "canopen", "ftt-can", "ethernet-udp", "ethercat"}


def _runtime_json(system: str) -> dict:
    return json.loads((ROOT / "generated" / system / "runtime.json").read_text(encoding="utf-8"))


def test_runtime_json_states_each_bus_link() -> None:
    got = {s: {b["name"]: b["link"] for b in _runtime_json(s)["buses"]} for s in STATED}
    assert got == STATED
    cfg = rt.load(ROOT / "generated" / "large_plant" / "runtime.json")
    assert {m.link for m in cfg.messages if m.bus == "plant"} == {"can"}


def test_the_runtime_tables_of_links_are_the_link_layer() -> None:
    """The runtime cannot import netcfg.links (it imports without the compiler), so it keeps the links' names and
    what it reads of them; these are the link layer's own."""
    assert set(rt_schema.LINKS) == set(LINKS)
    assert set(rt_config.CAN_LINKS) == {name for name, link in LINKS.items() if link.arbitrates}
    assert set(rt_config.SWITCHED_LINKS) == {name for name, link in LINKS.items() if link.switched}
    # is_udp reads a switched link as UDP datagrams: the one protocol netcfg runs over one
    assert [p.name for p in PROTOCOLS.values() if p.link.switched] == ["ethernet-udp"]
    assert set(rt_schema.EARLIER_LINKS) == EARLIER_PROTOCOLS
    assert {p: PROTOCOLS[p].link.name for p in EARLIER_PROTOCOLS} == rt_schema.EARLIER_LINKS


@pytest.mark.parametrize("system", sorted(STATED))
def test_a_file_written_before_buses_stated_their_link_loads_the_same(system: str) -> None:
    doc = _runtime_json(system)
    new = rt.parse(copy.deepcopy(doc), "new.json")
    for b in doc["buses"]:
        del b["link"]
    old = rt.parse(doc, "old.json")
    assert [(b.name, b.link, b.is_can, b.is_udp) for b in old.buses] == [
        (b.name, STATED[system][b.name], b.is_can, b.is_udp) for b in new.buses
    ]
    assert [(m.name, m.link, m.is_can, m.is_udp) for m in old.messages] == [
        (m.name, m.link, m.is_can, m.is_udp) for m in new.messages
    ]


def test_a_bus_without_link_whose_protocol_came_later_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """A protocol added since buses state their link has no earlier file: one without the key is damaged."""
    doc = _runtime_json("allex2")
    del doc["buses"][0]["link"]
    monkeypatch.delitem(rt_schema.EARLIER_LINKS, "canopen")
    with pytest.raises(rt.RuntimeConfigError, match=re.escape("bus 'can0': a canopen bus needs its 'link'")):
        rt.parse(doc, "old.json")
