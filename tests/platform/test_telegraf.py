"""Telegraf stores exactly the values that fit their signal, and only while it runs."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.platform.manifest import Probe, Signal
from rasm.platform.telegraf import Telegraf

PROBE = Probe(
    "box/sensors",
    {
        "temperature": Signal("temperature", "float", -40.0, 150.0),
        "lid_open": Signal("lid_open", "bool"),
        "count": Signal("count", "int", 0, 10),
        "mode": Signal("mode", "str"),
    },
)


def started_telegraf():
    stored = []
    tg = Telegraf([PROBE], lambda values, time: stored.append(dict(values)))
    tg.send("configure")
    assert tg.mode == "initialized"
    return tg, stored


def valid(signal, value):
    if signal.type == "float":
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        return ok and math.isfinite(value) and signal.minimum <= value <= signal.maximum
    if signal.type == "int":
        ok = isinstance(value, int) and not isinstance(value, bool)
        return ok and signal.minimum <= value <= signal.maximum
    if signal.type == "bool":
        return isinstance(value, bool)
    return isinstance(value, str)


VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-100, 200),
    st.booleans(),
    st.text(max_size=5),
    st.none(),
    st.lists(st.integers(), max_size=2),
)


@settings(max_examples=200, deadline=None)
@given(payload=st.dictionaries(st.sampled_from(sorted(PROBE.signals) + ["other"]), VALUES))
def test_telegraf_stores_exactly_the_valid_values(payload):
    tg, stored = started_telegraf()
    result = tg.digest("box/sensors", payload, 1.0)
    expected = {
        k: v for k, v in payload.items() if k in PROBE.signals and valid(PROBE.signals[k], v)
    }
    assert result == expected
    assert stored == ([expected] if expected else [])
    bad = sum(
        1 for k, v in payload.items() if k in PROBE.signals and not valid(PROBE.signals[k], v)
    )
    assert sum(tg.rejected.values()) == bad


def test_telegraf_refuses_unroutable_data_and_works_only_when_initialized():
    tg, stored = started_telegraf()
    assert tg.digest("elsewhere", {"temperature": 1.0}, 0) == {}
    assert tg.digest("box/sensors", ["not", "a", "dict"], 0) == {}
    assert tg.rejected["unroutable"] == 2
    tg.send("failed", reason="test")
    assert tg.mode == "fault"
    assert tg.digest("box/sensors", {"temperature": 20.0}, 0) == {}
    assert tg.rejected["not running"] == 1 and stored == []

