"""netcfg.spec.schema.safe_name: free text (EDS object names, DBC and bus.yml names) becomes a name that
check_name accepts, whatever the text; names that are safe already stay as they are."""

from __future__ import annotations

import pytest

from netcfg.resolve import snake
from netcfg.spec.names import C_KEYWORDS, CPP_KEYWORDS, check_name, is_name, safe_name

HARD = [
    "",
    "_",
    "__x",
    "9lives",
    "switch",
    "Switch",
    "class",
    "_Bool",
    "INT8_MAX",
    "UINT32_C",
    "errno",
    "assert",
    "NUL",
    "com1",
    "a b-c.d",
    "Position actual value",
    "é",
    "x" * 80,
    "9" * 80,
    "int" + "_" * 70,
]


@pytest.mark.parametrize("raw", HARD)
def test_safe_name_is_always_accepted(raw: str) -> None:
    for prefix, suffix in (("sig", "_sig"), ("obj", "_obj"), ("node", "_node")):
        assert check_name(safe_name(raw, prefix, suffix)) == safe_name(raw, prefix, suffix)
    assert is_name(snake(raw))


@pytest.mark.parametrize("word", sorted(C_KEYWORDS | CPP_KEYWORDS))
def test_no_keyword_survives(word: str) -> None:
    assert is_name(safe_name(word, "sig", "_sig"))
    assert is_name(snake(word))


def test_safe_names_stay_and_others_change_as_documented() -> None:
    assert safe_name("motor_cmd", "msg", "_msg") == "motor_cmd"
    assert safe_name("int", "msg", "_msg") == "int_msg"
    assert safe_name("1st", "msg", "_msg") == "msg_1st"
    assert safe_name("_x", "msg", "_msg") == "msg_x"
    assert safe_name("", "msg", "_msg") == "msg_"
    assert snake("Position actual value") == "position_actual_value"
    assert snake("Switch") == "switch_obj"
    assert snake("1st input") == "obj_1st_input"
    assert len(safe_name("x" * 80, "msg", "_msg")) == 63
