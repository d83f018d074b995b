"""run_app copies each record without a JSON round trip: the copy must be the round trip's."""

from __future__ import annotations

import json
import math
from enum import IntEnum

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.testing.apps import _jsonable, json_copy, trace_line

# every character, surrogates included (the JSON decoder joins a surrogate pair into one)
TEXT = st.text(st.characters(codec=None, categories=None), max_size=6) | st.sampled_from(
    ["", "time", "\ud83d\ude00", "\ud800", "😀", "é"]
)
SCALARS = (
    st.none()
    | st.booleans()
    | st.integers()
    | st.integers(min_value=-(2**70), max_value=2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | TEXT
)
KEYS = TEXT | st.integers(-3, 3) | st.booleans() | st.none() | st.floats(-2, 2)
VALUES = st.recursive(
    SCALARS,
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.lists(inner, max_size=4).map(tuple)
        | st.dictionaries(TEXT, inner, max_size=4)
        | st.dictionaries(KEYS, inner, max_size=4)
    ),
    max_leaves=20,
)
FAST = settings(max_examples=600, deadline=None, database=None)


def same(a, b) -> bool:
    """Equal with the same types all the way down, a nan equal to a nan."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return list(a) == list(b) and all(same(a[k], b[k]) for k in a)
    return a == b


def round_trip(value):
    try:
        return json.loads(json.dumps(value))
    except (TypeError, ValueError) as exc:
        return type(exc)


def fast(function, *args):
    try:
        return function(*args)
    except (TypeError, ValueError) as exc:
        return type(exc)


@FAST
@given(VALUES)
def test_json_copy_is_the_json_round_trip(value):
    assert same(fast(json_copy, value), round_trip(value))


@FAST
@given(st.dictionaries(KEYS, VALUES, max_size=6), st.floats(0, 1e6) | st.integers(0, 10**6))
def test_a_trace_line_is_the_record_as_the_trace_file_has_it(record, time):
    expected = round_trip({"time": round(time, 9), **{k: _jsonable(v) for k, v in record.items()}})
    assert same(fast(trace_line, time, record), expected)


def test_the_copy_shares_no_container_with_the_record():
    record = {"plan": {"mode": "boost", "steps": [1, 2.5]}, "broken_rules": ("a", "b")}
    line = trace_line(1.0, record)
    assert line == {
        "time": 1.0,
        "plan": {"mode": "boost", "steps": [1, 2.5]},
        "broken_rules": ["a", "b"],
    }
    record["plan"]["steps"].append(3)
    assert line["plan"]["steps"] == [1, 2.5]


class Level(IntEnum):
    LOW = 1


@pytest.mark.parametrize(
    "value",
    [
        Level.LOW,  # subclasses take the round trip: an int back
        {1: "a", "1": "b"},  # keys that collide once converted
        [float("nan"), math.inf, -0.0],
        [[[[[[[[1]]]]]]]] * 3,
        10**5000,  # the round trip refuses it: so does the copy
        {"a": {1, 2}},
    ],
    ids=["int-enum", "colliding-keys", "non-finite", "deep", "huge-int", "set"],
)
def test_odd_values_take_the_round_trip(value):
    assert same(fast(json_copy, value), round_trip(value))


def test_a_circular_value_fails_like_the_round_trip():
    value: list = []
    value.append(value)
    with pytest.raises(ValueError, match="Circular"):
        json_copy(value)
