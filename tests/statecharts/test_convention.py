"""Every platform chart follows the lifecycle convention that Core and the block drivers rely on."""

from __future__ import annotations

import pytest
from sismic.model import CompoundState, FinalState

from rasm.lint import lint_file

from .support import (
    BLOCKS,
    BRING_UP,
    CHART_DIR,
    LIFECYCLE,
    MODES,
    MONITOR_DIR,
    MONITORS,
    TIMED_FAULTS,
    chart_path,
    entered,
    load,
    monitor_path,
    start,
)


def test_there_is_one_chart_per_building_block_and_nothing_else():
    assert sorted(p.stem for p in CHART_DIR.glob("*.yaml")) == sorted(BLOCKS)


def test_there_is_one_file_per_monitor():
    assert sorted(p.stem for p in MONITOR_DIR.glob("*.yaml")) == sorted(MONITORS)


@pytest.mark.parametrize(
    "path",
    [chart_path(n) for n in BLOCKS] + [monitor_path(n) for n in MONITORS],
    ids=lambda p: f"{p.parent.name}/{p.name}",
)
def test_rasm_lint_finds_no_problem(path):
    # Not even a warning: the shipped charts are the examples users copy.
    assert lint_file(path) == []


@pytest.mark.parametrize("name", MONITORS)
def test_monitor_is_named_after_its_file_and_fails_only_by_its_final_state(name):
    monitor = load(monitor_path(name))
    assert monitor.name == name and monitor.description
    finals = [s for s in monitor.states if isinstance(monitor.state_for(s), FinalState)]
    assert finals == ["violation"]
    assert monitor.parent_for("violation") == monitor.root


@pytest.mark.parametrize("name", BLOCKS)
def test_chart_is_named_after_its_file_and_described(name):
    chart = load(chart_path(name))
    assert chart.name == name
    assert chart.description and len(chart.description.split()) >= 10


@pytest.mark.parametrize("name", BLOCKS)
def test_the_six_modes_are_the_children_of_the_lifecycle_root(name):
    chart = load(chart_path(name))
    assert chart.root == "lifecycle"
    assert sorted(chart.children_for("lifecycle")) == sorted(MODES)
    root = chart.state_for("lifecycle")
    assert root.initial == "instantiated"
    assert isinstance(chart.state_for("terminated"), FinalState)
    initialized = chart.state_for("initialized")
    assert isinstance(initialized, CompoundState)
    assert initialized.initial in chart.children_for("initialized")
    # Only `initialized` holds the block's core task; the other modes are plain states.
    for mode in set(MODES) - {"initialized"}:
        assert chart.children_for(mode) == []


@pytest.mark.parametrize("name", BLOCKS)
def test_the_modes_are_left_exactly_by_the_lifecycle_transitions(name):
    chart = load(chart_path(name))
    leaving_modes = {
        (t.source, t.event, t.target)
        for t in chart.transitions
        if t.source in MODES
        and t.target is not None
        and t.target not in chart.descendants_for(t.source)
    }
    expected = {(mode, event, target) for (mode, event), target in LIFECYCLE.items()}
    assert leaving_modes == expected
    # Lifecycle transitions are unguarded: a done signal or `terminate` is never refused.
    for t in chart.transitions:
        if (t.source, t.event) in LIFECYCLE:
            assert t.guard is None, t


@pytest.mark.parametrize("name", BLOCKS)
def test_the_core_task_leaves_initialized_only_into_fault_on_a_budget(name):
    chart = load(chart_path(name))
    inside = set(chart.descendants_for("initialized"))
    escaping = [
        t for t in chart.transitions
        if t.source in inside and t.target is not None and t.target not in inside
    ]
    for t in escaping:
        assert t.target == "fault" and t.event is None, t
        assert t.source in TIMED_FAULTS.get(name, set()), t


@pytest.mark.parametrize("name", BLOCKS)
def test_bring_up_enters_the_modes_in_order_and_starts_the_core_task(name):
    chart = load(chart_path(name))
    run = start(chart)
    run.send_all(BRING_UP)
    modes = [s for s in entered(run.steps) if s in MODES]
    assert modes == ["instantiated", "configuration", "initialization", "initialized"]
    assert sorted(run.configuration) == sorted(
        ["lifecycle", "initialized", chart.state_for("initialized").initial]
    )


@pytest.mark.parametrize("name", BLOCKS)
@pytest.mark.parametrize("steps_before", [0, 1, 2, 3])
def test_terminate_ends_the_chart_from_every_mode(name, steps_before):
    chart = load(chart_path(name))
    run = start(chart)
    run.send_all(BRING_UP[:steps_before])
    taken = run.send("terminate")
    assert "terminated" in entered(taken)
    # sismic leaves a final state under the root at once: the configuration empties, the
    # interpreter reports `final`, and nothing it is sent afterwards does anything.
    assert run.interpreter.final
    assert run.configuration == []
    for event in ("configure", "reset", "initialization_done", "terminate"):
        for step in run.send(event):
            assert all(not m.entered_states and not m.exited_states for m in step.steps)
    assert run.configuration == []


@pytest.mark.parametrize("name", BLOCKS)
def test_a_failure_records_its_reason_and_reset_starts_over(name):
    chart = load(chart_path(name))
    run = start(chart)
    run.send_all(BRING_UP)
    run.send("failed", reason="sensor unplugged")
    assert run.configuration == ["lifecycle", "fault"]
    assert run.context["failure_reason"] == "sensor unplugged"
    run.send("configure")  # fault is left only by reset or terminate
    assert run.configuration == ["lifecycle", "fault"]
    run.send("reset")
    assert run.configuration == ["lifecycle", "instantiated"]
    run.send_all(BRING_UP)
    assert "initialized" in run.configuration


@pytest.mark.parametrize("name", BLOCKS)
def test_a_failure_without_a_reason_is_recorded_as_none(name):
    chart = load(chart_path(name))
    run = start(chart, context={"failure_reason": "stale"})
    run.send("configure")
    run.send("failed")
    assert run.configuration == ["lifecycle", "fault"]
    assert run.context["failure_reason"] is None
