"""Operators the generator writes into the step function itself, against the reference evaluator.

``count[0, b]`` of a two-valued operand keeps only the times of its true records (a counter when
``b`` is unbounded) instead of a :class:`~rasm.properties.operators.WindowCore` call per record.

``trigger -> eventually[a, b] …`` (and ``w and F``, ``w or F``, until): online, a record whose
verdict the trigger alone decides opens no window.
"""

from __future__ import annotations

from collections import deque

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.errors import SourceError
from rasm.properties import compile_properties
from rasm.properties.loader import load_specification

from .reference import reference_verdicts
from .strategies import HEADER, bounds, formulas, traces
from .test_semantics import assert_agrees_with_reference, horizon, offline, online

BOUNDS = st.sampled_from(["[0, 0]", "[0, 0.5]", "[0, 1]", "[0, 2.5]", "[0, 3]", "[0, inf]"])
OPERANDS = st.sampled_from(["p", "q", "r", "p or q", "prev(p)", "once[0, 1] q", "x > 0.5"])
TESTS = st.sampled_from([">= 1", ">= 2", "== 0", "== 1", "== 2", "<= 3", "> 3"])


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(BOUNDS, OPERANDS, TESTS, traces(max_size=30))
def test_count_from_now_agrees_with_the_reference(bound, operand, test, records):
    text = HEADER + f"property p0: count{bound}({operand}) {test}\n"
    expected = reference_verdicts(load_specification(text), records)
    got, emitted_at = online(text, records)
    assert got == expected, text
    assert all(at == index for (_, index), at in emitted_at.items())  # past only: at once
    assert offline(text, records) == expected


def test_count_from_now_is_written_inline():
    monitor = compile_properties(HEADER + "property p0: count[0, 2](p) <= 1\n")
    assert ".push(" not in monitor.program.source


@st.composite
def decided_by_trigger(draw) -> str:
    """A property whose left operand alone may decide it, over an inline future window."""
    trigger = draw(formulas(2, future=False))
    right = draw(formulas(1, future=False))
    window = draw(
        st.sampled_from(
            [
                f"eventually{draw(bounds(False))} ({right})",
                f"({draw(formulas(1, future=False))}) until{draw(bounds(False))} ({right})",
            ]
        )
    )
    op = draw(st.sampled_from(["->", "and", "or"]))
    return f"({trigger}) {op} ({window})"


@pytest.mark.slow
@settings(max_examples=400, deadline=None)
@given(decided_by_trigger(), traces(max_size=30))
def test_records_the_trigger_decides_open_no_window_and_verdicts_stay_the_same(formula, records):
    spec, emitted_at = assert_agrees_with_reference(formula, records)
    b = horizon(spec.properties[0].formula)
    times = [t for t, _ in records]
    for (_, index), at in emitted_at.items():
        late = next((k for k, t in enumerate(times) if t > times[index] + b), None)
        assert late is None or at <= late, (formula, index, at, late)


def test_a_false_trigger_opens_no_window_online():
    monitor = compile_properties(HEADER + "property p0: p -> eventually[0, 5] q\n")
    for k in range(100):
        assert [v.value for v in monitor.step(float(k), {"p": False})] == [True]
    pending = [v for k, v in monitor.program.constants.items() if k.startswith("w")]
    assert pending == [deque()]  # the window holds nothing: no trigger was true


def test_monitors_compiled_from_the_same_text_share_no_state():
    # the parsed file and the code object are reused; every monitor has its own state
    text = HEADER + "property p0: p -> eventually[0, 2] q\nproperty p1: count[0, 5](p) <= 1\n"
    first, second = compile_properties(text), compile_properties(text)
    assert first.program.source == second.program.source
    assert [v.value for v in first.step(0.0, {"p": True})] == [True]  # p1; p0 waits for q
    assert [v.value for v in first.step(1.0, {"p": True})] == [False]
    assert [v.value for v in second.step(0.0, {"p": False})] == [True, True]
    assert [(v.property, v.value) for v in first.finish()] == [("p0", None), ("p0", None)]
    assert [(v.property, v.index) for v in second.finish()] == []


def test_a_file_that_does_not_load_fails_every_time():
    for _ in range(2):
        with pytest.raises(SourceError):
            compile_properties(HEADER + "property p0: p ->\n")
