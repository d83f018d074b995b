"""Explanations given from a bounded window of the trace: the same as from the whole trace,
abridged values, and what the text says when a window reaches past what was kept."""

from __future__ import annotations

import json
import math
from fractions import Fraction

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.cli import main
from rasm.properties import explain as explain_module
from rasm.properties.check import check_records, format_text
from rasm.properties.explain import ABRIDGE, explain
from rasm.properties.loader import load_specification
from rasm.times import format_seconds

from .strategies import HEADER, formulas, traces


def violations(spec, records) -> dict[str, list[int]]:
    report = check_records(spec, records, explain_violations=False)
    return {p.name: [i for i, _ in p.violations] for p in report.properties if p.violations}


def whole(spec, records, wanted):
    """The explanations of an explainer that keeps every record and explains at the end."""
    reach = explain_module._reach
    explain_module._reach = lambda node: (math.inf, math.inf)
    try:
        return explain(spec, records, wanted, chunk=len(records) + 1)
    finally:
        explain_module._reach = reach


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(st.lists(formulas(3), min_size=1, max_size=2), traces(), st.integers(1, 7))
def test_explanations_from_the_records_kept_are_those_of_the_whole_trace(bodies, records,
                                                                           chunk):
    text = HEADER + "".join(f"property p{k}: {body}\n" for k, body in enumerate(bodies))
    spec = load_specification(text)
    wanted = violations(spec, records)
    expected = whole(spec, records, wanted)
    assert explain(spec, records, wanted, chunk=chunk) == expected
    # fewer records kept than the windows reach: each explanation is the same, or says what
    # it could not see
    for key, found in explain(spec, records, wanted, chunk=chunk, keep=3).items():
        if found != expected[key]:
            said = "\n".join(found.lines)
            assert "not kept" in said or "not explained" in said, (found, expected[key])


def test_the_explanations_keep_only_the_records_their_windows_reach():
    spec = load_specification("input x: float\nproperty p: always (x < 1 -> once[0, 2s] x < "
                               "0.5)\n")
    # x stays above 0.5 from 93 s to 95 s: at 95 s the 2 s window holds no x below 0.5
    records = [(k / 10, {"x": 0.7 if 930 <= k <= 950 else 0.2}) for k in range(1000)]
    wanted = violations(spec, records)
    assert wanted == {"p": [950]}
    explainer = explain_module.Explainer(spec, wanted)
    part = explainer._parts[0]
    most = 0
    for k in range(0, 1000, 10):
        explainer.feed(records[k:k + 10])
        most = max(most, len(part.rows.times))
        if explainer.done:
            break
    # 2 s back at 10 records a second, and a chunk: never the 950 records before it
    assert explainer.done and most <= 2 * 10 + 1 + 10 + 10, most
    (found,) = explainer.finish().values()
    assert "once[0, 2] x < 0.5 failed: x < 0.5 never held in records 930–950" in "\n".join(
        found.lines)


def test_a_window_longer_than_the_records_kept_says_so():
    spec = load_specification("input x: float\nproperty p: always (x < 1 -> once x < 0.5)\n")
    # an unbounded past window: x never went below 0.5, from the first record on
    records = [(k, {"x": 0.7}) for k in range(40)]
    wanted = violations(spec, records)
    assert wanted["p"][0] == 0
    found = explain(spec, records, wanted, keep=5, chunk=1)
    last = found[("p", 39)]
    assert "not kept" in "\n".join(last.lines)
    assert found[("p", 0)].lines == explain(spec, records, wanted)[("p", 0)].lines


def test_long_values_are_abridged_in_explanations(tmp_path, capsys):
    props = tmp_path / "p.rv"
    props.write_text("input v: float\ninput mode: str\n"
                     "property p: always (v < 1 or mode == \"stop\")\n")
    trace = tmp_path / "t.jsonl"
    big = "x" * 10_000_000
    trace.write_text(json.dumps({"time": 0, "v": 2.0, "mode": big}) + "\n")
    assert main(["check", str(props), str(trace)]) == 1
    out = capsys.readouterr().out
    assert len(out) < 2_000, len(out)  # it was 20 MB: the value twice
    assert f'mode = "{"x" * ABRIDGE}… (10,000,000 characters)"' in out
    spec = load_specification(props.read_text())
    (prop,) = check_records(spec, [(0, {"v": 2.0, "mode": big})]).properties
    assert len(prop.explanations[0].signals["mode"]) < 2 * ABRIDGE


@pytest.mark.parametrize("time", [Fraction(1, 3), Fraction(5, 2)])
def test_times_of_any_number_type_are_printed(time):
    spec = load_specification("input v: float\nproperty p: always (v < 1)\n")
    report = check_records(spec, [(Fraction(0), {"v": 0.5}), (time, {"v": 2.0})])
    text = format_text(report)
    assert f"at record 1 (time {format_seconds(time)})" in text
