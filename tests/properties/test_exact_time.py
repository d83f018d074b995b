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
from rasm.properties.check import check_records, format_json, format_text, format_verdicts
from rasm.properties.times import Seconds, nanoseconds
from rasm.trace import parse_trace, read_trace

from .reference import exact_seconds
from .strategies import HEADER, UNITS, decimal_traces, formulas, time_comparisons
from .test_semantics import assert_agrees_with_reference, online


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(st.data())
def test_decimal_times_agree_with_the_exact_semantics(data):
    unit = data.draw(st.sampled_from(UNITS))
    formula = data.draw(formulas(3, unit=unit))
    records = data.draw(decimal_traces(unit))
    assert_agrees_with_reference(formula, records)


@pytest.mark.slow
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


@pytest.mark.slow
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
    # ``time`` is the record's time in seconds; verdicts carry it as an int or a float
    monitor = compile_properties("property late: time >= 0.3\n")
    got = [monitor.step(t, {})[0] for t in (0.1, 0.3, Decimal("0.35"), Fraction(1, 2), 1)]
    assert [v.value for v in got] == [False, True, True, True, True]
    assert [v.time for v in got] == [0.1, 0.3, 0.35, 0.5, 1]


def test_time_minus_prev_time_is_exact_as_window_bounds_are():
    # 0.3 - 0.1 is 0.2 for `time` as for once[0.2, 0.2], not 0.19999999999999998
    text = "event p\nproperty gap: time - prev(time) >= 0.2\nproperty at: once[0.2, 0.2] p\n"
    records = [(0.1, {"p": True}), (0.3, {"p": False})]
    online = compile_properties(text)
    got = [(v.property, v.index, v.value) for t, rec in records for v in online.step(t, rec)]
    assert got == [("gap", 0, False), ("at", 0, False), ("gap", 1, True), ("at", 1, True)]
    runs = compile_properties(text).run(records)
    assert [run.values for run in runs] == [[False, True], [False, True]]
    # and on times the float loses: epoch seconds with nine decimals, read from a trace
    equal = compile_properties("property same: time - prev(time) == 0.000000001\n")
    first, second = Seconds("1700000000.123456789"), Seconds("1700000000.123456790")
    assert float(first) == float(second)
    assert [v.value for t in (first, second) for v in equal.step(t, {})] == [False, True]


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(st.data())
def test_time_arithmetic_agrees_with_an_exact_oracle(data):
    # sums, differences, negation, abs, min, max and prev of times, with decimal numbers of up
    # to nine decimals: every comparison as exact as the decimals written (reference.py)
    unit = data.draw(st.sampled_from(UNITS))
    formula = data.draw(time_comparisons(unit))
    exact = data.draw(st.booleans())
    records = data.draw(decimal_traces(unit, max_size=12, exact=exact))
    assert_agrees_with_reference(formula, records)


def test_a_time_in_products_aggregates_and_explanations_is_its_float_seconds():
    text = ("input x: float\nproperty scaled: (time - prev(time)) * 10 >= 2\n"
            "property widest: max[0, 1](time - prev(time)) < 0.2\n")
    records = [(0.1, {"x": 1.0}), (0.3, {"x": 1.0}), (0.35, {"x": 1.0})]
    scaled, widest = (run.values for run in compile_properties(text).run(records))
    assert scaled == [False, True, False]  # 0.2 * 10 is 2.0; 0.05 * 10 is 0.5
    assert widest == [False, False, False]  # max of nan, 0.2, 0.05: undefined, then 0.2
    spec = load_specification("property steady: time - prev(time) <= 0.1\n")
    (report,) = check_records(spec, records).properties
    assert report.explanations[1].lines == (
        "time - prev(time) <= 0.1 failed:", "  time - prev(time) = 0.2",  # not ...99999998
    )


def test_fraction_and_decimal_times_are_explained_and_written_as_their_decimals():
    # check_records takes any exact time; every report writes it as its decimal (format_seconds)
    spec = load_specification(
        "input x: float\nproperty low: historically[0, 1] (x < 1)\n"
        "property seen: once[0, 0.5] (x > 5)\n"
    )
    records = [(Fraction(1, 10), {"x": 0.5}), (Fraction(3, 10), {"x": 2.0}),
               (Decimal("1700000000.123456789"), {"x": 0.5})]
    report = check_records(spec, records)
    text = format_text(report)
    assert "(first: record 1, time 0.3)" in text and "at record 1 (time 0.3):" in text
    assert "never held in records 2–2 (times 1700000000.123456789–1700000000.123456789)" in text
    violations = json.loads(format_json(report))["properties"][0]["violations"]
    assert violations == [{"index": 1, "time": 0.3}]
    lines = [json.loads(line) for line in format_verdicts(report).splitlines()]
    assert [line["time"] for line in lines[:3]] == [0.1, 0.3, 1700000000.1234567]


@pytest.mark.parametrize("number", ["0.0000000005", "1e-10", "2.0000000001"])
def test_a_number_finer_than_a_nanosecond_beside_a_time_is_an_error_at_its_place(number):
    text = f"property fine: time - prev(time) >= {number}\n"
    with pytest.raises(SourceError) as caught:
        compile_properties(text, source="fine.rv")
    message = str(caught.value)
    assert message.startswith("fine.rv:1:37: ")
    assert "is finer than a nanosecond, the resolution of times" in message


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


@pytest.mark.slow
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
