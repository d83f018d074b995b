"""The property statecharts in monitors/ against the orchestrator chart.

Two directions: for all event sequences the shipped orchestrator never makes a monitor fail (the
chart is right), and hand-broken variants of the orchestrator are caught by exactly the monitors
whose property they break (the monitors are not vacuous).
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sismic.exceptions import PropertyStatechartError
from sismic.interpreter import Interpreter as SismicInterpreter

from rasm.errors import ExecutionError
from rasm.statechart import Interpreter, load_statechart
from rasm.yamltext import load_yaml, plain

from .support import (
    BRING_UP,
    LIFECYCLE_EVENTS,
    LOOP_EVENTS,
    MONITORS,
    OUTCOMES,
    chart_path,
    entered,
    load,
    micro_steps,
    monitor_path,
    start,
)

CHART = chart_path("adaptation_orchestrator")


# what a violated monitor raises: sismic's error, or rasm's step error raised from it
MONITOR_FAILED = (PropertyStatechartError, ExecutionError)


def violation(error: BaseException) -> PropertyStatechartError:
    """sismic's PropertyStatechartError, as sismic raises it or as the cause of rasm's error."""
    cause = error.cause if isinstance(error, ExecutionError) else error
    assert isinstance(cause, PropertyStatechartError), error
    return cause


def monitors(names=MONITORS):
    return [load(monitor_path(name)) for name in names]


def current(run) -> str:
    """The orchestrator's innermost state, or its mode outside `initialized` ('' when final)."""
    config = set(run.configuration)
    inner = config - {"lifecycle", "initialized"}
    return next(iter(inner), "")


# ------------------------------------------------------------------------- the chart is right


@functools.cache
def next_step(state: str):
    """Mostly an outcome of the current stage (so iterations get deep), sometimes any loop event,
    `stage_failed`, a lifecycle event or an unknown one, after a random delay that may overrun
    the stage budget."""
    likely = OUTCOMES.get(state) or {
        "instantiated": ("configure",),
        "configuration": ("configuration_done",),
        "initialization": ("initialization_done",),
        "fault": ("reset",),
    }.get(state, ("tick",))
    # Hypothesis favours the first element of a sampled_from: offer the outcomes in both orders
    # so that, say, `rejected` comes about as often as `accepted`.
    event = st.one_of(
        st.sampled_from(likely),
        st.sampled_from(likely[::-1]),
        st.sampled_from(likely),
        st.sampled_from(likely[::-1]),
        st.sampled_from(LOOP_EVENTS),
        st.sampled_from([*LIFECYCLE_EVENTS, "bogus"]),
    )
    # Mostly short delays, so that iterations get through; sometimes one long enough to overrun.
    delay = st.one_of(
        st.just(0.0), st.floats(0.0, 0.3), st.just(0.0), st.sampled_from([0.5, 1.0, 2.5])
    )
    return st.tuples(delay, event)


BUDGETS = st.sampled_from([1.0, 2.0, 0.5, 0.0])
MAX_REPLANS = st.integers(min_value=0, max_value=3)


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(data=st.data(), budget=BUDGETS, max_replans=MAX_REPLANS)
def test_no_event_sequence_makes_a_monitor_fail_on_the_shipped_orchestrator(
    data, budget, max_replans
):
    run = start(
        load(CHART),
        context={"stage_budget": budget, "max_replans": max_replans},
        monitors=monitors(),
    )
    run.send_all(BRING_UP)
    for _ in range(data.draw(st.integers(min_value=0, max_value=60), label="length")):
        delay, event = data.draw(next_step(current(run)), label="delay, event")
        run.advance(delay)  # a monitor's failure here or below fails the test
        run.send(event)
    bound = [listener._interpreter for listener in run.interpreter._listeners]
    assert [p.statechart.name for p in bound] == list(MONITORS)
    assert not any(p.final for p in bound)


@pytest.mark.slow
def test_the_generated_sequences_reach_every_stage_and_outcome():
    """The property above means something only if its runs get deep: check that they do."""
    seen_states: set[str] = set()
    seen_events: set[str] = set()

    # Derandomized: a coverage claim must not depend on the luck of one run. What Hypothesis
    # draws still depends on the constants it finds in the modules the process has imported, so
    # on which tests ran before: 100 examples missed stage_timeout and adaptation_cancelled after
    # tests/platform and tests/turtlebot; 300 reach every outcome in every order tried.
    @settings(max_examples=300, deadline=None, database=None, derandomize=True)
    @given(data=st.data(), budget=BUDGETS, max_replans=MAX_REPLANS)
    def explore(data, budget, max_replans):
        run = start(load(CHART), context={"stage_budget": budget, "max_replans": max_replans})
        run.send_all(BRING_UP)
        for _ in range(data.draw(st.integers(min_value=0, max_value=60))):
            delay, event = data.draw(next_step(current(run)))
            run.advance(delay)
            run.send(event)
        seen_states.update(entered(run.steps))
        seen_events.update(m.event.name for m in micro_steps(run.steps) if m.event is not None)

    explore()
    assert {"executing", "fault", "instantiated"} <= seen_states
    assert set(LOOP_EVENTS) <= seen_events
    assert {"stage_timeout", "adaptation_cancelled"} <= seen_events


# ------------------------------------------------------------------------- the monitors bite

Edit = Callable[[dict], None]


def _state(node: dict, name: str) -> dict | None:
    if node.get("name") == name:
        return node
    for child in node.get("states", []) + node.get("parallel states", []):
        found = _state(child, name)
        if found is not None:
            return found
    return None


def drop(source: str, event: str | None) -> Edit:
    """Remove the transitions of ``source`` on ``event`` (None: the eventless ones)."""

    def edit(doc: dict) -> None:
        state = _state(doc["statechart"]["root state"], source)
        state["transitions"] = [t for t in state["transitions"] if t.get("event") != event]

    return edit


def add(source: str, **transition: str) -> Edit:
    def edit(doc: dict) -> None:
        _state(doc["statechart"]["root state"], source)["transitions"].append(transition)

    return edit


def rewire(source: str, event: str | None, target: str) -> Edit:
    """Replace the transitions of ``source`` on ``event`` by one unguarded transition to
    ``target`` (for ``event=None``: the timeout, kept as ``after(stage_budget)``, no action)."""

    def edit(doc: dict) -> None:
        drop(source, event)(doc)
        if event is None:
            add(source, guard="after(stage_budget)", target=target)(doc)
        else:
            add(source, event=event, target=target)(doc)

    return edit


@functools.cache
def mutant(*edits: Edit):
    doc = plain(load_yaml(CHART.read_text(encoding="utf-8"), str(CHART)).data)
    for edit in edits:
        edit(doc)
    return load_statechart(text=json.dumps(doc), source="<mutant>")  # JSON is YAML


TO_LEGITIMATING = ("tick", "monitored", "anomaly", "planned")
TO_EXECUTING = (*TO_LEGITIMATING, "accepted")

#: name -> (edits, what to feed: event names or delays in seconds, the monitors that must fail).
#: The order of the stages is checked on the trace (stage_order in properties/maple_k.rv), not by
#: a property statechart: a mutant that only breaks the order fails none of these.
MUTANTS = {
    "rejected_plan_is_executed": (
        (rewire("legitimating", "rejected", "executing"),),
        (*TO_LEGITIMATING, "rejected"),
        {"accepted_before_executing"},
    ),
    "planning_is_skipped": (
        (rewire("analysing", "anomaly", "legitimating"),),
        ("tick", "monitored", "anomaly"),
        set(),
    ),
    "idle_jumps_to_executing": (
        (rewire("idle", "tick", "executing"),),
        ("tick",),
        {"accepted_before_executing"},
    ),
    "accepted_plan_is_planned_again": (
        (rewire("legitimating", "accepted", "planning"),),
        (*TO_LEGITIMATING, "accepted"),
        set(),
    ),
    "next_iteration_skips_idle": (
        (rewire("executing", "executed", "monitoring"),),
        (*TO_EXECUTING, "executed"),
        set(),
    ),
    "failed_stage_executes": (
        (rewire("analysing", "stage_failed", "executing"),),
        ("tick", "monitored", "stage_failed"),
        {"accepted_before_executing"},
    ),
    "timeout_goes_on_to_the_next_stage": (
        (rewire("monitoring", None, "analysing"),),
        ("tick", 1.5),
        {"stage_outcome"},
    ),
    "timeout_without_signal": (
        (rewire("planning", None, "idle"),),
        ("tick", "monitored", "anomaly", 1.5),
        {"stage_outcome"},
    ),
    "legitimating_timeout_executes": (
        (rewire("legitimating", None, "executing"),),
        (*TO_LEGITIMATING, 1.5),
        {"accepted_before_executing", "stage_outcome"},
    ),
    "tick_interrupts_executing": (
        (add("executing", event="tick", target="idle"),),
        (*TO_EXECUTING, "tick"),
        {"stage_outcome"},
    ),
    "monitoring_left_by_a_foreign_outcome": (
        (add("monitoring", event="executed", target="idle"),),
        ("tick", "executed"),
        {"stage_outcome"},
    ),
}


def feed(run, script) -> None:
    for item in script:
        if isinstance(item, str):
            run.send(item)
        else:
            run.advance(item)


@pytest.mark.parametrize("engine", [Interpreter, SismicInterpreter], ids=["rasm", "sismic"])
@pytest.mark.parametrize("name", sorted(MUTANTS))
def test_the_shipped_orchestrator_passes_every_mutant_script(name, engine):
    _, script, _ = MUTANTS[name]
    run = start(load(CHART), monitors=monitors(), engine=engine)
    run.send_all(BRING_UP)
    feed(run, script)
    assert current(run)  # still running: nothing was refused


@pytest.mark.parametrize("engine", [Interpreter, SismicInterpreter], ids=["rasm", "sismic"])
@pytest.mark.parametrize("monitor", MONITORS)
@pytest.mark.parametrize("name", sorted(MUTANTS))
def test_a_broken_orchestrator_is_caught_by_exactly_the_monitors_it_breaks(name, monitor, engine):
    edits, script, catchers = MUTANTS[name]
    run = start(mutant(*edits), monitors=monitors([monitor]), engine=engine)
    run.send_all(BRING_UP)
    if monitor in catchers:
        with pytest.raises(MONITOR_FAILED) as failure:
            feed(run, script)
        assert violation(failure.value).property_statechart.statechart.name == monitor
    else:
        feed(run, script)


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_the_monitor_catches_every_rejected_plan_that_is_executed(data):
    """On the broken chart, `accepted_before_executing` fails exactly when a `rejected` arrives
    in legitimating (which that chart turns into an execution), whatever came before."""
    edits, _, _ = MUTANTS["rejected_plan_is_executed"]
    run = start(mutant(*edits), monitors=monitors(["accepted_before_executing"]))
    run.send_all(BRING_UP)
    for _ in range(data.draw(st.integers(min_value=0, max_value=40), label="length")):
        delay, event = data.draw(next_step(current(run)), label="delay, event")
        run.advance(delay)
        breaks = current(run) == "legitimating" and event == "rejected"
        if breaks:
            with pytest.raises(MONITOR_FAILED) as failure:
                run.send(event)
            violation(failure.value)
            return
        run.send(event)


# ------------------------------------------------------------- a rewrite that decides alike

#: stage_outcome as first written (the stage left kept in a context variable set by an action);
#: the shipped chart has a state per stage instead, so that every guard reads the meta-event only
ORIGINAL_STAGE_OUTCOME = Path(__file__).parent / "data" / "stage_outcome_original.yaml"


def _play(run, script) -> list[bool]:
    """Feed (delay, event or None) items; after each, whether a bound monitor has failed."""
    failed, out = False, []
    for delay, event in script:
        if not failed:
            try:
                run.advance(delay)
                if event is not None:
                    run.send(event)
            except MONITOR_FAILED as error:
                violation(error)
                failed = True
        out.append(failed)
    return out


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(
    data=st.data(),
    broken=st.sampled_from([None, *sorted(MUTANTS)]),
    budget=BUDGETS,
    max_replans=MAX_REPLANS,
)
def test_the_rewritten_stage_outcome_decides_like_the_original(data, broken, budget, max_replans):
    chart = load(CHART) if broken is None else mutant(*MUTANTS[broken][0])
    context = {"stage_budget": budget, "max_replans": max_replans}
    # a broken orchestrator's own script first (so its broken path is taken), then what the
    # orchestrator's current state makes likely
    script = [(0.0, item) if isinstance(item, str) else (item, None)
              for item in (MUTANTS[broken][1] if broken is not None else ())]
    run = start(chart, context=context)
    run.send_all(BRING_UP)
    _play(run, script)
    for _ in range(data.draw(st.integers(min_value=0, max_value=40), label="length")):
        script.append(data.draw(next_step(current(run)), label="delay, event"))
        _play(run, script[-1:])
    verdicts = {}
    for name, monitor in (
        ("original", load_statechart(ORIGINAL_STAGE_OUTCOME)),
        ("shipped", load(monitor_path("stage_outcome"))),
    ):
        run = start(chart, context=context, monitors=[monitor], engine=SismicInterpreter)
        run.send_all(BRING_UP)
        verdicts[name] = _play(run, script)
    assert verdicts["shipped"] == verdicts["original"]
