"""FastInterpreter against stock sismic on targeted cases: errors, shipped charts, copies,
queueing, bound interpreters, states and transitions known by their properties."""

from __future__ import annotations

import copy
import pickle

import pytest
from sismic.exceptions import (
    ConflictingTransitionsError,
    InvariantError,
    NonDeterminismError,
    PropertyStatechartError,
)
from sismic.interpreter import Interpreter
from sismic.io import import_from_yaml
from sismic.model import Event, Transition

from rasm.statechart.fast import FastInterpreter
from tests.statechart.fast import harness
from tests.statechart.fast.charts import STATECHARTS, chart, cycle, never_b_twice, toggle

NON_DETERMINISTIC = chart("""
statechart:
  name: nd
  root state:
    name: root
    initial: a
    states:
    - name: a
      transitions:
      - {target: b, event: e}
      - {target: c, event: e}
    - name: b
    - name: c
""")

CONFLICTING = chart("""
statechart:
  name: conflict
  root state:
    name: root
    initial: p
    states:
    - name: p
      parallel states:
      - name: r1
        initial: x
        states:
        - name: x
          transitions:
          - {target: out, event: e}
      - name: r2
        initial: y
        states:
        - name: y
          transitions:
          - {target: y, event: e}
    - name: out
""")

INVARIANT = chart("""
statechart:
  name: inv
  preamble: x = 0
  root state:
    name: root
    initial: a
    states:
    - name: a
      contract:
      - always: x < 2
      transitions:
      - {target: a, event: e, action: x += 1}
""")

PROPERTY = never_b_twice()
CYCLE = cycle()
TOGGLE = toggle()


def errors(klass, statechart, events, prop=None):
    interp = klass(statechart)
    if prop is not None:
        interp.bind_property_statechart(prop, interpreter_klass=klass)
    interp.execute()
    found = []
    for name in events:
        interp.queue(name)
        try:
            interp.execute(max_steps=5)
        except Exception as e:  # noqa: BLE001 - compared below
            found.append((type(e), str(e)))
    return found


@pytest.mark.parametrize(
    ("statechart", "events", "prop", "expected"),
    [
        (NON_DETERMINISTIC, ["e"], None, NonDeterminismError),
        (CONFLICTING, ["e"], None, ConflictingTransitionsError),
        (INVARIANT, ["e", "e", "e"], None, InvariantError),
        (TOGGLE, ["n"] * 4, PROPERTY, PropertyStatechartError),
    ],
    ids=["non-determinism", "conflict", "invariant", "property"],
)
def test_same_error_type_and_message(statechart, events, prop, expected):
    stock = errors(Interpreter, statechart, events, prop)
    fast = errors(FastInterpreter, statechart, events, prop)
    assert stock, "the scenario must raise"
    assert stock[0][0] is expected
    assert fast == stock


ROOT_TWICE = chart("""
statechart:
  name: root_twice
  root state:
    name: root
    transitions:
    - {event: e, action: x = 1}
    - {event: e, action: x = 2}
""")


def test_two_enabled_transitions_of_the_root_are_a_non_deterministic_choice():
    # stock sismic fails there looking for the root's parent ("State None does not exist");
    # the choice is as non-deterministic as between two transitions of any other state
    assert errors(Interpreter, ROOT_TWICE, ["e"])[0][1] == "State None does not exist"
    [(kind, message)] = errors(FastInterpreter, ROOT_TWICE, ["e"])
    assert kind is NonDeterminismError
    assert message.startswith("Non-determinist choice between transitions root -> e")


@pytest.mark.skipif(not STATECHARTS.is_dir(), reason="no shipped statecharts")
@pytest.mark.parametrize("path", sorted(STATECHARTS.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_charts_run_identically(path):
    statechart = import_from_yaml(filepath=str(path))
    names = statechart.events_for() + ["unknown"]
    script = [(0.5 * (i % 3), names[(i * 7) % len(names)], {}) for i in range(60)]
    expected = harness.run(Interpreter, statechart, script)
    assert harness.run(FastInterpreter, statechart, script) == expected


def test_copies_share_tables_and_keep_running_identically():
    interp = FastInterpreter(INVARIANT)
    interp.execute()
    clone = copy.deepcopy(interp, {id(INVARIANT): INVARIANT})
    assert clone._tables is interp._tables
    restored = pickle.loads(pickle.dumps(interp))
    for other in (interp, clone, restored):
        other.queue("e")
        other.execute()
        assert other.configuration == ["root", "a"]
        assert other.context["x"] == 1


@pytest.mark.parametrize(
    "queued",
    [
        (("n",), {}),
        (("n", "n"), {}),
        (("n", "x", "n"), {"v": 1}),
        ((Event("n", v=2),), {}),
        ((Event("n"), "n"), {"v": 3}),
        ((Event("n", delay=1),), {}),
        (("n",), {"delay": 0.5}),
    ],
)
def test_queue_takes_events_as_stock_does(queued):
    names, parameters = queued
    runs = []
    for klass in (Interpreter, FastInterpreter):
        interp = klass(CYCLE)
        interp.execute()
        interp.queue(*names, **parameters)
        queues = [(t, repr(e)) for t, e in interp._external_queue]
        interp.clock.time += 1
        runs.append((queues, [harness.describe_step(CYCLE, s) for s in interp.execute()]))
    assert runs[1] == runs[0]


SENDER = chart("""
statechart:
  name: sender
  root state:
    name: root
    initial: a
    states:
    - name: a
      transitions:
      - {target: b, event: n, action: "send('n', k=1)"}
    - name: b
      on entry: send('n', delay=2)
      transitions:
      - {target: a, event: n}
""")


@pytest.mark.parametrize("attach", ["bind", "callable"])
def test_a_bound_interpreter_receives_the_sent_events_as_with_stock(attach):
    # bind(): every event the sender sends is queued to the receiver (or given to a callable)
    runs = []
    for klass in (Interpreter, FastInterpreter):
        sender, receiver = klass(SENDER), klass(TOGGLE)
        received: list[str] = []
        if attach == "bind":
            sender.bind(receiver)
        else:
            sender.bind(lambda event, into=received: into.append(repr(event)))
        sender.execute()
        receiver.execute()
        trace = []
        for _ in range(6):
            sender.clock.time += 1
            receiver.clock.time += 1
            sender.queue("n")
            steps = sender.execute()
            trace.append((
                [harness.describe_step(SENDER, s) for s in steps],
                [(t, repr(e)) for t, e in receiver._external_queue],
                [harness.describe_step(TOGGLE, s) for s in receiver.execute()],
                list(received),
            ))
        runs.append(trace)
    assert runs[1] == runs[0]
    assert any(queued for _, queued, _, _ in runs[0]) or any(seen for *_, seen in runs[0])


# ------------------------------------------- states and transitions read through their properties


class _RenamingTransition(Transition):
    """A transition subclass whose `source`/`target` are its own (not sismic's `_source`)."""

    @property
    def target(self):
        return "b" if self._target == "a" else "a"


def _renamed_chart():
    """The flat cycle with a state whose `name` is not the name it is registered under, and a
    transition whose `target` property says something else than its `_target`."""
    statechart = chart("""
statechart:
  name: renamed
  root state:
    name: root
    initial: a
    states:
    - name: a
      on entry: x = 1
      transitions:
      - {target: b, event: e}
    - name: b
      transitions:
      - {target: a, event: e}
""")
    statechart.state_for("b")._name = "B"  # as a state renamed after it was registered
    original = statechart.transitions_from("a")[0]
    statechart._transitions.remove(original)
    statechart.add_transition(_RenamingTransition("a", "a", event="e"))  # really a -> b
    return statechart


def _record_renamed(klass) -> list:
    statechart = _renamed_chart()
    interp = klass(statechart)
    records: list = []
    interp.attach(lambda meta: records.append(repr(meta)))
    for _ in range(4):
        try:
            records.append(harness.describe_step(statechart, interp.execute_once()))
        except Exception as e:  # noqa: BLE001 - the error itself is what is compared
            records.append((type(e).__name__, str(e)))
        records.append(
            (sorted(interp._configuration), interp._entry_time, interp._idle_time)
        )
        interp.queue("e")
    return records


def test_states_and_transitions_are_read_through_their_properties_when_they_differ():
    """States and transitions are known by their `name`, `source` and `target` properties, as
    stock knows them, also where these say something else than what the chart registered."""
    expected = _record_renamed(Interpreter)
    assert "B" in expected[-1][0]  # the renamed state entered under its new name, as stock does
    assert _record_renamed(FastInterpreter) == expected
