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
