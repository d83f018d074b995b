"""The tables of a chart: they live as long as the chart, and an edit of the chart is caught."""

from __future__ import annotations

import gc
import weakref
from collections.abc import Callable

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sismic.exceptions import ContractError
from sismic.interpreter import Interpreter
from sismic.io import import_from_yaml
from sismic.model import BasicState, Statechart, Transition

from rasm.errors import ExecutionError
from rasm.statechart import Interpreter as PlatformInterpreter
from rasm.statechart.fast import ChartEditedError, FastInterpreter
from tests.statechart.fast import harness
from tests.statechart.fast.charts import cycle
from tests.statechart.fast.strategies import charts, scripts

WATCHER = """
statechart:
  name: watches b
  root state:
    name: root
    initial: idle
    states:
    - name: idle
      transitions:
      - {target: seen, event: state entered, guard: event.state == 'b'}
    - name: seen
"""


@pytest.mark.slow
@pytest.mark.parametrize("klass", [Interpreter, FastInterpreter, PlatformInterpreter])
def test_a_chart_is_freed_with_its_last_interpreter(klass):
    charts_run = []
    for _ in range(100):
        chart = cycle(shortcut=True)
        interp = klass(chart)
        interp.bind_property_statechart(import_from_yaml(WATCHER))
        interp.execute()
        interp.queue("n").execute()
        charts_run.append(weakref.ref(chart))
    del chart, interp
    gc.collect()
    assert [ref for ref in charts_run if ref() is not None] == []


def _transition(chart: Statechart, source: str, event: str) -> Transition:
    return next(t for t in chart.transitions if t.source == source and t.event == event)


EDITS: dict[str, Callable[[Statechart], None]] = {
    # what sismic's own test suite does to a chart an interpreter was built for
    "remove a transition": lambda c: c.remove_transition(_transition(c, "a", "n")),
    "add a transition": lambda c: c.add_transition(Transition("a", "a", event="x")),
    "add a state": lambda c: c.add_state(BasicState("d"), "root"),
    "remove a state": lambda c: c.remove_state("c"),
    "rename a state": lambda c: c.rename_state("b", "bb"),
    "rotate a transition": lambda c: c.rotate_transition(_transition(c, "a", "n"), new_target="c"),
    "change a transition's event": lambda c: setattr(_transition(c, "a", "n"), "event", "m"),
}


@pytest.mark.parametrize("klass", [FastInterpreter, PlatformInterpreter])
@pytest.mark.parametrize("edit", EDITS.values(), ids=EDITS.keys())
def test_a_chart_edited_under_a_running_interpreter_raises(klass, edit):
    chart = cycle(shortcut=True)
    interp = klass(chart)
    interp.execute()
    edit(chart)
    interp.queue("n")
    with pytest.raises(ChartEditedError, match="build a new interpreter") as raised:
        interp.execute()
    assert "'cycle' was edited after its interpreter was built" in str(raised.value)
    # an interpreter built for the edited chart runs it as sismic does
    script = [(1.0, name, {}) for name in ("n", "m", "n", "x", "n")]
    assert harness.run(FastInterpreter, chart, script) == harness.run(Interpreter, chart, script)


def test_a_chart_moved_under_a_running_interpreter_raises():
    chart = import_from_yaml("""
statechart:
  name: nested
  root state:
    name: root
    initial: outer
    states:
    - name: outer
      initial: inner
      states: [{name: inner}]
    - name: other
""")
    interp = FastInterpreter(chart)
    interp.execute()
    chart.move_state("inner", "other")
    with pytest.raises(ChartEditedError, match="a state was added, removed, renamed or moved"):
        interp.execute_once()


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(chart=charts(contracts=False), script=scripts, which=st.integers(0, 1000))
def test_removing_any_transition_is_caught_and_the_edited_chart_runs_as_stock(
    chart, script, which
):
    if not chart.transitions:
        return
    interp = FastInterpreter(chart, ignore_contract=True)
    chart.remove_transition(chart.transitions[which % len(chart.transitions)])
    with pytest.raises(ChartEditedError):
        interp.execute_once()
    assert harness.run(FastInterpreter, chart, script) == harness.run(Interpreter, chart, script)


@pytest.mark.parametrize("klass", [Interpreter, FastInterpreter, PlatformInterpreter])
@pytest.mark.parametrize(
    ("kind", "state"),
    # `n` leaves a for b: a's postconditions, b's preconditions and invariants are checked
    [("postconditions", "a"), ("preconditions", "b"), ("invariants", "b")],
)
def test_a_condition_added_to_a_chart_without_contracts_is_evaluated(klass, kind, state):
    # what sismic's own contract tests do: append a condition to a loaded chart
    chart = cycle(shortcut=True)
    interp = klass(chart)
    interp.execute()
    getattr(chart.state_for(state), kind).append("False")
    interp.queue("n")
    with pytest.raises((ContractError, ExecutionError)) as raised:
        interp.execute()
    # rasm's interpreter raises its ExecutionError from sismic's ContractError
    error = raised.value.cause if isinstance(raised.value, ExecutionError) else raised.value
    assert isinstance(error, ContractError) and error.condition == "False"
    assert isinstance(error.obj, BasicState) and error.obj.name == state
