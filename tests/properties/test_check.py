"""``rasm check``: trace reading, the three output formats, explanations and exit codes."""

from __future__ import annotations

import itertools
import json
from decimal import Decimal

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.cli import main
from rasm.errors import SourceErrors
from rasm.properties.printer import unparse
from rasm.trace import parse_trace

from .strategies import HEADER, formulas, traces

PROPS = """\
input velocity: float
input mode: str = "idle"
event anomaly
event adapted

property velocity_limit:
    always (velocity <= 0.5 or mode == "emergency")
property timely_adaptation:
    always (anomaly -> eventually[0, 2s] adapted)
"""

GOOD = [
    {"time": 0, "velocity": 0.1},
    {"time": 1, "velocity": 0.2, "anomaly": True},
    {"time": 2.5, "adapted": True},
    {"time": 3, "velocity": 0.3},
]

BAD = [
    {"time": 0, "velocity": 0.1},
    {"time": 1, "velocity": 0.7, "mode": "navigate"},
    {"time": 2, "anomaly": True, "velocity": 0.2},
    {"time": 5, "velocity": 0.3},
    {"time": 5.5, "anomaly": True},
]


def write(tmp_path, name, records):
    path = tmp_path / name
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    return str(path)


@pytest.fixture
def props(tmp_path):
    path = tmp_path / "props.rv"
    path.write_text(PROPS)
    return str(path)


def test_satisfied_trace_exits_0(props, tmp_path, capsys):
    assert main(["check", props, write(tmp_path, "t.jsonl", GOOD)]) == 0
    out = capsys.readouterr().out
    assert "velocity_limit: satisfied (4 records judged)" in out
    assert "0 of 2 properties fail: 2 satisfied" in out


def test_violations_exit_1_and_are_explained(props, tmp_path, capsys):
    assert main(["check", props, write(tmp_path, "t.jsonl", BAD)]) == 1
    out = capsys.readouterr().out
    assert "velocity_limit: VIOLATED at 1 of 5 judged records (first: record 1, time 1)" in out
    # which sub-formula failed, and the values that made it fail
    assert 'velocity <= 0.5 or mode == "emergency" failed' in out
    assert "velocity = 0.7" in out
    assert 'mode = "navigate"' in out
    assert "timely_adaptation: VIOLATED at 1 of 5" in out
    assert "eventually[0, 2] adapted failed: adapted never held" in out
    assert "anomaly was true" in out


def test_json_report(props, tmp_path, capsys):
    assert main(["check", props, write(tmp_path, "t.jsonl", BAD), "--format", "json"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report["records"] == 5
    first, second = report["properties"]
    assert first == {
        "name": "velocity_limit",
        "verdict": "violated",
        "violations": [{"index": 1, "time": 1}],
        "judged": 5,
        "inconclusive": 0,
        "errors": 0,
        "first_error": None,
        "missing": [],
        "vacuous": [],
    }
    # the anomaly at 5.5 cannot be decided: the trace ends before its window does
    assert second["verdict"] == "violated"
    assert second["violations"] == [{"index": 2, "time": 2}]
    assert second["inconclusive"] == 1


def test_inconclusive_alone_exits_0(props, tmp_path, capsys):
    trace = write(tmp_path, "t.jsonl", [{"time": 0, "velocity": 0.1, "anomaly": True}])
    assert main(["check", props, trace, "--format", "json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["properties"][1]["verdict"] == "inconclusive"


def test_verdicts_jsonl(props, tmp_path, capsys):
    assert main(["check", props, write(tmp_path, "t.jsonl", BAD), "--verdicts"]) == 1
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(lines) == 10
    assert lines[1] == {"property": "velocity_limit", "index": 1, "time": 1, "value": False}
    assert lines[-1] == {"property": "timely_adaptation", "index": 4, "time": 5.5, "value": None}


def test_bad_trace_reports_every_line(props, tmp_path, capsys):
    path = tmp_path / "bad.jsonl"
    path.write_text(
        '{"time": 0, "velocity": 0.1}\n'
        "[1, 2]\n"
        '{"time": "soon"}\n'
        '{"velocity": 0.2}\n'
        '{"time": 3, "velocity": "fast"}\n'
        '{"time": 2}\n'
        "{oops\n"
        '{"time": 4, "anomaly": "yes"}\n'
    )
    assert main(["check", props, str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [
        f"rasm: {path}:2:1: a record must be a JSON object, not list",
        f"rasm: {path}:3:2: 'time' must be a number, not \"soon\"",
        f"rasm: {path}:4:1: record without 'time' (seconds, a number)",
        f"rasm: {path}:5:13: 'velocity' must be a number, not \"fast\"",
        f"rasm: {path}:7:2: not valid JSON: Expecting property name enclosed in double quotes",
        f"rasm: {path}:8:13: 'anomaly' must be true or false, not \"yes\"",
    ]


def test_infinite_time_and_truncated_record_are_rejected_at_their_column(props, tmp_path, capsys):
    path = tmp_path / "inf.jsonl"
    path.write_text(
        '{"time": 0, "velocity": 0.1}\n'
        '{"time": Infinity, "velocity": 0.2}\n'
        '{"time": 1e999}\n'
        '{"time": -Infinity}\n'
        '{"time": 3, "velocity": 0.3\n'
    )
    assert main(["check", props, str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [
        f"rasm: {path}:2:2: 'time' must be finite, not Infinity",
        f"rasm: {path}:3:2: 'time' must be finite, not Infinity",
        f"rasm: {path}:4:2: 'time' must be finite, not -Infinity",
        f"rasm: {path}:5:28: not valid JSON: Expecting ',' delimiter",
    ]


def test_time_going_back_is_rejected_with_its_line():
    with pytest.raises(SourceErrors) as info:
        parse_trace(['{"time": 2}', "", '{"time": 1}'], {}, source="t.jsonl")
    (error,) = info.value.errors
    assert str(error).startswith("t.jsonl:3:2: time 1 goes back in time")


def test_bad_property_file_exits_2_with_location(tmp_path, capsys):
    path = tmp_path / "bad.rv"
    path.write_text("input v: float\nproperty p:\n    always[0, 1] (v <= 0.5) until[2, 1] v > 1\n")
    trace = write(tmp_path, "t.jsonl", GOOD)
    assert main(["check", str(path), trace]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"rasm: {path}:3:34: empty window [2, 1]")
    assert "^" in err and "Traceback" not in err


def test_missing_files_exit_2(props, tmp_path, capsys):
    assert main(["check", str(tmp_path / "nope.rv"), "x.jsonl"]) == 2
    assert main(["check", props, str(tmp_path / "nope.jsonl")]) == 2
    assert "No such file" in capsys.readouterr().err


def test_shipped_platform_properties_load():
    from pathlib import Path

    from rasm.properties import load_specification

    folder = Path(__file__).resolve().parents[2] / "properties"
    files = sorted(folder.glob("*.rv"))
    assert files
    for path in files:
        spec = load_specification(path.read_text(), source=str(path))
        assert spec.properties


def loop_trace(reject_second: bool = False, skip_legitimate: bool = False) -> list[dict]:
    """An adaptation trace as `rasm run --trace` writes it: two iterations, one anomaly."""
    t = 0.0
    out = []

    def at(dt, **values):
        nonlocal t
        t = round(t + dt, 3)
        out.append({"time": t, **values})

    for iteration in range(2):
        at(0.1, stage="monitor", duration=0.01)
        at(0.05, stage="analyse", duration=0.02, anomaly=True)
        at(0.05, stage="plan", duration=0.05, planned=True, plan=f"p{iteration}")
        if not skip_legitimate:
            rejected = reject_second and iteration == 1
            at(0.05, stage="legitimate", duration=0.01,
               **({"rejected": True} if rejected else {"legitimate": True}))
            if rejected:
                continue
        at(0.01, trusted=True)
        at(0.05, stage="execute", duration=0.1, executed=True)
    at(1.0, stage="monitor", duration=0.01)
    return out


@pytest.mark.parametrize("name", ["maple_k.rv", "adaptation.rv"])
def test_platform_properties_hold_on_a_good_loop(name, tmp_path, capsys):
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "properties" / name
    trace = write(tmp_path, "loop.jsonl", loop_trace())
    assert main(["check", str(path), trace, "--format", "json"]) == 0, capsys.readouterr().out
    report = json.loads(capsys.readouterr().out)
    assert all(p["verdict"] == "satisfied" for p in report["properties"])


def test_platform_properties_catch_an_unlegitimated_execution(tmp_path, capsys):
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "properties" / "maple_k.rv"
    trace = write(tmp_path, "loop.jsonl", loop_trace(skip_legitimate=True))
    assert main(["check", str(path), trace, "--format", "json"]) == 1
    report = {p["name"]: p for p in json.loads(capsys.readouterr().out)["properties"]}
    assert report["stage_order"]["verdict"] == "violated"  # plan -> execute skips a stage
    assert report["execute_only_legitimate_plans"]["verdict"] == "violated"
    assert report["rejected_plans_stay_rejected"]["verdict"] == "satisfied"


def test_a_broken_file_is_reported_by_its_first_problems():
    lines = ["[]"] * 80
    with pytest.raises(SourceErrors) as info:
        parse_trace(lines, {}, source="t.jsonl")
    errors = info.value.errors
    assert len(errors) == 51
    assert str(errors[49]).startswith("t.jsonl:50:1: a record must be a JSON object")
    assert str(errors[50]) == "t.jsonl: … and 30 more malformed records (fix the ones above first)"


@settings(max_examples=60, deadline=None)
@given(formulas(3), traces())
def test_every_violation_is_explained(formula, records):
    from rasm.properties import load_specification
    from rasm.properties.check import check_records, format_text

    spec = load_specification(HEADER + f"property p0: {formula}\n", source="p.rv")
    report = check_records(spec, records)
    (prop,) = report.properties
    from rasm.properties.check import EXPLAINED, SUMMARISED

    assert len(prop.explanations) == min(len(prop.violations), EXPLAINED + SUMMARISED)
    for explanation, (index, _) in zip(prop.explanations, prop.violations, strict=False):
        assert explanation.index == index
        assert explanation.lines  # which sub-formula failed
        assert explanation.lines[0].startswith(unparse(spec.properties[0].formula)[:20])
    text = format_text(report)
    assert ("VIOLATED" in text) == bool(prop.violations)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.sampled_from(["0", "0.1", "0.2", "0.5", "1"]), min_size=1, max_size=30),
    st.sampled_from(["0", "0.1", "0.3", "1"]),
    st.sampled_from(["0", "0.1", "0.2", "0.7", "2", "inf"]),
    st.data(),
)
def test_explanation_windows_are_the_semantic_ones(steps, low, width, data):
    # the explainer finds windows by bisection; they must be exactly the semantics' windows, on the
    # decimals the times stand for (0.3 - 0.1 is 0.2)
    from rasm.properties.ast import Bound, Name, Past
    from rasm.properties.explain import _Explainer, _Rows

    exact = list(itertools.accumulate(Decimal(step) for step in steps))
    high = Decimal(low) + Decimal(width)  # Decimal("inf") when unbounded
    i = data.draw(st.integers(0, len(exact) - 1))
    start = data.draw(st.integers(0, i))
    node = Past("once", Bound(float(low), float(high)), Name("p"))
    rows = _Rows(0)
    rows.add([(float(t), {}) for t in exact])
    explainer = _Explainer(rows, {}, start)
    t = exact
    a = Decimal(low)
    past = [j for j in range(i, start - 1, -1) if a <= t[i] - t[j] <= high]
    future = [j for j in range(i, len(t)) if a <= t[j] - t[i] <= high]
    assert list(explainer.past_window(node, i)[0]) == past
    assert list(explainer.future_window(node, i)[0]) == future
    # with the records before ``kept`` no longer held, the window is what is left of it, and
    # says when it may have lost judged records
    kept = data.draw(st.integers(0, i))
    rows.drop_before(kept)
    window, clipped = explainer.past_window(node, i)
    assert list(window) == [j for j in past if j >= kept]
    if any(j < kept for j in past):
        assert clipped  # it never claims a window whole that is not


def test_files_that_are_not_utf8_are_placed_at_their_first_bad_byte(tmp_path, capsys):
    props = tmp_path / "p.rv"
    props.write_text("input x: float\nproperty p:\n  always (x < 1)\n")
    trace = tmp_path / "t.jsonl"
    # the bad byte is in the second record, far enough in for a streamed read to be past it
    trace.write_bytes(b'{"time": 0, "x": 0.5}\n{"time": 1, "x": 0.\xff5}\n')
    assert main(["check", str(props), str(trace)]) == 2
    assert f"{trace}:2:20: not a UTF-8 text file" in capsys.readouterr().err
    props.write_bytes(b"input x: float\n# caf\xe9\nproperty p:\n  always (x < 1)\n")
    assert main(["check", str(props), str(trace)]) == 2
    assert f"{props}:2:6: not a UTF-8 text file" in capsys.readouterr().err


def test_a_property_that_is_a_literal_is_explained():
    # found by test_every_violation_is_explained: the explanation looked up the property's own
    # table, which was never made for a literal
    from rasm.properties import load_specification
    from rasm.properties.check import check_records

    spec = load_specification(HEADER + "property p0: false\n", source="p.rv")
    (prop,) = check_records(spec, [(0, {}), (1, {})]).properties
    assert [e.lines for e in prop.explanations] == [("false failed",), ("false failed",)]


# ---------------------------------------------------------------- the five states

MISSPELLED = """\
input velocity: float
input velocty: float

property velocity_limit:
    always (velocity <= 0.5)
property typo_limit:
    always (velocty <= 0.5)
"""


def test_a_property_on_a_misspelled_signal_is_not_judged_and_fails_the_check(tmp_path):
    """The real command, as CI runs it: the property that never saw its signal is named with
    the signal, and the exit code is 1 although nothing was violated."""
    import subprocess
    import sys

    props = tmp_path / "typo.rv"
    props.write_text(MISSPELLED)
    trace = write(tmp_path, "t.jsonl", GOOD)
    run = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "check", str(props), trace],
        capture_output=True, text=True, timeout=60,
    )
    assert run.returncode == 1, run.stdout + run.stderr
    assert f"typo_limit: NOT JUDGED: no value for velocty in any record  [{props}:6:10]" in (
        run.stdout
    )
    assert "1 of 2 properties fail: 1 not judged, 1 satisfied" in run.stdout
    assert "Traceback" not in run.stderr
    run = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "check", str(props), trace, "--format", "json"],
        capture_output=True, text=True, timeout=60,
    )
    assert run.returncode == 1
    limit, typo = json.loads(run.stdout)["properties"]
    assert limit["verdict"] == "satisfied" and limit["missing"] == []
    assert typo["verdict"] == "not judged" and typo["missing"] == ["velocty"]
    assert typo["judged"] == 0 and typo["errors"] == 0


def test_an_empty_trace_leaves_every_property_not_judged(props, tmp_path, capsys):
    assert main(["check", props, write(tmp_path, "t.jsonl", []), "--format", "json"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert [p["verdict"] for p in report["properties"]] == ["not judged", "not judged"]
    assert report["properties"][0]["missing"] == ["velocity"]


def _error_report():
    """A report whose first property could not be evaluated at records 1 and 2 (as a monitor
    reports an evaluation that raised), and whose second holds."""
    from rasm.properties.check import CheckReport, PropertyReport
    from rasm.properties.monitor import PropertyRun

    times = [0.0, 0.5, 1.0, 1.5]
    why = "OverflowError: the sum of the window overflowed"
    runs = [
        PropertyRun("budget", 0, [True, False, False, True], errors={1: why, 2: why}),
        PropertyRun("limit", 0, [True, True, True, True]),
    ]
    reports = [PropertyReport.of(r.name, f"p.rv:{k + 3}:10", r, times) for k, r in enumerate(runs)]
    return CheckReport("p.rv", "t.jsonl", len(times), reports, times), why


def test_a_property_in_error_is_reported_as_error_in_every_format():
    from rasm.properties.check import format_json, format_text, format_verdicts

    report, why = _error_report()
    budget, limit = report.properties
    # an error verdict's value is False, but it is not a violation: the checker could not tell
    assert budget.verdict == "error" and budget.violations == [] and not budget.passed
    assert limit.verdict == "satisfied"
    assert report.failed == [budget] and not report.violated
    text = format_text(report)
    assert "budget: ERROR at 2 of 4 judged records" in text
    assert f"in error at record 1 (time 0.5): {why}" in text
    assert "1 of 2 properties fail: 1 error, 1 satisfied" in text
    first = json.loads(format_json(report))["properties"][0]
    assert first["verdict"] == "error" and first["errors"] == 2 and first["first_error"] == why
    lines = [json.loads(line) for line in format_verdicts(report).splitlines()]
    assert lines[1] == {"property": "budget", "index": 1, "time": 0.5, "value": False,
                        "error": why}
    assert "error" not in lines[0] and "error" not in lines[4]


@settings(max_examples=100, deadline=None)
@given(
    values=st.lists(st.sampled_from([True, False, None, "error"]), max_size=12),
    started=st.booleans(),
)
def test_the_check_report_state_is_the_outcome_of_its_verdicts(values, started):
    """Whatever the verdicts, the report's state is PropertyOutcome's, and only satisfied and
    inconclusive pass."""
    from rasm.properties.check import PropertyReport
    from rasm.properties.monitor import PropertyRun
    from rasm.properties.outcome import PropertyOutcome

    if not started:
        values = []
    errors = {k: "boom" for k, v in enumerate(values) if v == "error"}
    run = PropertyRun(
        "p", 0 if started else None, [False if v == "error" else v for v in values],
        errors=errors, missing=() if started else ("x",),
    )
    report = PropertyReport.of("p", "p.rv:1:1", run, [float(k) for k in range(len(values))])
    expected = PropertyOutcome("p", missing=run.missing if not started else ())
    for k, value in enumerate(run.values):
        expected.add(value, errors.get(k))
    assert report.verdict == expected.state
    assert report.passed == (expected.state in ("satisfied", "inconclusive"))
    assert len(report.violations) == values.count(False)
