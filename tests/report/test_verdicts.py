"""Verdict timelines say what ``rasm check`` and the run summary say: the five states, counted
the same way, offline (``rasm report``) and live (the dashboard)."""

from __future__ import annotations

import json
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.properties.outcome import PropertyOutcome
from rasm.report.dashboard import serve
from rasm.report.verdicts import VerdictTimeline
from tests.platform.guarded import write_guarded_app

VALUES = st.lists(st.sampled_from([True, False, None, "error"]), max_size=15)


@settings(max_examples=200, deadline=None)
@given(warm_up=st.integers(0, 3), values=VALUES)
def test_a_timeline_counts_its_verdicts_as_property_outcome_does(warm_up, values):
    timeline = VerdictTimeline("p", "p.rv:1:1", ["x"])
    expected = PropertyOutcome("p")
    shown = []
    for time in range(warm_up):
        timeline.add(float(time), "warm-up")
        shown.append("warm-up")
    for time, value in enumerate(values, start=warm_up):
        error = "boom" if value == "error" else None
        verdict = False if value == "error" else value
        timeline.add(float(time), verdict, error)
        expected.add(verdict, error)
        shown.append(value)
    data = timeline.to_dict()
    assert data["verdict"] == expected.state == timeline.verdict
    assert (data["judged"], data["errors"], data["violated"]) == (
        expected.judged, expected.errors, expected.violations,
    )
    # the runs compress the values shown, in order, each run a stretch of one value
    compressed = [v for k, v in enumerate(shown) if k == 0 or shown[k - 1] != v]
    assert [run[2] for run in data["runs"]] == compressed
    assert len(data["violations"]) == values.count(False)
    # the episodes are the stretches of consecutive violations, each ended by the first
    # judged record that is no violation (None: violated to the end)
    stretches, k = [], 0
    while k < len(values):
        if values[k] is False:
            end = k
            while end + 1 < len(values) and values[end + 1] is False:
                end += 1
            until = float(warm_up + end + 1) if end + 1 < len(values) else None
            stretches.append((float(warm_up + k), float(warm_up + end), until, end - k + 1))
            k = end + 1
        else:
            k += 1
    assert [(e["start"], e["end"], e["until"], e["count"]) for e in data["episodes"]] == stretches


def test_the_dashboard_says_not_judged_and_names_the_signal(tmp_path: Path):
    app = write_guarded_app(
        tmp_path / "app",
        signals={"heading": "float"},
        inputs="input heading: float\n",
        extra="\nproperty steady:\n    always (heading <= 90)\n",
        every=8,
    )
    from rasm import Platform, RunOptions

    platform = Platform(app, RunOptions(clock="simulated", seed=1))
    platform.build()
    dashboard = serve(platform, 0)
    try:
        platform.run(5.0)
    finally:
        dashboard.close()
    timelines = {t["name"]: t for t in json.loads(dashboard.snapshot()[1])["properties"][
        "timelines"]}
    assert timelines["steady"]["verdict"] == "not judged"
    assert timelines["steady"]["missing"] == ["heading"]
    assert timelines["steady"]["describe"] == "not judged: no value for heading"
    assert timelines["slow"]["verdict"] == "satisfied" and timelines["slow"]["judged"] > 0
    # the dashboard's states are the run summary's
    outcomes = platform.managing.trustworthiness_checker.outcomes
    summary_states = {name: o.state for name, o in outcomes.items()}
    assert {name: t["verdict"] for name, t in timelines.items()} == summary_states
