"""Exact time: window edges decided exactly on decimal timestamps.

``0.3 - 0.1`` is ``0.19999999999999998`` in binary floating point; a monitor comparing float
differences misjudges every record that sits exactly on a window bound, and every 10 Hz or 100 Hz
trace has them. These tests compare the online (``step``) and offline (``run``) monitors with an
exact evaluator (``reference.py``, times as fractions) on traces whose records lie on a 0.1 s or
0.01 s grid — equal times, irregular gaps, epoch-like offsets — under bounds on the same grid.
"""

from __future__ import annotations

import json
import math
from decimal import Decimal
from fractions import Fraction

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.errors import SourceError, SourceErrors
from rasm.properties import compile_properties, load_specification
from rasm.properties.ast import Future, Until, children
from rasm.properties.check import check_records
from rasm.properties.times import Seconds, nanoseconds
from rasm.trace import parse_trace, read_trace

from .reference import exact_seconds
from .strategies import HEADER, UNITS, decimal_traces, formulas
from .test_semantics import assert_agrees_with_reference, online


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_decimal_times_agree_with_the_exact_semantics(data):
    unit = data.draw(st.sampled_from(UNITS))
    formula = data.draw(formulas(3, unit=unit))
    records = data.draw(decimal_traces(unit))
    assert_agrees_with_reference(formula, records)


@settings(max_examples=200, deadline=None)
@given(st.data())
def test_past_windows_on_decimal_times_agree_with_the_exact_semantics(data):
    unit = data.draw(st.sampled_from(UNITS))
    formula = data.draw(formulas(2, future=False, unit=unit))
    records = data.draw(decimal_traces(unit, max_size=40))
    assert_agrees_with_reference(formula, records)


def test_a_window_edge_on_a_decimal_gap_is_inside_the_window():
    # 0.3 - 0.1 is 0.2 exactly: the record at 0.1 is in the window [200ms, 400ms] of 0.3
    records = [(0.1, {"p": True}), (0.3, {"p": False})]
    text = "event p\nproperty w: once[200ms, 400ms] p\n"
    online = compile_properties(text)
    assert [v.value for t, rec in records for v in online.step(t, rec)] == [False, True]
    (run,) = compile_properties(text).run(records)
    assert run.values == [False, True]


@settings(max_examples=100, deadline=None)
@given(st.data())
def test_decimal_and_fraction_times_are_exact(data):
    unit = data.draw(st.sampled_from(UNITS))
    formula = data.draw(formulas(2, unit=unit))
    records = data.draw(decimal_traces(unit, exact=True))
    assert_agrees_with_reference(formula, records)
    as_fractions = [(Fraction(t), rec) for t, rec in records]
    assert_agrees_with_reference(formula, as_fractions)


def test_bounds_are_exact_nanoseconds_from_their_text():
    spec = load_specification(
        "event p\nproperty w: once[200ms, 0.4s] p and once[1.5min, inf] p and once[1e-9, 2] p\n"
    )
    bounds = []

    def walk(node):
        if hasattr(node, "bound"):
            bounds.append((node.bound.low_ns, node.bound.high_ns))
        for child in children(node):
            walk(child)

    walk(spec.properties[0].formula)
    assert bounds == [(200_000_000, 400_000_000), (90 * 10**9, math.inf), (1, 2 * 10**9)]


def test_a_bound_finer_than_a_nanosecond_is_an_error_at_its_place():
    with pytest.raises(SourceError) as info:
        load_specification("event p\nproperty w:\n  once[0, 0.0000000001] p\n", source="w.rv")
    assert str(info.value).startswith("w.rv:3:11: window bound 0.0000000001 is finer than a")
    with pytest.raises(SourceError, match="w.rv:2:21: window bound 0.0000001ms"):
        load_specification("event p\nproperty w: once[0, 0.0000001ms] p\n", source="w.rv")


EPOCH = 1_700_000_000


def test_epoch_times_with_nine_decimals_are_read_exactly_from_the_trace():
    # as floats, 1700000000.100000001 and 1700000000.300000001 are 1700000000.1 and
    # 1700000000.3000002: 0.2000002 s apart. Read from the text, they are 0.2 s apart
    lines = [
        '{"time": 1700000000.100000001, "p": true}',
        '{"time": 1700000000.300000001}',
        '{"time": 1700000000.300000002}',
    ]
    records = parse_trace(lines)
    assert [t.ns for t, _ in records] == [
        1700000000100000001, 1700000000300000001, 1700000000300000002
    ]
    assert json.dumps(records[0][0]) == "1700000000.1"  # still seconds, a JSON number
    text = "event p\nproperty w: once[200ms, 200ms] p\n"
    assert compile_properties(text).run(records)[0].values == [False, True, False]
    online = compile_properties(text)
    assert [v.value for t, rec in records for v in online.step(t, rec)] == [False, True, False]


def test_a_time_that_goes_back_by_a_nanosecond_is_refused():
    lines = ['{"time": 1700000000.300000002}', '{"time": 1700000000.300000001}']
    with pytest.raises(SourceErrors, match="goes back in time"):
        parse_trace(lines, source="t.jsonl")
    monitor = compile_properties("event p\nproperty w: once p\n")
    assert monitor.step(Decimal("1700000000.300000002"), {})[0].time == 1700000000.3
    assert monitor.step(Decimal("1700000000.300000001"), {}) == []
    assert monitor.rejected[0].reason.endswith("goes back in time")


@pytest.mark.parametrize("time", [math.inf, -math.inf, math.nan])
def test_a_time_that_is_not_finite_is_refused(time):
    monitor = compile_properties("event p\nproperty w: once p\n")
    assert monitor.step(time, {}) == []
    assert monitor.rejected[0].reason == f"'time' must be finite, not {time!r}"


def test_the_time_expression_and_verdicts_read_seconds():
    # ``time`` is a number of seconds like any other (binary64 arithmetic), an int or a float
    monitor = compile_properties("property late: time >= 0.3\n")
    got = [monitor.step(t, {})[0] for t in (0.1, 0.3, Decimal("0.35"), Fraction(1, 2), 1)]
    assert [v.value for v in got] == [False, True, True, True, True]
    assert [v.time for v in got] == [0.1, 0.3, 0.35, 0.5, 1]


@settings(max_examples=200, deadline=None)
@given(st.integers(-10**12, 10**12), st.integers(0, 8))
def test_a_float_time_stands_for_its_shortest_decimal(ns, digits):
    # a time with up to nine decimals, given as the float nearest it, is that many nanoseconds
    scale = 10 ** (9 - digits)
    exact = ns // scale * scale
    text = f"{Decimal(exact).scaleb(-9):f}"
    assert nanoseconds(float(text)) == exact
    assert nanoseconds(Decimal(text)) == exact == Seconds(text).ns
    assert nanoseconds(float(EPOCH + Fraction(exact, 10**9))) == round(
        Fraction(repr(float(EPOCH + Fraction(exact, 10**9)))) * 10**9
    )


@settings(max_examples=150, deadline=None)
@given(st.data())
def test_online_verdicts_on_decimal_times_come_no_later_than_the_horizon(data):
    # a verdict for record i comes no later than the first record with time > ti + b, exactly
    unit = data.draw(st.sampled_from(UNITS))
    formula = data.draw(formulas(3, unit=unit))
    records = data.draw(decimal_traces(unit))
    text = HEADER + f"property p0: {formula}\n"
    b = exact_horizon(load_specification(text).properties[0].formula)
    _, emitted_at = online(text, records)
    times = [exact_seconds(t) for t, _ in records]
    for (_, index), at in emitted_at.items():
        late = next((k for k, t in enumerate(times) if t > times[index] + b), None)
        assert late is None or at <= late, (formula, index, at, late)


def exact_horizon(node) -> Fraction:
    """How far into the future a formula looks, exactly: the sum of nested future bounds."""
    below = max((exact_horizon(c) for c in children(node)), default=Fraction(0))
    if isinstance(node, (Future, Until)):
        return Fraction(node.bound.high_ns, 10**9) + below
    return below


def test_rasm_check_judges_a_10hz_trace_exactly(tmp_path):
    # every record of a 10 Hz trace sits on the 200 ms bound of the one two steps before it
    trace = tmp_path / "t.jsonl"
    trace.write_text("".join(
        json.dumps({"time": round(0.1 * k, 1), "beat": k % 2 == 0}) + "\n" for k in range(50)
    ))
    spec = load_specification(
        "event beat\nproperty steady: always (beat -> once[200ms, 200ms] beat)\n", source="p.rv"
    )
    records = read_trace(trace, spec.signals)
    (report,) = check_records(spec, records).properties
    assert report.violations == [(0, 0.0)]  # record 0 has no record 200 ms before it
    assert report.judged == 50
