"""The MAPLE-K loop of the Adaptation Orchestrator chart, step by step and against its monitors."""

from __future__ import annotations

import pytest

from .support import (
    BRING_UP,
    STAGES,
    chart_path,
    entered,
    load,
    sent,
    start,
)

CHART = chart_path("adaptation_orchestrator")

TO_STAGE = {
    "idle": (),
    "monitoring": ("tick",),
    "analysing": ("tick", "monitored"),
    "planning": ("tick", "monitored", "anomaly"),
    "legitimating": ("tick", "monitored", "anomaly", "planned"),
    "executing": ("tick", "monitored", "anomaly", "planned", "accepted"),
}


def loop(**context):
    """The orchestrator brought up to `idle`, its loop ready for the first tick."""
    run = start(load(CHART), context=context or None)
    run.send_all(BRING_UP)
    assert run.configuration == ["lifecycle", "initialized", "idle"]
    return run


def stage_of(run) -> str:
    (stage,) = set(run.configuration) - {"lifecycle", "initialized"}
    return stage


def test_one_iteration_walks_the_stages_in_order_and_returns_to_idle():
    run = loop()
    start_at = len(run.steps)
    run.send_all(["tick", "monitored", "anomaly", "planned", "accepted", "executed"])
    assert entered(run.steps[start_at:]) == [*STAGES, "idle"]


@pytest.mark.parametrize(
    ("events", "ends_after"),
    [
        (("tick", "monitored", "no_anomaly"), "analysing"),
        (("tick", "monitored", "anomaly", "no_plan"), "planning"),
        (("tick", "monitored", "anomaly", "planned", "accepted", "dropped"), "executing"),
    ],
)
def test_an_iteration_without_an_adaptation_returns_to_idle(events, ends_after):
    run = loop()
    start_at = len(run.steps)
    run.send_all(events)
    stages = entered(run.steps[start_at:])
    assert stages[-1] == "idle" and stages[-2] == ends_after
    assert "executing" not in stages or ends_after == "executing"


def test_a_rejected_plan_is_replanned_until_max_replans_then_cancelled():
    run = loop(max_replans=2)
    run.send_all(TO_STAGE["legitimating"])
    for attempt in (1, 2):
        run.send("rejected")
        assert stage_of(run) == "planning" and run.context["replans"] == attempt
        run.send("planned")
    taken = run.send("rejected")
    assert stage_of(run) == "idle"
    assert sent(taken) == ["adaptation_cancelled"]
    assert taken[0].steps[0].sent_events[0].data == {"replans": 2}


def test_max_replans_zero_cancels_on_the_first_rejection():
    run = loop(max_replans=0)
    run.send_all(TO_STAGE["legitimating"])
    assert sent(run.send("rejected")) == ["adaptation_cancelled"]
    assert stage_of(run) == "idle"


def test_the_replan_counter_restarts_with_each_new_analysis():
    run = loop(max_replans=1)
    run.send_all([*TO_STAGE["legitimating"], "rejected", "planned", "rejected"])  # cancelled
    assert stage_of(run) == "idle" and run.context["replans"] == 1
    run.send_all(TO_STAGE["legitimating"])
    assert run.context["replans"] == 0
    run.send("rejected")  # one replan is allowed again
    assert stage_of(run) == "planning"


@pytest.mark.parametrize("stage", STAGES)
def test_stage_failed_ends_the_iteration_without_an_action(stage):
    run = loop()
    run.send_all(TO_STAGE[stage])
    assert stage_of(run) == stage
    taken = run.send("stage_failed")
    assert stage_of(run) == "idle"
    assert "executing" not in entered(taken)


@pytest.mark.parametrize("stage", STAGES)
@pytest.mark.parametrize("budget", [0.25, 1.0, 3.0])
def test_a_stage_overrunning_its_budget_cancels_the_iteration(stage, budget):
    run = loop(stage_budget=budget)
    run.send_all(TO_STAGE[stage])
    assert run.clock.time == 0.0  # the stage was entered at time 0
    run.advance_to(budget * 0.999)
    assert stage_of(run) == stage  # still within budget
    taken = run.advance_to(budget)
    assert stage_of(run) == "idle"
    timeouts = [e for m in taken for s in m.steps for e in s.sent_events]
    assert [(e.name, e.data) for e in timeouts] == [("stage_timeout", {"stage": stage})]


def test_the_budget_restarts_when_planning_is_entered_again_after_a_rejection():
    run = loop(stage_budget=1.0)
    run.send_all(TO_STAGE["legitimating"])
    run.advance(0.9)
    run.send("rejected")
    run.advance(0.9)  # 1.8 s since the iteration's first planning, 0.9 s since this one
    assert stage_of(run) == "planning"


def test_the_default_budget_is_one_second_and_the_default_replans_two():
    run = loop()
    assert run.context["stage_budget"] == 1.0 and run.context["max_replans"] == 2


def test_a_tick_during_an_iteration_is_skipped_and_counted():
    run = loop()
    run.send_all(TO_STAGE["planning"])
    taken = run.send("tick")
    assert stage_of(run) == "planning"
    assert all(not m.entered_states and not m.exited_states for s in taken for m in s.steps)
    assert run.context["ticks_skipped"] == 1
    run.send("tick")
    assert run.context["ticks_skipped"] == 2


@pytest.mark.parametrize("event", ["terminate", "failed"])
@pytest.mark.parametrize("stage", STAGES)
def test_the_lifecycle_interrupts_any_stage(stage, event):
    run = loop()
    run.send_all(TO_STAGE[stage])
    run.send(event)
    assert "executing" not in set(run.configuration)
    assert run.configuration == ([] if event == "terminate" else ["lifecycle", "fault"])


def test_after_a_reset_the_loop_starts_again_from_idle():
    run = loop()
    run.send_all(TO_STAGE["legitimating"])
    run.send_all(["failed", "reset", *BRING_UP])
    assert stage_of(run) == "idle"
    run.send_all(TO_STAGE["executing"])
    assert stage_of(run) == "executing"
