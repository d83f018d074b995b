"""One property's failure never blinds the others, and the checker fails closed.

Arithmetic and aggregates follow IEEE-754 and never raise (the overflow, Infinity and huge-int
cases below once made a whole file's step function raise on every later record). Should a
property still raise, its verdicts are errors (value False) where they depend on the failure,
the other properties are judged as if nothing happened, and the failing property recovers by
itself. Faults are injected through ``Monitor(spec, fault_hook=…)``: the generated code then
calls the hook before evaluating each property at each record.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.properties import compile_properties
from rasm.properties.loader import load_specification
from rasm.properties.monitor import Monitor

from .reference import reference_verdicts
from .strategies import HEADER, formulas, traces


def stepped(monitor: Monitor, records) -> list:
    return [v for t, rec in records for v in monitor.step(t, rec)] + monitor.finish()


def table(verdicts, name: str) -> dict[int, tuple]:
    """``{index: (value, error)}`` of one property, checking each index comes once."""
    out: dict[int, tuple] = {}
    for v in verdicts:
        if v.property == name:
            assert v.index not in out, f"two verdicts for record {v.index} of {name}"
            out[v.index] = (v.value, v.error)
    return out


# --------------------------------------------------------------------------- no exceptions


def test_two_readings_of_1e308_overflow_a_sum_to_inf_and_every_property_goes_on():
    # the attack of the issue: two probe messages of 1e308 on a float signal without a range
    text = (
        "input v: float\n"
        "property bounded: sum[0, 5s](v) < 1e308\n"
        "property veto: always (v < 100)\n"
    )
    records = [(0.0, {"v": 1.0}), (1.0, {"v": 1e308}), (2.0, {"v": 1e308})]
    records += [(float(t), {"v": 1.0}) for t in range(3, 12)]
    verdicts = stepped(compile_properties(text), records)
    assert all(v.error is None for v in verdicts)
    bounded = table(verdicts, "bounded")
    veto = table(verdicts, "veto")
    # the exact sum of 1e308 and 1e308 is beyond the largest float: inf, as 1e308 + 1e308 is
    assert [bounded[i][0] for i in range(12)] == [True, False] + [False] * 6 + [True] * 4
    assert [veto[i][0] for i in range(12)] == [True, False, False] + [True] * 9
    runs = {run.name: run for run in compile_properties(text).run(records)}
    assert runs["bounded"].values == [bounded[i][0] for i in range(12)]
    assert not runs["bounded"].errors and not runs["veto"].errors


def test_infinity_under_avg_and_both_infinities_make_it_undefined():
    text = "input v: float\nproperty mean: avg[0, 2](v) < 100\nproperty high: avg[0, 2](v) > 0\n"
    records = [(0, {"v": 1.0}), (1, {"v": math.inf}), (2, {"v": -math.inf}), (3, {"v": 1.0}),
               (4, {"v": 1.0}), (5, {"v": 1.0})]
    verdicts = stepped(compile_properties(text), records)
    assert all(v.error is None for v in verdicts)
    # inf in the window: avg is inf; +inf and -inf: undefined, every comparison false
    assert [table(verdicts, "mean")[i][0] for i in range(6)] == [
        True, False, False, False, True, True
    ]
    assert [table(verdicts, "high")[i][0] for i in range(6)] == [
        True, True, False, False, False, True
    ]


def test_a_400_digit_int_under_avg_and_in_float_arithmetic():
    huge = 10**400
    text = (
        "input n: int\n"
        "property mean: avg[0, 5](n) > 1e300\n"
        "property total: sum[0, 5](n) > 1e300\n"
        "property half: n * 0.5 > 1e300\n"
        "property ratio: n / 3 > 1e300\n"
        "property exact: n - 1 < n\n"
    )
    records = [(0, {"n": huge}), (1, {"n": -huge}), (10, {"n": 1})]
    verdicts = stepped(compile_properties(text), records)
    assert all(v.error is None for v in verdicts)
    values = {(v.property, v.index): v.value for v in verdicts}
    for name in ("mean", "total", "half", "ratio"):
        assert [values[(name, i)] for i in range(3)] == [True, False, False], name
    assert [values[("exact", i)] for i in range(3)] == [True, True, True]  # ints stay exact


# --------------------------------------------------------------------------- injected faults


def faulty(text: str, faults: set[tuple[str, int]]) -> Monitor:
    """A monitor whose property ``name`` raises at record ``index`` for each pair."""

    def hook(name: str, index: int) -> None:
        if (name, index) in faults:
            raise RuntimeError(f"injected into {name} at {index}")

    return Monitor(load_specification(text), fault_hook=hook)


TEXT = (
    "event p\nevent q\n"
    "property window: once[0, 2] p\n"
    "property response: p -> eventually[0, 2] q\n"
    "property ever: historically (not q)\n"
    "property calm: not (p and q)\n"
)
RECORDS = [(t, {"p": t % 3 == 0, "q": t % 4 == 1}) for t in range(14)]


def test_a_faulty_property_does_not_change_the_others_verdicts():
    clean = stepped(compile_properties(TEXT), RECORDS)
    verdicts = stepped(faulty(TEXT, {("window", 5), ("response", 5)}), RECORDS)
    for name in ("ever", "calm"):
        assert table(verdicts, name) == table(clean, name)


def test_the_failing_record_and_the_records_it_owes_are_errors_then_it_recovers():
    clean = {name: table(stepped(compile_properties(TEXT), RECORDS), name)
             for name in ("window", "response")}
    verdicts = stepped(faulty(TEXT, {("window", 5), ("response", 5)}), RECORDS)
    window = table(verdicts, "window")
    # once[0, 2] p at 5: record 5 is an error, and 6 and 7 look back to records before the
    # reset; from 8 on (3 s after the reset) the window holds only records after it
    assert sorted(i for i, (_, error) in window.items() if error) == [5, 6, 7]
    assert all(window[i] == clean["window"][i] for i in range(14) if i not in (5, 6, 7))
    assert "RuntimeError at record 5: injected into window at 5" in window[5][1]
    assert "depends on records before a reset at record 5" in window[6][1]
    response = table(verdicts, "response")
    # record 3 (p) waits for q until 5; record 4 was decided at once (no p); the future
    # operator looks forward only: from 6 on, exact again
    assert sorted(i for i, (_, error) in response.items() if error) == [3, 5]
    assert all(response[i] == clean["response"][i] for i in range(14) if i not in (3, 5))
    assert set(window) == set(response) == set(range(14))  # one verdict per record


def test_an_unbounded_past_never_recovers_and_says_so_at_every_record():
    verdicts = stepped(faulty(TEXT, {("ever", 2)}), RECORDS)
    ever = table(verdicts, "ever")
    assert [i for i, (value, error) in ever.items() if error] == list(range(2, 14))
    assert all(value is False for i, (value, _) in ever.items() if i >= 2)


def test_a_property_that_raises_at_every_record_is_an_error_at_every_record():
    faults = {("calm", i) for i in range(14)}
    verdicts = stepped(faulty(TEXT, faults), RECORDS)
    calm = table(verdicts, "calm")
    assert sorted(calm) == list(range(14))
    assert all(value is False and error for value, error in calm.values())
    assert table(verdicts, "window") == table(stepped(compile_properties(TEXT), RECORDS), "window")


def test_offline_run_counts_the_errors_per_record():
    runs = {run.name: run for run in faulty(TEXT, {("window", 5)}).run(RECORDS)}
    assert sorted(runs["window"].errors) == [5, 6, 7]
    assert [runs["window"].values[i] for i in (5, 6, 7)] == [False, False, False]
    clean = {run.name: run for run in compile_properties(TEXT).run(RECORDS)}
    assert runs["calm"] == clean["calm"] and runs["response"] == clean["response"]
    # offline as online: record 3 still waits for its window and record 5 failed; record 4,
    # which its trigger alone decided before the fault, keeps its verdict
    runs = {run.name: run for run in faulty(TEXT, {("response", 5)}).run(RECORDS)}
    assert sorted(runs["response"].errors) == [3, 5]
    online = table(stepped(faulty(TEXT, {("response", 5)}), RECORDS), "response")
    assert runs["response"].values == [online[i][0] for i in range(14)]
    assert len(runs["response"].values) == 14


def test_a_fault_while_finishing_makes_the_open_records_errors():
    # the generated code makes its verdicts through the name ``VERDICT_NEW`` of its namespace:
    # replaced by one that raises, the end of the trace fails half way through a property
    text = "event p\nevent q\nproperty response: p -> eventually[0, 5] q\nproperty calm: not q\n"
    monitor = compile_properties(text)
    records = [(0, {"p": True}), (1, {"p": True}), (2, {})]
    verdicts = [v for t, rec in records for v in monitor.step(t, rec)]
    assert [(v.property, v.index) for v in verdicts if v.property == "response"] == [
        ("response", 2)
    ]
    monitor._namespace["VERDICT_NEW"] = _raising_verdict
    finished = monitor.finish()
    assert [(v.index, v.value) for v in finished] == [(0, False), (1, False)]
    assert all("RuntimeError at the end of the trace: no verdicts" in v.error for v in finished)


def _raising_verdict(*args):
    raise RuntimeError("no verdicts")


def test_a_missing_signal_still_leaves_the_property_not_started():
    text = "input x: float\nevent p\nproperty typo: x > 1\nproperty fine: not p\n"
    monitor = faulty(text, {("fine", 0)})
    verdicts = stepped(monitor, [(0, {}), (1, {"p": True})])
    assert monitor.missing("typo") == ("x",) and table(verdicts, "typo") == {}
    assert table(verdicts, "fine") == {
        0: (False, "evaluating the property raised RuntimeError at record 0: "
                   "injected into fine at 0"),
        1: (False, None),
    }


# --------------------------------------------------------------------------- for all formulas


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(
    st.lists(formulas(3), min_size=2, max_size=3),
    traces(max_size=20),
    st.lists(st.tuples(st.integers(0, 2), st.integers(0, 19)), max_size=3),
)
def test_faults_are_isolated_and_fail_closed(formulas_, records, faults):
    """For any formulas, trace and injected faults: every started record gets exactly one
    verdict per property; a property without faults gets exactly its reference verdicts; a
    faulty one gets its reference verdict wherever it is not an error; offline errors cover
    the online ones."""
    text = HEADER + "".join(f"property p{k}: {f}\n" for k, f in enumerate(formulas_))
    spec = load_specification(text)
    expected = reference_verdicts(spec, records)
    names = [p.name for p in spec.properties]
    injected = {(names[k % len(names)], index) for k, index in faults}
    online = stepped(faulty(text, injected), records)
    runs = {run.name: run for run in faulty(text, injected).run(records)}
    for prop in spec.properties:
        got = table(online, prop.name)
        assert set(got) == set(expected[prop.name])
        run = runs[prop.name]
        assert set(run.errors) >= {i for i, (_, error) in got.items() if error}
        for i, (value, error) in got.items():
            if error is None:
                assert value == expected[prop.name][i], (prop.name, i)
            else:
                assert value is False
        for k, value in enumerate(run.values):
            i = run.start + k
            assert value == (False if i in run.errors else expected[prop.name][i])
        if not any(name == prop.name for name, _ in injected):
            assert all(error is None for _, error in got.values()) and not run.errors
