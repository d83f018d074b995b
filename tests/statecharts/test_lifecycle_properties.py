"""For all event sequences, every platform chart keeps the lifecycle's invariants.

The sequences are drawn step by step from the events the chart's own transitions name (weighted
towards the one that moves the current mode on, so that runs reach `initialized` and its core
task), a few events no chart knows, random data and random time advancing between events (so every
`after(...)` budget can fire). The observed
mode sequence is compared with the reference model of the convention (support.LIFECYCLE).
"""

from __future__ import annotations

import functools

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from .support import (
    BLOCKS,
    LIFECYCLE,
    LIFECYCLE_EVENTS,
    MODES,
    TIMED_FAULTS,
    chart_path,
    load,
    start,
    transition_events,
)

UNKNOWN_EVENTS = ["bogus", "Terminate", "configure_done"]
#: The event that moves each mode on; drawn more often so that most runs reach the core task.
PROGRESS = {
    "instantiated": "configure",
    "configuration": "configuration_done",
    "initialization": "initialization_done",
    "fault": "reset",
}
DELAYS = st.one_of(
    st.just(0.0),
    st.floats(min_value=0.0, max_value=2.0, allow_nan=False),
    st.sampled_from([0.999999, 1.0, 5.0, 30.0]),
)
DATA = st.one_of(
    st.just({}),
    st.fixed_dictionaries({"reason": st.text(max_size=5)}),
    st.fixed_dictionaries({"stage": st.sampled_from(["monitoring", "x"])}),
)


@functools.cache
def next_event(chart, mode: str):
    """A strategy for the next event, given the mode the chart is in: mostly the event that moves
    the lifecycle on (or, in `initialized`, one of the core task's events), sometimes any event
    of the chart, an unknown one, or a lifecycle event that does not apply here."""
    own = sorted(transition_events(chart) - set(LIFECYCLE_EVENTS))
    likely = st.sampled_from(own) if mode in ("initialized", "terminated") else st.just(
        PROGRESS[mode]
    )
    return st.one_of(
        likely,
        likely,
        likely,
        st.sampled_from(own),
        st.sampled_from(LIFECYCLE_EVENTS),
        st.sampled_from(UNKNOWN_EVENTS),
    )


@functools.cache
def next_step(chart, mode: str):
    return st.tuples(DELAYS, next_event(chart, mode), DATA)


def mode_of(configuration: list[str]) -> str:
    """The active mode, or `terminated` once sismic has emptied the configuration."""
    modes = [s for s in configuration if s in MODES]
    if not configuration:
        return "terminated"
    assert len(modes) == 1, configuration
    return modes[0]


def check_step(name, before: str, macro, after: str) -> None:
    """One macro step moved the chart from mode ``before`` to mode ``after``: was that allowed?"""
    event = macro.event.name if macro.event is not None else None
    if before == "terminated":
        # Nothing happens after terminated.
        assert all(not m.entered_states and not m.exited_states for m in macro.steps), macro
        assert after == "terminated"
        return
    if event is not None and (before, event) in LIFECYCLE:
        assert after == LIFECYCLE[(before, event)], (before, event, after)
        return
    if after != before:
        # The only mode change not caused by a lifecycle event: a core-task budget overrun.
        assert before == "initialized" and after == "fault", (before, event, after)
        sources = {m.transition.source for m in macro.steps if m.transition is not None}
        assert sources & TIMED_FAULTS.get(name, set()), macro


def entered_modes(macro) -> list[str]:
    return [s for m in macro.steps for s in m.entered_states if s in MODES]


@pytest.mark.slow
@pytest.mark.parametrize("name", BLOCKS)
@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_random_event_sequences_keep_the_lifecycle_invariants(name, data):
    chart = load(chart_path(name))
    run = start(chart)
    # The configuration is replayed from each macro step's exits and entries, so every step is
    # judged on the mode it really left and reached, not on the state at the end of a batch.
    config = set(run.configuration)
    mode = mode_of(sorted(config))
    assert mode == "instantiated"
    history = [mode]
    for _ in range(data.draw(st.integers(min_value=0, max_value=40), label="length")):
        delay, event, payload = data.draw(next_step(chart, mode), label="delay, event, data")
        for macro in run.advance(delay) + run.send(event, **payload):
            for micro in macro.steps:
                config.difference_update(micro.exited_states)
                config.update(micro.entered_states)
            new_mode = mode_of(sorted(config))
            check_step(name, mode, macro, new_mode)
            history.extend(entered_modes(macro))
            mode = new_mode
        assert sorted(config) == sorted(run.configuration)
        if mode == "terminated":
            assert run.interpreter.final and run.configuration == []
    _check_mode_history(history)


ALLOWED_NEXT = {
    "instantiated": {"configuration", "terminated"},
    "configuration": {"initialization", "fault", "terminated"},
    "initialization": {"initialized", "fault", "terminated"},
    "initialized": {"fault", "terminated"},
    "fault": {"instantiated", "terminated"},
    "terminated": set(),
}


def _check_mode_history(history: list[str]) -> None:
    """The modes entered, in order: bring-up is never skipped, terminated is the last word."""
    assert history[0] == "instantiated"
    for previous, current in zip(history, history[1:], strict=False):
        assert current in ALLOWED_NEXT[previous], history
