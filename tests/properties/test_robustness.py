"""Robustness (SPEC §12) against its definition (the brute-force reference, exact times), and
the rules that tie it to the boolean verdicts: its sign agrees with the verdict wherever it is
not zero, and every interval given contains the final value."""

from __future__ import annotations

import json
import math
from decimal import Decimal

from hypothesis import example, given, settings
from hypothesis import strategies as st

from rasm.properties import compile_properties
from rasm.properties.loader import load_specification

from .reference import reference_robustness, reference_verdicts
from .strategies import (
    HEADER,
    ORDERED_LATE,
    UNORDERED_LATE,
    count_comparisons,
    decimal_traces,
    formulas,
    numeric_formulas,
    traces,
)


def close(a: float, b: float) -> bool:
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


def offline(text: str, records):
    runs = compile_properties(text, robustness=True).run(records)
    return {run.name: ({run.start + k: v for k, v in enumerate(run.values)},
                       {run.start + k: r for k, r in enumerate(run.robustness)})
            if run.values else ({}, {}) for run in runs}


def online(text: str, records):
    """Each verdict's robustness and interval, and the intervals of the open records after
    each step (to check that they contain the final values)."""
    monitor = compile_properties(text, robustness=True, intervals=True)
    verdicts: dict[tuple[str, int], object] = {}
    seen_intervals: list[tuple[str, int, tuple[float, float]]] = []
    for t, rec in records:
        for v in monitor.step(t, rec):
            verdicts[(v.property, v.index)] = v
        for name in monitor.properties:
            seen_intervals += [(name, j, iv) for j, iv in monitor.intervals(name).items()]
    for v in monitor.finish():
        verdicts[(v.property, v.index)] = v
    return verdicts, seen_intervals


def check(formula: str, records) -> None:
    text = HEADER + f"property p0: {formula}\n"
    spec = load_specification(text)
    expected = reference_robustness(spec, records)["p0"]
    values, robust = offline(text, records)["p0"]
    assert set(robust) == set(expected), formula
    for j, want in expected.items():
        got = robust[j]
        # not final where the definition needs a record after the end (the monitor may also
        # leave one undecided at the end that waits in record order behind such a record)
        if want is None:
            assert got is None, (formula, j, got)
        if got is not None:
            assert close(got, want), (formula, j, got, want)
            if want != 0:  # the sign agrees with the verdict (§5)
                assert values[j] is (want > 0), (formula, j, want, values[j])
    verdicts, seen = online(text, records)
    for (_, j), v in verdicts.items():
        final = expected[j]
        if v.robustness is not None and v.error is None:  # online, the same as offline
            assert close(v.robustness, robust[j]), (formula, j, v, robust[j])
        lo, hi = v.robustness_interval
        if v.error is None:
            assert lo <= hi
            if final is not None:
                assert lo - 1e-9 <= final <= hi + 1e-9, (formula, j, v, final)
            if v.robustness is not None:
                assert lo == hi == v.robustness
    for _, j, (lo, hi) in seen:
        final = expected[j]
        if final is not None:
            assert lo - 1e-9 <= final <= hi + 1e-9, (formula, j, lo, hi, final)


@settings(max_examples=150, deadline=None)
@given(formulas(3), traces(max_size=15))
# an aggregate's operand is computed as the boolean compile sees it (historically as not once not)
@example("count[0, inf](historically (p)) >= 0", [(0, {}), (0, {}), (0, {}), (0, {"p": True})])
def test_robustness_agrees_with_its_definition(formula, records):
    check(formula, records)


@settings(max_examples=300, deadline=None)
@given(numeric_formulas(3), traces(max_size=15))
def test_robustness_of_distances_agrees_with_its_definition(formula, records):
    check(formula, records)


@settings(max_examples=200, deadline=None)
@given(count_comparisons(ORDERED_LATE + UNORDERED_LATE), traces(max_size=15))
# an undefined side (x / 0) makes the comparison -inf however the count's range ends up
@example("x / y != count[0, inf](eventually[0, 1] p)",
         [(0, {}), (0.5, {"x": 1.0, "y": 0}), (3, {})])
def test_robustness_of_count_comparisons_agrees_with_its_definition(formula, records):
    """A count over late values compared with a value known at its record: its interval is
    the count's range while its window is open, and contains the final value."""
    check(formula, records)


@settings(max_examples=150, deadline=None)
@given(st.data())
def test_robustness_on_decimal_times(data):
    unit = data.draw(st.sampled_from([Decimal("0.1"), Decimal("0.01")]))
    formula = data.draw(st.one_of(formulas(3, unit=unit), numeric_formulas(3, unit=unit)))
    check(formula, data.draw(decimal_traces(unit, max_size=15)))


def test_the_boolean_verdicts_stay_as_they_are():
    text = HEADER + "property p0: always (x <= 0.5 -> eventually[0, 1] p)\n" \
        "property p1: x < 0 or x == 0.5\n"
    records = [(0, {"x": 0.5, "p": False}), (0.5, {"x": 0, "p": True}), (2, {"x": 0.5})]
    spec = load_specification(text)
    values = {name: v for name, (v, _) in offline(text, records).items()}
    assert values == reference_verdicts(spec, records)


def test_an_aggregate_is_a_value():
    text = "input t: float\nproperty band: avg[0, 5](t) <= 40\n"
    runs = compile_properties(text, robustness=True).run(
        [(0, {"t": 38}), (1, {"t": 41}), (7, {"t": 39.5})])
    assert runs[0].robustness == [2.0, 0.5, 0.5]


def test_prev_undefined_strings_and_booleans():
    text = ("input x: float\ninput mode: str\nevent go\n"
            "property a: prev(x) > 0\nproperty b: mode == \"run\"\nproperty c: go\n"
            "property d: avg[1, 2](x) > 0\n")
    runs = compile_properties(text, robustness=True).run(
        [(0, {"x": 1.0, "mode": "run", "go": True}), (1, {"x": 2.0, "mode": "stop"})])
    by = {run.name: run.robustness for run in runs}
    assert by == {"a": [-math.inf, 1.0], "b": [math.inf, -math.inf], "c": [math.inf, -math.inf],
                  "d": [-math.inf, 1.0]}


def test_an_early_verdict_carries_an_interval_and_the_final_value_comes_at_the_end():
    text = "input x: float\nproperty p: eventually[0, 2] x > 1\n"
    monitor = compile_properties(text, robustness=True, intervals=True)
    (v,) = monitor.step(0, {"x": 3.0})
    assert v.value is True and v.robustness is None and v.robustness_interval == (2.0, math.inf)
    (w,) = monitor.step(1, {"x": 5.0})  # record 1 is decided early too
    assert w.index == 1 and w.robustness_interval == (4.0, math.inf)
    assert monitor.intervals("p") == {0: (4.0, math.inf), 1: (4.0, math.inf)}
    assert [v.robustness for v in monitor.step(2.5, {"x": 0.0})] == []  # record 2: x > 1 fails
    assert monitor.intervals("p") == {1: (4.0, math.inf), 2: (-1.0, math.inf)}
    assert [(v.index, v.value, v.robustness) for v in monitor.finish()] == [(2, None, None)]


# --------------------------------------------------------------------------- rasm check


CLI_PROPS = """input x: float
property band: always (x <= 0.5)
property react: always (x > 0.4 -> eventually[0, 1] x < 0.2)
"""
CLI_TRACE = ('{"time": 0, "x": 0.1}\n{"time": 0.5, "x": 0.45}\n{"time": 1, "x": 0.1}\n'
             '{"time": 3, "x": 0.3}\n')


def _cli_files(tmp_path):
    props, trace = tmp_path / "p.rv", tmp_path / "t.jsonl"
    props.write_text(CLI_PROPS)
    trace.write_text(CLI_TRACE)
    return str(props), str(trace)


def test_check_json_adds_the_minimum_robustness(tmp_path, capsys):
    from rasm.cli import main

    props, trace = _cli_files(tmp_path)
    assert main(["check", props, trace, "--robustness", "--format", "json"]) == 0
    report = json.loads(capsys.readouterr().out)
    got = {p["name"]: p["robustness"] for p in report["properties"]}
    assert close(got["band"], 0.05) and close(got["react"], 0.1)
    assert main(["check", props, trace, "--format", "json"]) == 0
    assert "robustness" not in json.loads(capsys.readouterr().out)["properties"][0]


def test_check_verdicts_add_each_robustness_null_where_not_final(tmp_path, capsys):
    from rasm.cli import main

    props, trace = _cli_files(tmp_path)
    assert main(["check", props, trace, "--robustness", "--verdicts"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    react = [line["robustness"] for line in lines if line["property"] == "react"]
    assert [round(r, 9) for r in react[:3]] == [0.3, 0.1, 0.3] and react[3] is None


def test_check_text_shows_the_robustness(tmp_path, capsys):
    from rasm.cli import main

    props, trace = _cli_files(tmp_path)
    assert main(["check", props, trace, "--robustness"]) == 0
    assert "robustness (minimum over the judged records): 0.05" in capsys.readouterr().out


def test_check_robustness_refuses_parts_and_workers(tmp_path, capsys):
    from rasm.cli import main

    props, trace = _cli_files(tmp_path)
    for extra in (["--jobs", "2"], ["--part-size", "1M"], ["--cluster", "tcp://127.0.0.1:1"]):
        assert main(["check", props, trace, "--robustness", *extra]) == 2
        err = capsys.readouterr().err
        assert "--robustness is computed in one pass" in err and "Traceback" not in err


def test_without_intervals_an_early_verdict_has_none():
    monitor = compile_properties("input x: float\nproperty p: eventually[0, 2] x > 1\n",
                                 robustness=True)
    (v,) = monitor.step(0, {"x": 3.0})
    assert v.value is True and v.robustness is None and v.robustness_interval is None
    assert monitor.intervals("p") == {0: (2.0, math.inf)}  # on demand
