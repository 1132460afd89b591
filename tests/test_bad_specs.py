"""Bad specs: each file in tests/bad_specs holds exactly one mistake (named in its first-line comment).

`netcfg check` must exit 1 without a traceback and report the mistake at the line a user would look at: the
offending key or value (for a missing key: the mapping that lacks it; for a bus-wide problem: the bus).
The expected lines below were chosen by reading the files, not copied from netcfg's output. Cases where
netcfg is wrong today are strict xfails, so that fixing the program makes them fail loudly here.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from netcfg.commands import main

BAD = Path(__file__).parent / "bad_specs"
ROOT = Path(__file__).parent.parent

# file -> (expected line, expected code, substring of the expected message)
EXPECTED: dict[str, tuple[int, str, str]] = {
    "yaml_bad_indent.yaml": (6, "yaml-syntax", "YAML syntax error"),
    "yaml_unclosed_bracket.yaml": (9, "yaml-syntax", "YAML syntax error"),
    "yaml_tab_indent.yaml": (11, "yaml-syntax", "tab character"),
    "yaml_duplicate_key.yaml": (19, "duplicate-key", "key 'period' appears twice"),
    "yaml_python_tag.yaml": (2, "yaml-value", "cannot read this value"),
    "yaml_python_tag_on_list.yaml": (7, "yaml-value", "cannot read this value"),
    "yaml_deep_nesting.yaml": (3, "yaml-syntax", "deep"),
    "yaml_alias_bomb.yaml": (3, "too-large", "expands to more than"),
    "sync_id_fixed_by_device.yaml": (9, "sync-id", "fixed COB-ID SYNC (0x1005) of 0x080"),
    "sync_start_on_event_tpdo.yaml": (16, "sync-start", "synchronous TPDOs"),
    "signal_scale_zero.yaml": (15, "value-error", "scale of 0"),
    "name_cpp_keyword.yaml": (15, "value-error", "C or C++ keyword"),
    "signal_overlap.yaml": (16, "signal-overlap", "overlaps signal 'a'"),
    "sync_task_not_on_canopen.yaml": (10, "task-sync", "exactly one bus with a cycle for it"),
    "name_taken_by_sync.yaml": (12, "duplicate-name", "taken by the SYNC of bus can0"),
    "canopen_master_overruns_cycle.yaml": (13, "master-cycle", "ends up to 2.5 ms after SYNC"),
    "canopen_master_jitter_negative.yaml": (7, "value-error", "cannot read '-5 us' as a duration"),
    "ftt_macro_cycle_too_long.yaml": (7, "macro-cycle", "323,323 ECs"),
    "type_bool_for_int.yaml": (16, "int-type", "valid integer"),
    "duration_too_large.yaml": (18, "value-error", "1e30 s"),
    "spec_is_list.yaml": (2, "not-a-mapping", "a spec is a mapping"),
    "empty_file.yaml": (1, "empty-spec", "the spec is empty"),
    "yaml_not_utf8.yaml": (3, "encoding", "not UTF-8"),
    "type_string_for_int.yaml": (17, "int-type", "valid integer"),
    "type_string_for_list.yaml": (15, "list-type", "valid list"),
    "duration_bare_number.yaml": (18, "value-error", "with a unit"),
    "duration_unknown_unit.yaml": (18, "value-error", "unknown time unit 'parsec'"),
    "bitrate_bare_number.yaml": (6, "value-error", "with a unit"),
    "protocol_unknown.yaml": (5, "literal-error", "'ethernet-udp'"),
    "canfd_no_data_bitrate.yaml": (4, "data-bitrate", "needs 'data_bitrate'"),
    "canfd_payload_over_64.yaml": (18, "payload", "65 bytes do not fit a CAN FD frame"),
    "canfd_classical_frame_over_8.yaml": (19, "payload", "do not fit a classical frame"),
    "canfd_data_bitrate_below_bitrate.yaml": (7, "data-bitrate", "cannot be slower than arbitration"),
    "canfd_brs_on_classical_can.yaml": (17, "wrong-section", "'brs' is a CAN FD setting"),
    "canfd_data_bitrate_on_classical_can.yaml": (7, "wrong-section", "'data_bitrate' is the CAN FD data phase"),
    "canopen_over_ethernet_link.yaml": (6, "link", "CANopen over ethernet is not modelled"),
    "canopen_fd_classical_pdo.yaml": (14, "payload", "do not fit a classical frame (at most 8); drop 'fd: false'"),
    "ftt_over_ethernet_link.yaml": (6, "link", "FTT-CAN over ethernet is not modelled"),
    "ftt_over_canfd_no_data_bitrate.yaml": (4, "data-bitrate", "needs 'data_bitrate'"),
    "udp_over_can_link.yaml": (6, "link", "does not model it over can"),
    "unknown_key_typo.yaml": (18, "extra-forbidden", "unknown key 'perod'"),
    "missing_system.yaml": (2, "missing", "missing required key 'system'"),
    "missing_producer.yaml": (13, "missing", "missing required key 'producer'"),
    "missing_task_wcet.yaml": (11, "missing", "missing required key 'wcet'"),
    "unknown_producer.yaml": (14, "unknown-node", "node 'ghost'"),
    "unknown_consumer.yaml": (15, "unknown-node", "node 'ghost'"),
    "node_on_undefined_bus.yaml": (13, "unknown-bus", "'can1'"),
    "message_unknown_bus.yaml": (14, "unknown-bus", "'can9'"),
    "trigger_unknown_task.yaml": (36, "unknown-task", "'b.ghost'"),
    "flow_unknown_step.yaml": (27, "unknown-message", "'ghost'"),
    "on_message_unknown.yaml": (16, "unknown-message", "'ghost'"),
    "duplicate_node_name.yaml": (12, "duplicate-name", "'a' is used twice"),
    "duplicate_message_name.yaml": (19, "duplicate-name", "'m' is used twice"),
    "duplicate_name_case.yaml": (19, "duplicate-name", "differ only in case"),
    "duplicate_can_id.yaml": (22, "duplicate-id", "collides with 'm'"),
    "duplicate_node_id.yaml": (19, "duplicate-node-id", "already used by 'drive'"),
    "cobid_collides_with_sdo.yaml": (23, "duplicate-id", "SDO"),
    "cobid_collides_with_heartbeat.yaml": (23, "duplicate-id", "heartbeat"),
    "cobid_collides_with_emcy.yaml": (23, "duplicate-id", "EMCY"),
    "cobid_restricted.yaml": (23, "restricted-id", "restricted"),
    "node_id_zero.yaml": (15, "node-id", "1..127"),
    "node_id_128.yaml": (15, "node-id", "1..127"),
    "pdo_over_64_bits.yaml": (25, "pdo-length", "96 bits"),
    "pdo_unknown_object.yaml": (27, "unknown-object", "0x6099"),
    "joint_unknown_node.yaml": (30, "unknown-node", "there is no node 'drvie'"),
    "joint_signal_not_mapped.yaml": (35, "joint-signal", "does not map 'velocity_actual_value' into message 'state'"),
    "joint_limits_outside_signal.yaml": (37, "joint-limits", "which carries -32.768..32.767 N m"),
    "joint_two_on_one_axis.yaml": (33, "joint-axis", "axis 1 of node 'drive' already moves joint 'hip'"),
    "joint_position_without_encoder_counts.yaml": (29, "joint-scale", "give encoder_counts"),
    "joint_name_twice.yaml": (32, "duplicate-name", "joint 'hip' appears twice"),
    "pdo_not_mappable.yaml": (34, "not-mappable", "not PDO-mappable"),
    "pdo_readonly_in_rpdo.yaml": (26, "pdo-direction", "read-only"),
    "tpdo_number_above_device.yaml": (30, "pdo-number", "TPDO 5 does not exist"),
    "epos4_event_timer.yaml": (31, "event-timer", "no TPDO event timer"),
    "heartbeat_not_on_device.yaml": (17, "heartbeat", "no producer heartbeat time (0x1017)"),
    "unknown_device_profile.yaml": (16, "unknown-device", "'epos9'"),
    "eds_file_missing.yaml": (16, "eds-missing", "not found"),
    "ftt_period_not_ec_multiple.yaml": (23, "ec-multiple", "not a whole number"),
    "ftt_offset_not_ec_multiple.yaml": (24, "ec-multiple", "not a whole number"),
    "ftt_offset_not_below_period.yaml": (24, "offset", "must be smaller than the period"),
    "ftt_trigger_period_range_not_ec_multiple.yaml": (25, "ec-multiple", "23 ms is not a whole number of ECs"),
    "ftt_id_beyond_capacity.yaml": (24, "ftt-id-range", "does not fit"),
    "can_payload_over_8.yaml": (17, "payload", "at most 8"),
    "can_id_over_11_bits.yaml": (16, "id-range", "11 bits"),
    "can_bitrate_too_high.yaml": (6, "bitrate", "at most 1 Mbit/s"),
    "errors_interval_zero.yaml": (7, "errors", "interval must be a time longer than 0"),
    "errors_ber_above_one.yaml": (9, "less-than", "less than 1"),
    "producer_not_on_bus.yaml": (18, "not-on-bus", "node 'a' is not on bus 'can1'"),
    "name_path_traversal.yaml": (2, "value-error", "not a safe name"),
    "name_comment_close.yaml": (13, "value-error", "not a safe name"),
    "name_comment_include.yaml": (11, "value-error", "not a safe name"),
    "name_c_keyword.yaml": (13, "value-error", "C or C++ keyword"),
    "name_windows_reserved.yaml": (2, "value-error", "reserved file name"),
    "name_with_space.yaml": (18, "value-error", "not a safe name"),
    "name_unicode.yaml": (2, "value-error", "not a safe name"),
    "ethernet_three_nodes_no_switch.yaml": (4, "topology", "no switch"),
    "ethernet_switch_loop.yaml": (19, "topology", "closes a loop (sw1 - sw2 - sw3 - sw1)"),
    "ethernet_parallel_cables.yaml": (13, "topology", "loop"),
    "ethernet_id_above_ff.yaml": (16, "id-range", "one byte"),
    "task_bcet_above_wcet.yaml": (14, "bcet", "exceeds worst case"),
    "task_no_activation.yaml": (11, "task-period", "no period, no trigger"),
    "flow_message_wrong_producer.yaml": (34, "flow-chain", "produced by 'b'"),
}

# netcfg bugs found by these specs (exact output in each reason). Remove an entry once the program is fixed.
KNOWN_BUGS: dict[str, str] = {}

# The handful run as real processes, to prove no traceback escapes the real CLI (incl. non-UTF-8 and broken YAML).
SUBPROCESS_FILES = [
    "yaml_not_utf8.yaml",
    "yaml_bad_indent.yaml",
    "yaml_unclosed_bracket.yaml",
    "yaml_tab_indent.yaml",
    "yaml_duplicate_key.yaml",
    "yaml_python_tag.yaml",
    "empty_file.yaml",
    "spec_is_list.yaml",
    "cobid_collides_with_sdo.yaml",
    "name_comment_include.yaml",
    "yaml_deep_nesting.yaml",
    "duration_too_large.yaml",
]
# Of those, the ones whose real process crashes today (traceback or exit code other than 1).
CRASHES: set[str] = set()


def _cases(names: list[str], bugs: dict[str, str] | set[str]) -> list[object]:
    out = []
    for name in names:
        reason = KNOWN_BUGS[name] if name in bugs else None
        marks = [pytest.mark.xfail(reason=reason, strict=True)] if reason else []
        out.append(pytest.param(name, marks=marks, id=name.removesuffix(".yaml")))
    return out


def _run_main(capsys: pytest.CaptureFixture[str], args: list[str]) -> tuple[int, str, str]:
    try:
        rc = main(args)
    except SystemExit as exc:  # argparse
        rc = exc.code if isinstance(exc.code, int) else 2
    captured = capsys.readouterr()
    return rc, captured.out, captured.err


def _run_process(args: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "netcfg", *args], cwd=ROOT, capture_output=True, text=True, timeout=120, check=False
    )


def _describe(errors: list[dict[str, object]]) -> str:
    return "\n".join(f"  {e['line']}:{e['column']} [{e['code']}] {e['message']}" for e in errors) or "  (no errors)"


def _check_json(name: str, out: str) -> None:
    line, code, text = EXPECTED[name]
    doc = json.loads(out)
    assert doc["ok"] is False
    errors = doc["errors"]
    hits = [
        e
        for e in errors
        if str(e["file"]).endswith(name)
        and e["line"] == line
        and e["column"] >= 1
        and e["code"] == code
        and text in e["message"]
    ]
    assert hits, f"expected an error at line {line}, code {code!r}, message containing {text!r}; got:\n" + _describe(
        errors
    )


def _check_text(name: str, path: Path, err: str) -> None:
    line, code, text = EXPECTED[name]
    where = re.escape(str(path))
    pattern = re.compile(rf"^{where}:{line}:[1-9][0-9]*: error: (?P<msg>.*) \[{re.escape(code)}\]$", re.M)
    assert any(text in m["msg"] for m in pattern.finditer(err)), f"no '{path}:{line}:<column>: error' line:\n{err}"


def test_folder_has_at_least_40_specs() -> None:
    assert len(list(BAD.glob("*.yaml"))) >= 40


def test_every_spec_has_an_expectation_and_a_comment() -> None:
    files = {p.name for p in BAD.glob("*.yaml")}
    assert files == set(EXPECTED), f"without expectation: {files - set(EXPECTED)}; missing: {set(EXPECTED) - files}"
    assert set(KNOWN_BUGS) <= files
    for name in files:
        assert (BAD / name).read_bytes().startswith(b"# Mistake: "), f"{name}: first line must say the mistake"


@pytest.mark.parametrize("name", _cases(sorted(EXPECTED), set(KNOWN_BUGS)))
def test_bad_spec_is_reported_in_place(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    path = BAD / name
    rc, out, err = _run_main(capsys, ["check", "--format", "json", str(path)])
    assert rc == 1, f"exit code {rc}, errors:\n{_describe(json.loads(out)['errors'])}\n{err}"
    assert "Traceback" not in out + err
    _check_json(name, out)

    rc, out, err = _run_main(capsys, ["check", str(path)])
    assert rc == 1
    assert "Traceback" not in out + err
    _check_text(name, path, err)


@pytest.mark.parametrize("name", _cases(SUBPROCESS_FILES, CRASHES))
def test_real_process_never_shows_a_traceback(name: str) -> None:
    path = BAD / name
    for fmt in ("json", "text"):
        proc = _run_process(["check", "--format", fmt, str(path)])
        assert "Traceback" not in proc.stdout + proc.stderr, proc.stderr[-1500:]
        assert proc.returncode == 1, f"--format {fmt}: exit code {proc.returncode}\n{proc.stderr}"
        if fmt == "json":
            doc = json.loads(proc.stdout)
            assert doc["ok"] is False
            assert any(str(e["file"]).endswith(name) and e["line"] >= 1 and e["column"] >= 1 for e in doc["errors"])
        else:
            assert re.search(rf"^{re.escape(str(path))}:[1-9][0-9]*:[1-9][0-9]*: error: ", proc.stderr, re.M)


def test_missing_spec_file_exits_2_without_traceback(tmp_path: Path) -> None:
    missing = tmp_path / "no_such_spec.yaml"
    for fmt in ("json", "text"):
        proc = _run_process(["check", "--format", fmt, str(missing)])
        assert proc.returncode == 2, proc.stderr
        assert "Traceback" not in proc.stdout + proc.stderr
        assert "no_such_spec.yaml" in proc.stderr


def test_missing_spec_file_in_process(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc, _, err = _run_main(capsys, ["check", str(tmp_path / "no_such_spec.yaml")])
    assert rc == 2
    assert "cannot read" in err


def test_a_folder_of_bad_specs_checks_each_and_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    """`check DIR` checks every spec in the folder (issue 21; a folder without specs is exit 2, see
    test_check_folder.py): every file here has a mistake, so each is reported and the run fails."""
    rc, out, err = _run_main(capsys, ["check", "--quiet", str(BAD)])
    assert rc == 1
    assert "Traceback" not in out + err
    reported = {line.split(":", 1)[0] for line in err.splitlines() if ": error: " in line}
    assert reported == {str(p) for p in BAD.glob("*.yaml")}


def test_zero_byte_spec(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = tmp_path / "zero.yaml"
    spec.write_bytes(b"")
    rc, out, _ = _run_main(capsys, ["check", "--format", "json", str(spec)])
    assert rc == 1
    errors = json.loads(out)["errors"]
    assert [(e["line"], e["column"], e["code"]) for e in errors] == [(1, 1, "empty-spec")]
