"""A monitor's ``tally`` is its ``step`` with each verdict as a (property, value) pair.

The Trustworthiness Checker feeds the trace to ``tally`` when nobody wants verdict objects; it
must decide exactly what ``step`` decides, record after record, refusing the same records.
"""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.spec import compile

from .strategies import HEADER, formulas, traces

BAD = st.sampled_from(
    [
        (None, {"x": "text"}),  # a value of the wrong type
        (None, {"y": 1.5}),
        (None, {"p": 3}),
        (None, []),  # not a record
        (-5.0, {}),  # a time going back
        (math.nan, {}),
        ("soon", {}),
    ]
)


@st.composite
def traces_with_bad_records(draw):
    records = draw(traces())
    for _ in range(draw(st.integers(0, 3))):
        at = draw(st.integers(0, len(records)))
        time, record = draw(BAD)
        before = records[at - 1][0] if at else 0
        records.insert(at, (before if time is None else time, record))
    return records


@settings(max_examples=200, deadline=None)
@given(st.lists(formulas(3), min_size=1, max_size=3), traces_with_bad_records())
def test_tally_gives_the_steps_verdicts_as_pairs(formulas_, records):
    text = HEADER + "".join(f"property p{k}: {f}\n" for k, f in enumerate(formulas_))
    stepped, tallied = compile(text), compile(text)
    for time, record in records:
        verdicts = stepped.step(time, record)
        assert tallied.tally(time, record) == [(v.property, v.value) for v in verdicts]
    assert [vars(r) for r in tallied.rejected] == [vars(r) for r in stepped.rejected]
    assert tallied.finish() == stepped.finish()
    assert tallied.starts == stepped.starts


@settings(max_examples=200, deadline=None)
@given(st.lists(formulas(3), min_size=1, max_size=3), traces_with_bad_records())
def test_tally_into_keeps_what_the_tallys_pairs_say(formulas_, records):
    """``tally_into`` stores the last value of each property the record decided, and hands the
    values that are not True to ``unusual`` in ``tally``'s order."""
    text = HEADER + "".join(f"property p{k}: {f}\n" for k, f in enumerate(formulas_))
    tallied, kept = compile(text), compile(text)
    expected_latest: dict = {}
    expected_unusual: list = []
    latest: dict = {}
    unusual: list = []
    for time, record in records:
        for name, value in tallied.tally(time, record):
            expected_latest[name] = value
            if value is not True:
                expected_unusual.append((name, value))
        assert kept.tally_into(time, record, latest, lambda *pair: unusual.append(pair)) is None
        assert latest == expected_latest and list(latest) == list(expected_latest)
        assert unusual == expected_unusual
    assert [vars(r) for r in kept.rejected] == [vars(r) for r in tallied.rejected]
    assert kept.finish() == tallied.finish()


def test_tally_into_hands_nothing_over_for_a_record_that_fails_half_way():
    # the second property divides by an int far beyond a float: evaluating it raises after
    # the first property's verdict was decided
    text = "input n: int\nproperty small: always (n < 10)\nproperty ratio: always (1.5 * n > 0)\n"
    monitor = compile(text)
    latest: dict = {}
    unusual: list = []
    monitor.tally_into(0.0, {"n": 20}, latest, lambda *pair: unusual.append(pair))
    assert latest == {"small": False, "ratio": True} and unusual == [("small", False)]
    try:
        monitor.tally_into(1.0, {"n": 10**400}, latest, lambda *pair: unusual.append(pair))
    except OverflowError:
        pass
    else:
        raise AssertionError("1.5 * 10**400 should overflow")
    assert latest == {"small": False, "ratio": True} and unusual == [("small", False)]
