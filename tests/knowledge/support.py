"""Strategies and helpers shared by the knowledge tests."""

from __future__ import annotations

import json
from typing import Any

from hypothesis import strategies as st

# every str Python can hold, lone surrogates included (they must survive the JSON text on disk)
any_text = st.text(st.characters(min_codepoint=0, max_codepoint=0x10FFFF, exclude_categories=()))

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | any_text,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(any_text, inner, max_size=4),
    max_leaves=12,
)

VALUES: dict[str, st.SearchStrategy[Any]] = {
    "float": st.floats(),  # NaN, infinities and -0.0 included
    "int": st.integers(),  # unbounded: big ints must keep every digit
    "bool": st.booleans(),
    "str": any_text,
    "json": json_values,
}

# non-decreasing times with many ties, so that range bounds fall on runs of equal times
time_steps = st.sampled_from([0.0, 0.0, 0.5, 1.0, 2.25])


def times_from(steps: list[float], start: float = 0.0) -> list[float]:
    times, now = [], start
    for step in steps:
        now += step
        times.append(now)
    return times


def same(a: Any, b: Any) -> bool:
    """Equal in type and in every digit: 1 vs 1.0 vs True, -0.0 vs 0.0, NaN == NaN, key order."""
    return type(a) is type(b) and json.dumps(a) == json.dumps(b)
