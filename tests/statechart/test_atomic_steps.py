"""A step that raises leaves the configuration and context exactly as they were."""

from __future__ import annotations

import contextlib

import pytest
from sismic.clock import SimulatedClock
from sismic.exceptions import CodeEvaluationError, InvariantError, PropertyStatechartError
from sismic.interpreter import Interpreter as StockInterpreter

from rasm.errors import ExecutionError
from rasm.statechart import Interpreter, load_statechart


@contextlib.contextmanager
def step_fails(cause: type[Exception], match: str | None = None):
    """rasm's step fails with ExecutionError, raised from what sismic or the chart raised."""
    with pytest.raises(ExecutionError, match=match) as caught:
        yield caught
    assert isinstance(caught.value.cause, cause) and caught.value.__cause__ is caught.value.cause

CHART = """
statechart:
  name: fragile
  preamble: |
    items = [1, 2]
    level = 0
  root state:
    name: root
    initial: a
    states:
      - name: a
        transitions:
          - target: b
            event: go
            action: |
              level = 10
              items.append(3)
              send('went')
              level = level / divisor
      - name: b
        transitions:
          - target: a
            event: back
"""


def chart():
    return load_statechart(text=CHART, source="fragile.yaml")


def test_stock_sismic_is_left_half_applied():
    interp = StockInterpreter(chart())
    interp.execute()
    interp.queue("go")
    with pytest.raises(CodeEvaluationError):
        interp.execute()
    # the documented corruption: `a` exited, `b` not entered, context half-updated
    assert interp.configuration == ["root"]
    assert interp.context["level"] == 10


def test_rasm_rolls_the_step_back_and_discards_the_event():
    interp = Interpreter(chart())
    interp.execute()
    interp.queue("go").queue("back")
    with step_fails(CodeEvaluationError, match="divisor"):
        interp.execute_once()
    assert interp.configuration == ["root", "a"]
    assert interp.context["level"] == 0
    assert interp.context["items"] == [1, 2]  # in-place mutation undone too
    assert interp.last_failure.event.name == "go"
    assert [e.name for _, e in interp._internal_queue] == []  # `went` was not kept
    # the failing event is gone: the next step handles `back` (nothing to do in `a`)
    step = interp.execute_once()
    assert step.event.name == "back" and step.transitions == []
    interp._evaluator._context["divisor"] = 5
    interp.queue("go")
    interp.execute()
    assert interp.configuration == ["root", "b"]
    assert interp.context["level"] == 2


def test_bound_interpreters_only_receive_events_of_successful_steps():
    sender = Interpreter(chart())
    received = []
    sender.bind(lambda event: received.append(event.name))
    sender.execute()
    sender.queue("go")
    with step_fails(CodeEvaluationError):
        sender.execute()
    assert received == []
    sender._evaluator._context["divisor"] = 1
    sender.queue("go")
    sender.execute()
    assert received == ["went"]


PROPERTY = """
statechart:
  name: never_b
  root state:
    name: watching
    initial: ok
    states:
      - name: ok
        transitions:
          - target: broken
            event: state entered
            guard: event.state == 'b'
      - name: broken
        type: final
"""


def test_a_violated_property_statechart_rolls_the_step_back():
    interp = Interpreter(chart(), initial_context={"divisor": 1})
    interp.bind_property_statechart(load_statechart(text=PROPERTY))
    interp.execute()
    interp.queue("go")
    with step_fails(PropertyStatechartError):
        interp.execute()
    assert interp.configuration == ["root", "a"]
    # the property chart itself is restored as well: it can catch the next violation
    interp.queue("go")
    with step_fails(PropertyStatechartError):
        interp.execute()


def test_an_exception_in_the_initial_step_leaves_the_chart_uninitialised():
    bad = load_statechart(
        text="""
statechart:
  name: bad_entry
  root state:
    name: root
    on entry: x = 1 / 0
"""
    )
    interp = Interpreter(bad, clock=SimulatedClock())
    with step_fails(CodeEvaluationError):
        interp.execute_once()
    assert interp.configuration == []
    assert interp.last_failure.event is None


COUNTING_PROPERTY = """
statechart:
  name: counts_exits_of_a
  preamble: exits = 0
  root state:
    name: root
    initial: watching
    states:
      - name: watching
        transitions:
          - target: seen
            event: state exited
            guard: event.state == 'a'
            action: exits += 1
      - name: seen
        transitions:
          - target: watching
            event: state entered
            guard: event.state == 'a'
"""


def watch(interp, prop, stock_listener: bool):
    """Bind ``prop`` with rasm's listener (snapshotted lazily) or stock's (up front)."""
    if stock_listener:
        from sismic.interpreter.listener import PropertyStatechartListener

        watcher = StockInterpreter(prop, clock=interp.clock)
        interp.attach(PropertyStatechartListener(watcher))
        return watcher
    return interp.bind_property_statechart(prop).interpreter


@pytest.mark.parametrize("stock_listener", [False, True])
def test_a_property_changed_before_the_failure_is_restored(stock_listener):
    # `a` is exited (the property moves to `seen`, counting it) before the action divides by
    # zero: the rollback must bring the property back too, whether it was snapshotted lazily
    # (rasm's listener, on its first change) or up front (stock's listener).
    interp = Interpreter(chart(), initial_context={"divisor": 0})
    prop = load_statechart(text=COUNTING_PROPERTY)
    watcher = watch(interp, prop, stock_listener)
    interp.execute()
    assert watcher.configuration == ["root", "watching"]
    interp.queue("go")
    with step_fails(CodeEvaluationError):
        interp.execute()
    assert interp.configuration == ["root", "a"]
    assert watcher.configuration == ["root", "watching"]
    assert watcher.context["exits"] == 0


@pytest.mark.parametrize("stock_listener", [False, True])
def test_the_time_a_skipped_meta_event_records_is_rolled_back_too(stock_listener):
    # The property cannot react to anything in the failing step (it only watches entries of
    # `b`, which the failure prevents), so rasm's listener skips every meta-event and only
    # records the new time, as the skipped executions would have; the rollback must undo that
    # too, as it undoes stock's executions.
    interp = Interpreter(chart(), initial_context={"divisor": 0}, clock=SimulatedClock())
    prop = load_statechart(text=COUNTING_PROPERTY.replace("'a'", "'b'"))
    watcher = watch(interp, prop, stock_listener)
    interp.execute()
    assert watcher.time == 0
    interp.clock.time = 5
    interp.queue("go")
    with step_fails(CodeEvaluationError):
        interp.execute()
    assert watcher.time == 0
    assert watcher.configuration == ["root", "watching"]
    # a step that succeeds at the new time is recorded
    interp.queue("unknown")
    interp.execute()
    assert watcher.time == 5


def test_a_property_that_records_the_time_then_changes_is_restored_to_before_both():
    # In one failing step the property first only records the new time (a skipped meta-event:
    # its time alone is saved) and then reacts to the exit of `a` (its full snapshot, taken
    # then, already holds the new time): the rollback must bring back the time from before both.
    interp = Interpreter(chart(), initial_context={"divisor": 0}, clock=SimulatedClock())
    watcher = watch(interp, load_statechart(text=COUNTING_PROPERTY), stock_listener=False)
    interp.execute()
    interp.clock.time = 5
    interp.queue("go")
    with step_fails(CodeEvaluationError):
        interp.execute()
    assert (watcher.time, watcher.configuration, watcher.context["exits"]) == (
        0, ["root", "watching"], 0
    )


# the same property without its counter: it only ever moves between its two states
STATIC_PROPERTY = COUNTING_PROPERTY.replace("  preamble: exits = 0\n", "").replace(
    "            action: exits += 1\n", ""
)


@pytest.mark.parametrize("rounds", [1, 3])
def test_a_property_that_reacted_before_is_rolled_back_with_the_failed_step(rounds):
    # After reacting in earlier steps, the property reacts to leaving `a` in a step that then
    # fails: it must be brought back exactly as it was before that step.
    interp = Interpreter(chart(), initial_context={"divisor": 1}, clock=SimulatedClock())
    listener = interp.bind_property_statechart(load_statechart(text=STATIC_PROPERTY))
    watcher = listener.interpreter
    interp.execute()
    for _ in range(rounds):
        for event in ("go", "back"):
            interp.clock.time += 1
            interp.queue(event)
            interp.execute()

    def state(p):
        return p.configuration, dict(p._entry_time), dict(p._idle_time), p.time

    before = state(watcher)
    interp.context["divisor"] = 0
    interp.clock.time = now = 2 * rounds + 3
    interp.queue("go")
    with step_fails(CodeEvaluationError):
        interp.execute()
    assert state(watcher) == before
    interp.context["divisor"] = 1  # and the property goes on as stock's would
    interp.queue("go")
    interp.execute()
    assert watcher.configuration == ["root", "seen"]
    assert watcher._entry_time["seen"] == now


DELAYED = """
statechart:
  name: delayed_failure
  root state:
    name: root
    initial: a
    states:
      - name: a
        on entry: send('later', delay=5)
        transitions:
          - target: b
            event: later
            action: x = 1 / 0
      - name: b
"""


def test_a_delayed_event_that_fails_its_step_is_discarded():
    # the event is due only at the step's new time, not at the time before it
    clock = SimulatedClock()
    interp = Interpreter(load_statechart(text=DELAYED), clock=clock)
    interp.execute()
    clock.time = 5
    with step_fails(CodeEvaluationError):
        interp.execute_once()
    assert interp.last_failure.event.name == "later"
    assert interp.configuration == ["root", "a"]
    assert interp._internal_queue == []
    assert interp.execute_once() is None  # nothing left to fail on


BOUNDED = """
statechart:
  name: bounded
  preamble: x = 0
  root state:
    name: root
    initial: a
    states:
      - name: a
        contract:
          - always: x < 5
        transitions:
          - target: a
            event: jump
            action: x = 5
"""


def test_a_contract_error_shows_the_context_at_the_failure_not_the_restored_one():
    # The step is rolled back (x is 0 again), but the error says what broke the invariant.
    for klass in (StockInterpreter, Interpreter):
        interp = klass(load_statechart(text=BOUNDED))
        interp.execute()
        interp.queue("jump")
        with pytest.raises(Exception) as failure:  # noqa: B017 - stock's or rasm's, below
            interp.execute()
        error = failure.value.cause if klass is Interpreter else failure.value
        assert isinstance(error, InvariantError)
        assert error.context["x"] == 5
        assert " - x = 5" in str(error).splitlines()
    assert interp.context["x"] == 0  # rasm's step was rolled back


GUARDED = """statechart:
  name: guarded
  root state:
    name: root
    initial: a
    states:
      - name: a
        transitions:
          - target: b
            event: go
            guard: 1 / event.data.get('n', 1) > 0
      - name: b
"""


def test_an_event_whose_guard_raises_is_discarded_not_left_to_fail_every_later_step():
    # sismic looks at an event before it takes it from the queue: a guard raising on it left
    # it at the head, and every later step failed on it again
    chart = Interpreter(load_statechart(text=GUARDED))
    chart.execute()
    chart.queue("go", n=0)
    with pytest.raises(ExecutionError, match="division by zero"):
        chart.execute_once()
    assert chart.last_failure.event.name == "go" and chart.last_failure.event.data == {"n": 0}
    chart.queue("go", n=2)
    assert chart.execute_once() is not None
    assert chart.configuration == ["root", "b"]
