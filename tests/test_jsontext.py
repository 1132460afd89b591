"""netcfg.jsontext.dumps writes what json.dumps writes (the reference: Python's own json module), byte for byte,
and leaves every error to it."""

from __future__ import annotations

import enum
import json
import math
from collections import OrderedDict

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from netcfg.jsontext import dumps


class Level(enum.IntEnum):
    LOW = 1


class Text(str):
    pass


scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),  # any code point: escapes, surrogates, non-ASCII
    st.sampled_from([Level.LOW, Text("ü\"x")]),
)
keys = st.one_of(st.text(max_size=6), st.integers(-5, 5), st.floats(allow_nan=False), st.booleans(), st.none())
documents = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.lists(inner, max_size=3).map(tuple),
        st.dictionaries(keys, inner, max_size=4),
        st.dictionaries(st.text(max_size=4), inner, max_size=3).map(OrderedDict),
    ),
    max_leaves=25,
)


@settings(max_examples=400, deadline=None)
@given(documents, st.sampled_from([0, 1, 2, 4]), st.booleans(), st.booleans())
def test_the_text_is_json_dumps_text(doc: object, indent: int, sort_keys: bool, ensure_ascii: bool) -> None:
    try:
        expected = json.dumps(doc, indent=indent, sort_keys=sort_keys, ensure_ascii=ensure_ascii)
    except TypeError:  # keys of mixed types cannot be sorted: the same error from both
        with pytest.raises(TypeError):
            dumps(doc, indent=indent, sort_keys=sort_keys, ensure_ascii=ensure_ascii)
        return
    assert dumps(doc, indent=indent, sort_keys=sort_keys, ensure_ascii=ensure_ascii) == expected


def test_errors_are_json_dumps_errors() -> None:
    with pytest.raises(ValueError, match="Out of range float"):
        dumps({"x": [math.nan]}, allow_nan=False)
    loop: list[object] = []
    loop.append(loop)
    with pytest.raises(ValueError, match="Circular reference"):
        dumps({"a": loop})
    with pytest.raises(TypeError, match="not JSON serializable"):
        dumps({"a": {1, 2}})
    with pytest.raises(TypeError, match="keys must be"):
        dumps({(1, 2): 3})
    assert dumps({"nan": math.nan, "inf": [-math.inf]}) == json.dumps({"nan": math.nan, "inf": [-math.inf]}, indent=2)


def test_a_check_report_is_written_as_json_dumps_writes_it() -> None:
    from conftest import SPECS

    from netcfg.check import check

    report = check(SPECS / "allex2.yaml")
    assert dumps(report) == json.dumps(report, indent=2)
    assert dumps(report, indent=1, sort_keys=True, allow_nan=False) == json.dumps(
        report, indent=1, sort_keys=True, allow_nan=False
    )
