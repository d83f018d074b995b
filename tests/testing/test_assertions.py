"""assert_properties and run_app: failures explained as `rasm check` explains them, traces saved."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.cli import main
from rasm.errors import SourceErrors
from rasm.testing import PropertyViolation, Trace, assert_properties, check_trace, run_app

from .conftest import HOTBOX, HOTBOX_PROPS

PROPS = """
input velocity: float
event anomaly, adapted
property velocity_limit: always (velocity <= 0.5)
property timely: always (anomaly -> eventually[0, 2s] adapted)
"""

GOOD = [
    {"time": 0.0, "velocity": 0.1},
    {"time": 1.0, "anomaly": True},
    {"time": 2.0, "adapted": True},
]
BAD = [{"time": 0.0, "velocity": 0.1}, {"time": 0.5, "velocity": 0.62}, {"time": 1.0}]


def test_properties_that_hold_return_the_report():
    report = assert_properties(PROPS, GOOD)
    assert {p.name: p.verdict for p in report.properties} == {
        "velocity_limit": "satisfied",
        "timely": "satisfied",
    }


def test_a_violation_is_explained_like_rasm_check_and_the_trace_saved(tmp_path, capsys):
    props = tmp_path / "robot.rv"
    props.write_text(PROPS)
    with pytest.raises(PropertyViolation) as caught:
        assert_properties(str(props), BAD)
    message = str(caught.value)
    assert message.startswith("violated: velocity_limit")
    assert (
        "velocity_limit: VIOLATED at 2 of 3 judged records (first: record 1, time 0.5)" in message
    )
    assert "velocity = 0.62" in message  # the explanation names the value that broke it
    saved = caught.value.saved
    assert saved.name.startswith("robot-") and saved.suffix == ".jsonl"
    assert f"reproduce: rasm check {props} {saved}" in message
    assert [json.loads(line) for line in saved.read_text().splitlines()] == BAD
    # the command it prints reproduces the same report
    capsys.readouterr()
    assert main(["check", str(props), str(saved)]) == 1
    out = capsys.readouterr().out
    assert "velocity_limit: VIOLATED" in out and "velocity = 0.62" in out


def test_only_restricts_the_verdict_and_checks_the_names():
    assert_properties(PROPS, BAD, only=["timely"])  # velocity_limit is violated, not asked
    with pytest.raises(ValueError, match="no property 'timley'; its properties: timely"):
        assert_properties(PROPS, BAD, only=["timley"])


def test_a_trace_file_is_accepted(tmp_path):
    path = tmp_path / "trace.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in GOOD))
    assert not check_trace(PROPS, path).violated


def test_run_app_returns_the_records_rasm_run_writes(tmp_path):
    written = tmp_path / "trace.jsonl"
    trace = run_app(HOTBOX, seed=5, duration=12, scenario={"openings": [[2, 6]]}, trace=written)
    assert isinstance(trace, Trace) and len(trace) > 100
    assert trace.records == [json.loads(line) for line in written.read_text().splitlines()]
    assert trace.summary.stats.executed >= 1
    assert trace.when("executed") and trace.when("anomaly")[0] <= trace.when("executed")[0]
    saved = trace.save(tmp_path / "again.jsonl")
    assert [json.loads(line) for line in saved.read_text().splitlines()] == trace.records
    assert not check_trace(HOTBOX_PROPS, saved).violated


def test_run_app_overrides_and_their_errors():
    trace = run_app(HOTBOX, seed=1, duration=3, period=0.25)
    ticks = [r["time"] for r in trace if r.get("stage") == "monitor"]
    assert ticks[:3] == [0.25, 0.5, 0.75]
    with pytest.raises(TypeError, match="neither one of its arguments nor a manifest field"):
        run_app(HOTBOX, seed=1, duration=3, stage_budgt=0.1)
    with pytest.raises(ValueError, match="positive number of seconds"):
        run_app(HOTBOX, seed=1, duration=0)


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"seed": "1"}, TypeError, "seed must be an int (e.g. seed=1), not '1'"),
        ({"scenario": 5}, TypeError, "scenario must be a dict (e.g. {'openings': [[3.0, 10.0]]}"),
        (
            {"stage_budget": "x"},
            ValueError,
            "stage_budget must be a positive number of seconds, not 'x'",
        ),
        ({"period": -1}, ValueError, "period must be a positive number of seconds, not -1"),
        (
            {"period": float("nan")},
            ValueError,
            "period must be a positive number of seconds, not nan",
        ),
        ({"max_replans": 1.5}, ValueError, "max_replans must be an int >= 0, not 1.5"),
    ],
)
def test_run_app_refuses_bad_arguments_before_running(kwargs, error, message):
    # a string stage_budget used to run, every tick failing deep in the scheduler and the chart
    arguments = {"seed": 1, "duration": 1, **kwargs}
    with pytest.raises(error) as caught:
        run_app(HOTBOX, **arguments)
    assert str(caught.value).startswith(message)


def test_assert_properties_says_what_a_trace_is(tmp_path):
    for junk in (None, {"time": 0.0}, 3):
        with pytest.raises(TypeError, match=r"^a trace is a list of records like"):
            assert_properties(PROPS, junk)
    with pytest.raises(FileNotFoundError, match=r"^no trace file nope\.jsonl \(pass a JSONL"):
        assert_properties(PROPS, "nope.jsonl")
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"time": 0, "velocity": 0.1}\n{"time": 1, velocity\n')
    with pytest.raises(SourceErrors) as caught:  # was a bare JSONDecodeError
        assert_properties(PROPS, bad)
    assert (
        str(caught.value)
        == f"{bad}:2:13: not valid JSON: Expecting property name enclosed in double quotes"
    )
    with pytest.raises(
        SourceErrors, match=r"^<trace>:2:1: a record must be a JSON object, not int"
    ):
        assert_properties(PROPS, [{"time": 0.0, "velocity": 0.1}, 7])
    # one name is a name, not its letters
    assert_properties(PROPS, BAD, only="timely")


def test_a_property_on_a_signal_the_trace_never_has_fails_naming_the_signal():
    props = PROPS + "input velocty: float\nproperty typo: always (velocty <= 0.5)\n"
    with pytest.raises(PropertyViolation) as caught:
        assert_properties(props, GOOD)
    message = str(caught.value)
    assert message.startswith("not judged: typo (no value for velocty)\n")
    assert "typo: NOT JUDGED: no value for velocty in any record" in message
    assert caught.value.report.failed == [caught.value.report.properties[2]]
    assert_properties(props, GOOD, only=["velocity_limit", "timely"])
    assert check_trace(props, GOOD).properties[2].missing == ("velocty",)


def test_the_headline_names_every_failing_property_by_state():
    props = PROPS + "property typo: always (velocty <= 0.5)\n"
    with pytest.raises(PropertyViolation) as caught:
        assert_properties(props, BAD)
    assert str(caught.value).startswith(
        "violated: velocity_limit; not judged: typo (no value for velocty)\n"
    )


@settings(max_examples=20, deadline=None)
@given(length=st.integers(1, 5000), limit=st.floats(0.0, 2.0))
def test_a_report_prints_as_one_short_line_however_long_the_trace(length, limit):
    records = [{"time": i * 0.1, "velocity": 1.0} for i in range(length)]
    report = check_trace(f"property slow: always (velocity <= {limit})", records)
    verdict = "satisfied" if limit >= 1.0 else "violated"
    shown = repr(report)
    assert "\n" not in shown and len(shown) < 200, shown
    assert f"over {length} records" in shown and f"slow: {verdict}" in shown
    assert repr(report.properties[0]).startswith(f"<PropertyReport slow: {verdict}")
    assert len(repr(report.properties[0])) < 100


def test_a_seeded_failure_is_saved_under_the_same_name_on_every_run():
    """Two runs of one seed differ only in the stages' measured durations: the saved trace's name
    is the same, so a guide (or a colleague) can name it."""
    class Stalls:
        def plan(self, ctx):
            return None  # never adapts: the band is left

    saved = []
    for _ in range(2):
        trace = run_app(HOTBOX, seed=3, duration=25, components={"plan": Stalls()},
                        scenario={"openings": [[1.0, 15.0]]})
        with pytest.raises(PropertyViolation) as caught:
            assert_properties(HOTBOX_PROPS, trace, only=["temperature_band"])
        saved.append(caught.value.saved)
    durations = [
        [r["duration"] for r in map(json.loads, path.read_text().splitlines()) if "stage" in r]
        for path in saved
    ]
    assert saved[0] == saved[1] and durations[0]
