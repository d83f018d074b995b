"""The compiled monitors against the reference evaluator, on random formulas and traces."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.properties import compile_properties
from rasm.properties.loader import load_specification

from .reference import reference_verdicts
from .strategies import HEADER, formulas, traces


def online(text: str, records):
    monitor = compile_properties(text)
    got: dict[str, dict[int, object]] = {name: {} for name in monitor.properties}
    emitted_at: dict[tuple[str, int], int] = {}
    for k, (t, rec) in enumerate(records):
        for v in monitor.step(t, rec):
            assert v.index not in got[v.property], "a verdict was given twice"
            got[v.property][v.index] = v.value
            emitted_at[(v.property, v.index)] = k
            given = records[v.index][0]  # seconds: a Decimal or a Fraction comes as a float
            assert v.time == (given if isinstance(given, (int, float)) else float(given))
            assert v.value in (True, False)
    for v in monitor.finish():
        assert v.index not in got[v.property]
        got[v.property][v.index] = v.value
    return got, emitted_at


def offline(text: str, records):
    monitor = compile_properties(text)
    runs = monitor.run(records)
    return {
        run.name: {run.start + k: v for k, v in enumerate(run.values)} if run.values else {}
        for run in runs
    }


def assert_agrees_with_reference(formula: str, records):
    """Online and offline verdicts of ``formula`` equal the reference semantics; returns the
    specification and when each online verdict was emitted."""
    text = HEADER + f"property p0: {formula}\n"
    spec = load_specification(text)
    expected = reference_verdicts(spec, records)
    got, emitted_at = online(text, records)
    assert got == expected, formula
    assert offline(text, records) == expected
    return spec, emitted_at


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(formulas(3), traces())
def test_monitor_agrees_with_reference(formula, records):
    assert_agrees_with_reference(formula, records)


@pytest.mark.slow
@settings(max_examples=100, deadline=None)
@given(formulas(3, future=False), traces())
def test_past_only_verdicts_come_at_once(formula, records):
    text = HEADER + f"property p0: {formula}\n"
    got, emitted_at = online(text, records)
    for (_, index), at in emitted_at.items():
        assert at == index
    assert len(emitted_at) == len(got["p0"])


@pytest.mark.slow
@settings(max_examples=100, deadline=None)
@given(st.lists(formulas(2), min_size=2, max_size=4), traces())
def test_several_properties_in_one_file(formulas_, records):
    text = HEADER + "".join(f"property p{k}: {f}\n" for k, f in enumerate(formulas_))
    spec = load_specification(text)
    got, _ = online(text, records)
    assert got == reference_verdicts(spec, records)


def horizon(node) -> float:
    """How far into the future a formula looks: the sum of nested future upper bounds."""
    from rasm.properties.ast import Future, Until, children

    below = max((horizon(c) for c in children(node)), default=0.0)
    if isinstance(node, (Future, Until)):
        return node.bound.high + below
    return below


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(formulas(3), traces())
def test_online_verdicts_come_no_later_than_the_horizon(formula, records):
    # a verdict for record i comes no later than the first record with time > ti + b
    text = HEADER + f"property p0: {formula}\n"
    b = horizon(load_specification(text).properties[0].formula)
    _, emitted_at = online(text, records)
    times = [t for t, _ in records]
    for (_, index), at in emitted_at.items():
        late = next((k for k, t in enumerate(times) if t > times[index] + b), None)
        assert late is None or at <= late, (formula, index, at, late)
