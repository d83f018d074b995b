"""Records as they come: refused ones mixed in, numbers of every size, and what they do.

A refused record (a wrong value, a time going back, not a mapping) changes nothing; a value no
float can hold (an int of 400 digits on a float signal, ±inf) is a value like any other: the
arithmetic and the aggregates follow IEEE-754 and never raise, so no property is in error.
"""

from __future__ import annotations

import math
from collections import OrderedDict

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.properties import compile_properties
from rasm.properties.loader import load_specification

from .reference import reference_verdicts
from .strategies import HEADER, formulas

# values of the wrong type, per signal of HEADER (events p, q; inputs r: bool, x: float, y: int)
WRONG = {"p": [3, "yes", None], "q": [1.5], "r": [2, "no"], "x": ["text", None], "y": [1.5, True]}
GOOD = {
    "p": st.booleans(),
    "q": st.booleans(),
    "r": st.booleans(),
    # 10**400: float() overflows; 1e308: sums overflow; ±inf
    "x": st.sampled_from([-1.0, 0, 0.5, 1.5, 2.25, 10**400, 1e308, math.inf, -math.inf]),
    "y": st.sampled_from([0, 1, 2]),
}


@st.composite
def records(draw, good: dict = GOOD, wrong: dict = WRONG, events=("p", "q"), max_size=30):
    """Timed records, most of them quiet (no event key), with bad ones mixed in."""
    out = []
    t = draw(st.sampled_from([0, 0.5, 3]))
    for _ in range(draw(st.integers(1, max_size))):
        kind = draw(st.integers(0, 9))
        rec: object = {}
        names = [n for n in good if n not in events or kind >= 6]  # kinds 0-5: quiet
        for name in names:
            if draw(st.integers(0, 2)) > 0:
                rec[name] = draw(good[name])
        if kind == 7 and draw(st.booleans()):  # an event present but false: not quiet
            rec[draw(st.sampled_from(events))] = False
        time: object = t
        if kind == 8:  # a bad record: a wrong value, a wrong time, not a dict
            bad = draw(st.integers(0, 6))
            if bad == 0 and wrong:
                name = draw(st.sampled_from(sorted(wrong)))
                rec[name] = draw(st.sampled_from(wrong[name]))
            elif bad == 1:
                time = t - draw(st.sampled_from([0.5, 3]))
            elif bad == 2:
                time = draw(st.sampled_from([math.nan, "soon", None]))
            elif bad == 3:
                rec = draw(st.sampled_from([[], ["p"], "p", None, 7]))
            elif bad == 4:
                rec = OrderedDict(rec)  # a mapping, not a dict: the general path
            elif bad == 5:
                time = int(t) if t == int(t) else t  # an int time: fine
            else:
                rec["unknown"] = 1.0  # a signal no property reads
        out.append((time, rec))
        t = t + draw(st.sampled_from([0, 0.5, 1, 1, 1.5, 6]))
    return out


def _spec(formulas_: list[str]) -> str:
    return HEADER + "".join(f"property p{k}: {f}\n" for k, f in enumerate(formulas_))


def stepped(monitor, trace) -> list:
    return [v for time, rec in trace for v in monitor.step(time, rec)] + monitor.finish()


@st.composite
def with_refusals(draw):
    """Records with refused ones among them: good values for every signal but one, which is
    wrong (or the time goes back), so that a partial update would show."""
    trace = draw(records(max_size=20))
    for _ in range(draw(st.integers(1, 4))):
        at = draw(st.integers(0, len(trace)))
        rec = {name: draw(value) for name, value in GOOD.items() if name not in ("p", "q")}
        if draw(st.booleans()):
            rec.update((name, draw(GOOD[name])) for name in ("p", "q"))
        time = trace[at - 1][0] if at else 0
        if draw(st.integers(0, 3)) == 0 and isinstance(time, (int, float)):
            time = time - 1
        else:
            wrong = draw(st.sampled_from(sorted(WRONG)))
            rec[wrong] = draw(st.sampled_from(WRONG[wrong]))
        trace.insert(at, (time, rec))
    return trace


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(st.lists(formulas(3), min_size=1, max_size=3), with_refusals())
def test_a_refused_record_changes_nothing(formulas_, trace):
    """Whatever a refused record holds (good values next to the bad one), the monitor goes on
    as if it had never come."""
    text = _spec(formulas_)
    full, without = compile_properties(text), compile_properties(text)
    for time, rec in trace:
        refused = len(full.rejected)
        got = full.step(time, rec)
        if len(full.rejected) == refused:
            assert without.step(time, rec) == got
        else:
            assert got == []
    assert full.finish() == without.finish()


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(st.lists(formulas(3), min_size=1, max_size=3), records(wrong={}))
def test_huge_and_infinite_values_are_judged_never_in_error(formulas_, trace):
    """Ints of 400 digits, 1e308 and ±inf in arithmetic and aggregates: every verdict is the
    reference semantics' (IEEE-754), none is an error, online and offline alike."""
    trace = [
        (t, rec) for t, rec in trace if type(rec) is dict and isinstance(t, (int, float)) and t == t
    ]
    trace = [(t, rec) for k, (t, rec) in enumerate(trace) if all(t >= s for s, _ in trace[:k])]
    text = _spec(formulas_)
    expected = reference_verdicts(load_specification(text), trace)
    verdicts = stepped(compile_properties(text), trace)
    assert all(v.error is None for v in verdicts)
    assert {name: {v.index: v.value for v in verdicts if v.property == name}
            for name in expected} == expected
    runs = compile_properties(text).run(trace)
    assert all(not run.errors for run in runs)
    assert {run.name: dict(enumerate(run.values, run.start or 0)) for run in runs} == expected
