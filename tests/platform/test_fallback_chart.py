"""The fallback switch's chart (statecharts/fallback.yaml) explored with hypothesis: control is
handed back only after no trigger for the dwell time, every engagement is released at most once,
and a chart that hands back too early is caught."""

from __future__ import annotations

from hypothesis import Phase, settings

from rasm.resources import platform_chart
from rasm.testing import ChartFailure, statechart_machine

DWELL = 2.0
EVENTS = ["configure", "configuration_done", "initialization_done", "trigger", "clear"]
BUDGET = settings(
    max_examples=150, stateful_step_count=14, deadline=None, database=None, derandomize=True,
    phases=[Phase.explicit, Phase.reuse, Phase.generate, Phase.shrink],
)


def handed_back_only_after_the_dwell(state):
    if not state.active("initialized"):
        return True
    context = state.context
    holding = state.active("fallback") or state.active("recovering")
    assert context["engagements"] == context["releases"] + holding
    if context["releases"] and state.active("nominal"):
        # the last hand-back came at least the dwell after the switch last started recovering,
        # and no trigger was sent in between
        since, released = context["recovering_since"], context["released_at"]
        assert released - since >= DWELL
        assert not any(
            since < event["time"] < released for event in state.events
            if event["event"] == "trigger"
        )
    return True


def explore(chart):
    machine = statechart_machine(
        chart, invariant=handed_back_only_after_the_dwell, events=EVENTS,
        initial_context={"dwell": DWELL}, delays=[0.0, 0.5, 1.0, 2.5],
    )
    machine.TestCase.settings = BUDGET
    machine.TestCase().runTest()


def test_the_switch_hands_back_only_after_the_dwell_without_a_trigger():
    explore(platform_chart("fallback"))


def test_a_switch_that_hands_back_too_early_is_caught(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the failing sequence is saved under .rasm/failures/
    text = platform_chart("fallback").read_text().replace("after(dwell)", "after(dwell / 4)")
    early = tmp_path / "fallback.yaml"
    early.write_text(text)
    try:
        explore(str(early))
    except ChartFailure as failure:
        assert "after the dwell" in failure.reason or "assert" in failure.reason.lower()
    else:
        raise AssertionError("the early hand-back was not found")
