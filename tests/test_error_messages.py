"""Error messages a new user met that were not as good as the rest: each names what is wrong, where, and the fix.
The expectations are the project's issue "Every command agrees with every other" (its list of messages to mend)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from conftest import ROOT, check, check_data, cli

DRIVE_EDS = ROOT / "tests" / "data" / "seams" / "drive_et.eds"


def canopen_spec(nodes: list[dict[str, Any]], messages: list[dict[str, Any]]) -> dict[str, Any]:
    return {
        "system": "msgs",
        "buses": [{"name": "can0", "protocol": "canopen", "bitrate": "1 Mbit/s", "canopen": {"sync_period": "20 ms"}}],
        "nodes": [{"name": "master", "role": "master", "node_id": 127, "buses": ["can0"]}, *nodes],
        "messages": messages,
    }


def can_spec(messages: list[dict[str, Any]]) -> dict[str, Any]:
    return {
        "system": "msgs",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": "500k"}],
        "nodes": [{"name": "a", "buses": ["can0"]}, {"name": "b", "buses": ["can0"]}],
        "messages": messages,
    }


def test_a_duplicated_node_id_is_one_error(tmp_path: Path) -> None:
    """Two drives with node id 1, each with a heartbeat, a TPDO1 and an RPDO1: their default COB-IDs (0x701, 0x181,
    0x201, CiA 301's predefined connection set) follow from the one duplicated id, so they collide too. The user made
    one mistake: one error, at the second node's node_id."""
    pdo_nodes = [
        {"name": n, "node_id": 1, "device": "epos4", "buses": ["can0"], "heartbeat": "100 ms"} for n in ("a", "b")
    ]
    messages = [
        {"name": f"{n}_state", "producer": n, "consumers": ["master"],
         "pdo": {"tpdo": 1, "transmission": 1, "map": [0x6064]}}
        for n in ("a", "b")
    ] + [
        {"name": f"{n}_cmd", "producer": "master", "consumers": [n], "period": "20 ms",
         "pdo": {"rpdo": 1, "transmission": 255, "map": [0x60FF]}}
        for n in ("b", "a")
    ]
    errors = check_data(tmp_path, canopen_spec(pdo_nodes, messages))["errors"]
    assert [e["code"] for e in errors] == ["duplicate-node-id"], errors
    lines = (tmp_path / "spec.yaml").read_text(encoding="utf-8").splitlines()
    second = [i + 1 for i, line in enumerate(lines) if line.strip() == "node_id: 1"][1]
    assert errors[0]["line"] == second  # at node b's node_id, the second use of id 1


def test_explicit_identifiers_still_collide_beside_a_duplicated_node_id(tmp_path: Path) -> None:
    """Only identifiers derived from the duplicated id are the same mistake: an explicit COB-ID written twice is a
    second one."""
    pdo_nodes = [{"name": n, "node_id": 1, "device": "epos4", "buses": ["can0"]} for n in ("a", "b")]
    messages = [
        {"name": f"{n}_state", "producer": n, "consumers": ["master"], "id": 0x281,
         "pdo": {"tpdo": 2, "transmission": 1, "map": [0x6064]}}
        for n in ("a", "b")
    ]
    codes = sorted(e["code"] for e in check_data(tmp_path, canopen_spec(pdo_nodes, messages))["errors"])
    assert codes == ["duplicate-id", "duplicate-node-id"]


def test_an_11_bit_overflow_suggests_extended(tmp_path: Path) -> None:
    """0x814 > 0x7FF, the largest 11-bit identifier (ISO 11898-1); it fits 29 bits, so 'extended: true' is the fix."""
    msgs = [{"name": "m2", "producer": "a", "consumers": ["b"], "period": "10 ms", "size": 2, "id": 0x814}]
    (err,) = check_data(tmp_path, can_spec(msgs))["errors"]
    assert err["code"] == "id-range"
    assert "message 'm2'" in err["message"] and "extended: true" in err["message"]


@pytest.mark.parametrize(
    ("field", "value", "code"),
    [("size", 9, "payload"), ("period", "0 ms", "period")],
)
def test_payload_and_period_errors_name_their_message(tmp_path: Path, field: str, value: Any, code: str) -> None:
    """9 bytes exceed classical CAN's 8 (ISO 11898-1); a period of 0 is no period."""
    msg = {"name": "motor_cmd", "producer": "a", "consumers": ["b"], "period": "10 ms", "size": 2, "id": 0x10}
    msg[field] = value
    (err,) = check_data(tmp_path, can_spec([msg]))["errors"]
    assert err["code"] == code and "message 'motor_cmd'" in err["message"], err


def test_a_signal_outside_its_frame_is_named_at_its_line(tmp_path: Path) -> None:
    """'angle' starts at bit 12 and is 8 bits long (little-endian: bits 12..19), so it reaches byte 2 (bits 16..23)
    of a 2-byte message. The error names the signal, its start bit and the size it needs (3), at the signal."""
    spec = tmp_path / "sig.yaml"
    spec.write_text(
        "system: sig\n"
        "buses: [{name: can0, protocol: can, bitrate: 500k}]\n"
        "nodes: [{name: a, buses: [can0]}, {name: b, buses: [can0]}]\n"
        "messages:\n"
        "  - name: m\n"
        "    id: 0x10\n"
        "    producer: a\n"
        "    consumers: [b]\n"
        "    period: 10 ms\n"
        "    size: 2\n"
        "    signals:\n"
        "      - {name: speed, start_bit: 0, bits: 8}\n"
        "      - {name: angle, start_bit: 12, bits: 8}\n",
        encoding="utf-8",
    )
    (err,) = check(spec)["errors"]
    assert err["line"] == 13
    for part in ("signal 'angle'", "start bit 12", "size: 3"):
        assert part in err["message"], err["message"]


def test_a_bad_value_inside_a_vendor_eds_points_at_the_eds_line(tmp_path: Path) -> None:
    """An EPOS4 EDS (the one the seam tests carry) with one DataType written as 0xZZ, not a number (CiA 306: DataType
    is an unsigned16): the error is at that line of the EDS, and says which node's device file it is."""
    lines = DRIVE_EDS.read_text(encoding="latin-1").splitlines(keepends=True)
    at = next(i for i, line in enumerate(lines) if line.strip() == "[6064]") + 3  # ParameterName, ObjectType, DataType
    assert lines[at].startswith("DataType=")
    lines[at] = "DataType=0xZZ\n"
    (tmp_path / "drive.eds").write_text("".join(lines), encoding="latin-1")
    spec = canopen_spec(
        [{"name": "a", "node_id": 1, "device": {"eds": "drive.eds"}, "buses": ["can0"]}],
        [{"name": "a_state", "producer": "a", "consumers": ["master"],
          "pdo": {"tpdo": 1, "transmission": 1, "map": [0x6064]}}],
    )
    (err,) = check_data(tmp_path, spec)["errors"]
    assert err["code"] == "eds-invalid"
    assert Path(err["file"]).name == "drive.eds" and err["line"] == at + 1 and err["column"] == len("DataType=") + 1
    assert "node 'a'" in err["message"]


def test_a_plain_bitrate_below_1_kbits_asks_for_k(tmp_path: Path) -> None:
    """No CAN bus runs at 500 bit/s (ISO 11898 rates start in the kbit/s); '500' is 500k without its unit."""
    dbc = tmp_path / "one.dbc"
    dbc.write_text('VERSION ""\n\nBU_: A B\n\nBO_ 16 M: 1 A\n SG_ s : 0|8@1+ (1,0) [0|255] "" B\n', encoding="utf-8")
    proc = cli("check", str(dbc), "--bitrate", "500")
    assert proc.returncode == 2 and "did you mean '500k'?" in proc.stderr, proc.stderr


@pytest.mark.parametrize("name", ["new.yaml", "int.yml", "class.yaml", "3axis.yaml"])
def test_init_writes_a_spec_check_accepts_whatever_its_file_name(tmp_path: Path, name: str) -> None:
    """`init -o new.yaml` named the system 'new', a C++ keyword that check refuses (names become C identifiers)."""
    proc = cli("init", "-o", str(tmp_path / name))
    assert proc.returncode == 0, proc.stderr
    report = check(tmp_path / name)
    assert report["ok"], report["errors"]


@pytest.mark.parametrize(
    ("section", "key", "code", "title", "role"),
    [
        ({"canopen": {"sync_period": "20 ms"}}, "sync_producer", "sync-producer", "CANopen", "SYNC producer"),
        ({"ftt": {"ec": "5 ms", "tm_size": 5}}, "master", "ftt-master", "FTT-CAN", "FTT-CAN master"),
    ],
)
def test_the_node_driving_canopen_and_ftt_is_found_by_one_rule(
    tmp_path: Path, section: dict[str, Any], key: str, code: str, title: str, role: str
) -> None:
    """CANopen's SYNC producer (CiA 301) and FTT-CAN's master (seed 002) are each the node the bus's section names,
    which must be on the bus, else the bus's one node with 'role: master'. Three specs per protocol: two masters
    and no name (which one?), a name that is no node on the bus (with the close name suggested), and one master."""
    protocol = "canopen" if "canopen" in section else "ftt-can"
    (name,) = section

    def spec(masters: int, given: str | None) -> dict[str, Any]:
        body = {**section[name], **({key: given} if given else {})}
        nodes = [{"name": f"m{i}", "role": "master", "node_id": 120 + i, "buses": ["bus0"]} for i in range(masters)]
        return {"system": "t", "buses": [{"name": "bus0", "protocol": protocol, "bitrate": "1M", name: body}],
                "nodes": nodes, "messages": []}

    (err,) = check_data(tmp_path, spec(2, None))["errors"]
    lines = (tmp_path / "spec.yaml").read_text(encoding="utf-8").splitlines()
    # at the section that lacks the key: its mapping, which starts on the line below `name:` (1-based: + 2)
    assert (err["code"], err["line"]) == (code, lines.index(f"  {name}:") + 2)
    assert err["message"].startswith(f"{title} bus 'bus0' needs one node with 'role: master' (found 2)")
    assert f"'{name}: {{{key}: <node>}}'" in err["message"]
    (err,) = check_data(tmp_path, spec(1, "m_0"))["errors"]
    assert err["code"] == "unknown-node"
    assert err["message"] == f"{role} 'm_0' is not a node on bus 'bus0' (did you mean 'm0'?)"
    assert check_data(tmp_path, spec(1, None))["errors"] == []
