"""One record's robustness interval (``Monitor.interval``, ``Monitor(intervals="newest")``):
it contains the final value, it contains the interval :meth:`Monitor.intervals` gives (never
narrower than what is known), and it is that interval where every operator of the formula
answers for one record (docs/properties.md §10)."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.properties import compile_properties
from rasm.properties.loader import load_specification
from rasm.properties.robust_ops import FutureWindow, Ordered, Pointwise, PrevStream

from .reference import reference_robustness
from .strategies import (
    HEADER,
    ORDERED_LATE,
    UNORDERED_LATE,
    count_comparisons,
    formulas,
    numeric_formulas,
    traces,
)

TOLERANCE = 1e-9


def exact_for_one_record(monitor) -> bool:
    """Every robustness operator of the monitor answers ``at`` as ``intervals`` does: the
    pointwise ones, ``prev``, a count's comparison and future windows over values known at
    their records."""
    top = monitor.program.robust_tops[0]
    ops = list(_operators(monitor._namespace[top])) if top is not None else []
    return all(isinstance(op, Pointwise | PrevStream | Ordered)
               or isinstance(op, FutureWindow) and op.source is None for op in ops)


def _operators(stream):
    yield stream
    inputs = [getattr(stream, name, None) for name in ("source", "left", "right")]
    for child in [*inputs, *getattr(stream, "sources", ())]:
        if hasattr(child, "intervals"):
            yield from _operators(child)


def check(formula: str, records) -> None:
    text = HEADER + f"property p0: {formula}\n"
    expected = reference_robustness(load_specification(text), records)["p0"]
    full = compile_properties(text, robustness=True, intervals=True)
    newest = compile_properties(text, robustness=True, intervals="newest")
    exact = exact_for_one_record(full)
    for t, record in records:
        by_full = {v.index: v for v in full.step(t, record)}
        given = newest.step(t, record)
        known = full.intervals("p0")
        for j, (lo, hi) in known.items():
            one = full.interval("p0", j)
            assert one[0] <= lo and hi <= one[1], (formula, j, one, (lo, hi))
            if exact:
                assert one == (lo, hi), (formula, j, one, (lo, hi))
            final = expected[j]
            if final is not None:
                assert one[0] - TOLERANCE <= final <= one[1] + TOLERANCE, (formula, j, one)
        # "newest": the same verdicts; the newest with its interval if decided early
        assert [v._replace(robustness_interval=None) for v in given] == [
            by_full[v.index]._replace(robustness_interval=None) for v in given]
        if given:
            last = max(given, key=lambda v: v.index)
            if last.robustness is None and last.error is None:
                assert last.robustness_interval == full.interval("p0", last.index)
            elif last.robustness is not None:
                assert last.robustness_interval == by_full[last.index].robustness_interval
            for v in given:
                if v is not last and v.robustness is None:
                    assert v.robustness_interval is None
    full.finish()
    newest.finish()


@settings(max_examples=200, deadline=None)
@given(st.one_of(formulas(3), numeric_formulas(3)), traces(max_size=15))
def test_one_records_interval_contains_the_final_value_and_the_full_interval(formula, records):
    check(formula, records)


@settings(max_examples=100, deadline=None)
@given(count_comparisons(ORDERED_LATE + UNORDERED_LATE), traces(max_size=15))
def test_one_records_interval_of_a_count_comparison(formula, records):
    check(formula, records)


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(["x > 0.5 -> eventually[0, 1] y > 0.25",
                        "always[0.5, 2] (x <= y)", "eventually[1, 3] x > 0 and prev(y) < 1",
                        "not (eventually[0, 0.5] (x > y) or always[0, 2] p)"]),
       traces(max_size=25))
def test_future_windows_over_values_known_at_their_records_answer_exactly(formula, records):
    check(formula, records)


def test_a_future_window_answers_one_record_from_its_wedges():
    monitor = compile_properties("input x: float\nproperty p: eventually[1, 3] x > 1\n",
                                 robustness=True, intervals="newest")
    for t, x in ((0, 0.0), (1, 4.0), (2, 2.0), (3, 1.5)):
        monitor.step(t, {"x": x})
    # record 0's window [1, 3] has all its values but waits for a record after 3
    assert monitor.interval("p", 0) == (3.0, math.inf)
    assert monitor.interval("p", 2) == (0.5, math.inf)  # [3, 5]: only 1.5 so far
    assert monitor.interval("p", 3) == (-math.inf, math.inf)  # [4, 6]: nothing yet
    assert monitor.intervals("p") == {0: (3.0, math.inf), 1: (1.0, math.inf),
                                      2: (0.5, math.inf), 3: (-math.inf, math.inf)}
    assert monitor.interval("p", 7) == (-math.inf, math.inf)  # never open


def test_newest_gives_the_interval_of_the_newest_early_verdict_of_each_property():
    text = "input x: float\nproperty p: eventually[0, 2] x > 1\n"
    monitor = compile_properties(text, robustness=True, intervals="newest")
    (v,) = monitor.step(0, {"x": 3.0})
    assert v.robustness_interval == (2.0, math.inf)
    assert monitor.step(1, {"x": 0.0}) == []  # record 1 waits
    u, w = monitor.step(1.5, {"x": 5.0})  # decides records 1 and 2: 2 is the newest
    assert (u.index, u.value, u.robustness_interval) == (1, True, None)
    assert w.index == 2 and w.robustness_interval == (4.0, math.inf)
    assert monitor.intervals("p") == {0: (4.0, math.inf), 1: (4.0, math.inf),
                                      2: (4.0, math.inf)}  # all of them, on demand


def test_an_unknown_interval_mode_is_refused():
    import pytest

    with pytest.raises(ValueError, match="newest"):
        compile_properties("input x: float\nproperty p: x > 1\n", robustness=True,
                           intervals="all")
