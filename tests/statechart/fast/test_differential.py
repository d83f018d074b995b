"""Differential tests: FastInterpreter and stock sismic observe exactly the same runs.

For random charts (see ``strategies``) and random event scripts with time advancing, every macro
step, configuration, context, memory, queue, sent event and error (type and message) must be equal
between ``sismic.interpreter.Interpreter`` and ``FastInterpreter``.

Time moves in steps on a binary grid (multiples of 1/8 s), where stock sismic's binary arithmetic
is exact: off the grid the one departure shows, rasm's timers holding at their deadline where
stock's can miss it (``tests/statechart/test_exact_timers.py``).
"""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sismic.interpreter import Interpreter
from sismic.io import import_from_yaml

from rasm.statechart.fast import FastInterpreter
from rasm.statechart.interpreter import FastGuardEvaluator
from rasm.statechart.interpreter import Interpreter as PlatformInterpreter
from tests.statechart.fast import harness
from tests.statechart.fast.charts import MONITORS, STATECHARTS
from tests.statechart.fast.strategies import charts, property_charts, scripts

SETTINGS = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])


class OneFrameGuards(FastInterpreter):
    """FastInterpreter with the platform's guard evaluator (one frame, only the names used)."""

    def __init__(self, statechart, **options):
        options.setdefault("evaluator_klass", FastGuardEvaluator)
        super().__init__(statechart, **options)

    def __repr__(self) -> str:  # as stock's, for PropertyStatechartError messages
        return f"Interpreter({self._statechart!r})"


def assert_same(chart, script, klass=FastInterpreter, **options) -> list:
    expected = harness.run(Interpreter, chart, script, **options)
    actual = harness.run(klass, chart, script, **options)
    assert actual == expected
    return expected


@pytest.mark.slow
@SETTINGS
@given(chart=charts(contracts=False), script=scripts)
def test_same_runs_without_contracts(chart, script):
    assert_same(chart, script)


@pytest.mark.slow
@SETTINGS
@given(chart=charts(), script=scripts)
def test_same_runs_with_contracts(chart, script):
    assert_same(chart, script)


@pytest.mark.slow
@SETTINGS
@given(chart=charts(), script=scripts)
def test_same_runs_when_contracts_are_ignored(chart, script):
    assert_same(chart, script, ignore_contract=True)


@pytest.mark.slow
@SETTINGS
@given(chart=charts(), prop=property_charts(), script=scripts)
def test_same_runs_with_a_property_statechart(chart, prop, script):
    assert_same(chart, script, prop=prop)


@pytest.mark.slow
@SETTINGS
@given(chart=charts(), props=st.lists(property_charts(), min_size=2, max_size=3), script=scripts)
def test_same_runs_with_several_property_statecharts(chart, props, script):
    # as the platform binds three to its orchestrator: each listener decides, moves its time,
    # replays and raises on its own, in binding order
    assert_same(chart, script, prop=props)


@pytest.mark.slow
@SETTINGS
@given(chart=charts(), prop=st.none() | property_charts(), script=scripts)
def test_same_runs_with_the_platform_guard_evaluator(chart, prop, script):
    assert_same(chart, script, OneFrameGuards, prop=prop)


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(chart=charts(), prop=property_charts(), script=scripts, every=st.integers(1, 3))
def test_same_runs_when_state_is_restored_by_reassignment(chart, prop, script, every):
    # The atomic-step layer restores the state attributes by reassigning copies; cached
    # orders must follow.
    assert_same(chart, script, prop=prop, restore_every=every)


@pytest.mark.slow
@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(chart=charts(), prop=st.none() | property_charts(), script=scripts)
def test_same_meta_events_for_attached_listeners(chart, prop, script):
    records = assert_same(chart, script, prop=prop, record_meta=True)
    # The recorder hears every meta-event unless a property listener attached before it raised.
    assert any(record[0] == "meta" for record in records) or any(
        "error" in record[0] for record in records
    )


class Platform(PlatformInterpreter):
    """The platform's interpreter, binding properties as the platform does (its own default
    class: FastInterpreter with the one-frame evaluator, remembered selections and replays)."""

    def bind_property_statechart(self, statechart, *, interpreter_klass=None):  # noqa: D102
        return super().bind_property_statechart(statechart)

    def __repr__(self) -> str:  # as stock's, for PropertyStatechartError messages
        return f"Interpreter({self._statechart!r})"


@pytest.mark.slow
@SETTINGS
@given(chart=charts(), props=st.lists(property_charts(), max_size=3), script=scripts)
def test_the_platform_interpreter_runs_as_stock_while_no_step_fails(chart, props, script):
    # The atomic-step layer only acts when a step raises (it rolls the step back, where stock is
    # left half-applied): on runs without a failure, everything must be as stock's, with no
    # property, one, or several as on the platform's orchestrator.
    expected = harness.run(Interpreter, chart, script, prop=props)
    if any(record[0] in ("error", "init error") for record in expected):
        return
    assert harness.run(Platform, chart, script, prop=props) == expected


@pytest.mark.slow
@SETTINGS
@given(chart=charts(), prop=st.none() | property_charts(), script=scripts)
def test_a_failed_platform_step_leaves_everything_as_before_but_its_event(chart, prop, script):
    try:
        interp = harness.bounded(Platform)(chart)
        if prop is not None:
            interp.bind_property_statechart(prop)
    except Exception:  # noqa: BLE001 - a chart whose preamble fails: nothing to roll back
        return
    watcher = harness._property(interp)

    def state() -> tuple:
        return harness.describe_state(interp), (
            None if watcher is None else harness.describe_state(watcher)
        )

    def steps() -> None:
        for _ in range(harness.MAX_STEPS):
            before = state()
            try:
                if interp.execute_once() is None:
                    return
            except Exception:  # noqa: BLE001 - what a failure leaves is the point
                after = state()
                event = interp.last_failure.event
                if event is None:
                    assert after == before
                    return
                # the event the step consumed, the head of one queue, is gone; nothing else moved
                alternatives = []
                for queue in ("internal", "external"):
                    found = before[0][queue]
                    if found and found[0][1] == repr(event):
                        alternatives.append(
                            ({**before[0], queue: found[1:]}, before[1])
                        )
                assert after in alternatives

    steps()
    for dt, name, data in script:
        interp.clock.time += dt
        interp.queue(name, **data)
        steps()


ORCHESTRATOR_EVENTS = [
    "tick", "monitored", "no_anomaly", "anomaly", "planned", "no_plan", "accepted", "rejected",
    "executed", "dropped", "stage_failed", "drift_detected", "managed_system_lost",
    "managed_system_back", "failed", "reset",
]


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    script=st.lists(
        st.tuples(
            st.sampled_from([0, 0.125, 0.125, 0.625, 2.0]),  # the stage budget here is 1 s
            st.sampled_from(ORCHESTRATOR_EVENTS),
            st.just({}),
        ),
        max_size=40,
    )
)
def test_the_orchestrator_with_its_monitors_runs_as_stock(script):
    # The platform's own setting: the MAPLE-K orchestrator with the monitors/ property
    # statecharts, driven in any order, timers firing or not.
    orchestrator = import_from_yaml(filepath=str(STATECHARTS / "adaptation_orchestrator.yaml"))
    monitors = [import_from_yaml(filepath=str(p)) for p in sorted(MONITORS.glob("*.yaml"))]
    setup = [
        (0.125, name, {}) for name in ("configure", "configuration_done", "initialization_done")
    ]
    expected = harness.run(Interpreter, orchestrator, setup + script, prop=monitors)
    assert harness.run(FastInterpreter, orchestrator, setup + script, prop=monitors) == expected
    if not any(record[0] in ("error", "init error") for record in expected):
        assert harness.run(Platform, orchestrator, setup + script, prop=monitors) == expected
