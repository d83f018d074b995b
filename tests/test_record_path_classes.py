"""The per-record class tests: ``type()`` first (a pointer test), ``__class__`` only after.

Telegraf's digest, the store's ring and the platform's record of the values
stored decide on a value's class. They read ``type(value)`` first and fall back to
``value.__class__`` (an attribute lookup) only when that is not the class looked for, so their
answer is the one ``__class__`` always gave, also for an object that says it is another class.
The platform's record keeps the scalars as ``isinstance`` says, subclasses included.
"""

from __future__ import annotations

import math
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.platform.manifest import Probe, Signal
from rasm.platform.telegraf import Telegraf, _check_value


class ClaimsFloat:
    """Says it is a float (``__class__``) and computes like 1.5."""

    @property  # type: ignore[misc]
    def __class__(self) -> type:
        return float

    def __le__(self, other: Any) -> bool:
        return 1.5 <= other

    def __ge__(self, other: Any) -> bool:
        return 1.5 >= other

    def __sub__(self, other: Any) -> float:
        return 0.0

    def __float__(self) -> float:
        return 1.5


def test_telegraf_takes_a_value_that_says_it_is_a_float_as_it_is():
    probe = Probe("box", {"t": Signal("t", "float", 0.0, 2.0)})
    tg = Telegraf([probe], lambda values, time: None)
    tg.send("configure")
    claims = ClaimsFloat()
    assert tg.digest("box", {"t": claims}, 1.0)["t"] is claims


# -------------------------------------------------------------------- Telegraf's range test

ODD_BOUNDS = Probe(
    "box/odd",
    {
        "any": Signal("any", "float", -math.inf, math.inf),
        "up": Signal("up", "float", math.inf, math.inf),
        "nan": Signal("nan", "float", math.nan, None),
        "top": Signal("top", "float", None, 1e308),
        "count": Signal("count", "int", -math.inf, 2.5),
        "big": Signal("big", "int", None, None),
    },
)
EDGE_VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([math.inf, -math.inf, math.nan, 1.7976931348623157e308, -0.0, 2.5, 3]),
    st.integers(),
    st.sampled_from([2**1000, 2**1000 + 1, -(2**1000), 10**400]),
    st.booleans(),
)


@settings(max_examples=400, deadline=None, database=None)
@given(st.dictionaries(st.sampled_from(sorted(ODD_BOUNDS.signals)), EDGE_VALUES))
def test_telegraf_range_test_agrees_with_the_full_check_on_any_bounds(payload):
    # the straightforward version: every value through the full check
    expected, problems, raised = {}, [], None
    for key, signal in ODD_BOUNDS.signals.items():
        if key in payload:
            try:
                problem = _check_value(signal, payload[key])
            except Exception as exc:  # a huge int has no float for math.isfinite
                raised = type(exc)
                break
            if problem:
                problems.append(problem)
            else:
                value = payload[key]
                expected[key] = float(value) if signal.type == "float" else value
    tg = Telegraf([ODD_BOUNDS], lambda values, time: None)
    tg.send("configure")
    try:
        got = tg.digest(ODD_BOUNDS.topic, payload, 1.0)
    except Exception as exc:
        assert type(exc) is raised
        return
    assert raised is None
    assert [(k, type(v), v) for k, v in got.items()] == [
        (k, type(v), v) for k, v in expected.items()
    ]
    assert sorted(tg.rejected.elements()) == sorted(problems)
