"""The platform charts mean the same under stock sismic and under rasm's interpreter.

rasm.statechart.Interpreter is a faster, atomic re-implementation of sismic's step semantics;
the charts in statecharts/ are written against sismic's documented semantics. For all event
sequences both engines must take the same macro steps on every platform chart, with the same
context afterwards: otherwise a chart simulated with one would behave differently in the other.
The clock moves in steps on a binary grid, where stock's binary arithmetic is exact: off it,
rasm's timers hold at their deadline where stock's can miss it (tests/statechart/
test_exact_timers.py).
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sismic.clock import SimulatedClock
from sismic.interpreter import Interpreter as SismicInterpreter

from rasm.statechart import Interpreter

from .support import BLOCKS, LIFECYCLE_EVENTS, chart_path, load, transition_events


def observe(engine, chart, script, context):
    clock = SimulatedClock()
    interpreter = engine(chart, clock=clock, initial_context=dict(context))
    steps = list(interpreter.execute())
    for delay, event in script:
        clock.time += delay
        steps += interpreter.execute()
        interpreter.queue(event)
        steps += interpreter.execute()
    trace = [
        (
            macro.time,
            macro.event.name if macro.event is not None else None,
            [
                (
                    micro.transition.source if micro.transition else None,
                    micro.transition.target if micro.transition else None,
                    list(micro.entered_states),
                    list(micro.exited_states),
                    [(e.name, e.data) for e in micro.sent_events],
                )
                for micro in macro.steps
            ],
        )
        for macro in steps
    ]
    return trace, sorted(interpreter.configuration), dict(interpreter.context)


@pytest.mark.parametrize("name", BLOCKS)
@settings(max_examples=30, deadline=None)
@given(data=st.data())
def test_stock_sismic_and_rasm_take_the_same_steps(name, data):
    chart = load(chart_path(name))
    events = sorted(transition_events(chart)) + ["bogus"]
    lifecycle = ["configure", "configuration_done", "initialization_done"] * 3 + LIFECYCLE_EVENTS
    script = data.draw(
        st.lists(
            st.tuples(
                st.sampled_from([0.0, 0.125, 0.5, 1.0, 2.5, 6.0]),
                st.one_of(st.sampled_from(lifecycle), st.sampled_from(events)),
            ),
            max_size=30,
        )
    )
    context = data.draw(st.sampled_from([{}, {"stage_budget": 0.5, "max_replans": 0}]))
    assert observe(Interpreter, chart, script, context) == observe(
        SismicInterpreter, chart, script, context
    )
