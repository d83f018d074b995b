"""Targeted checks of FastInterpreter: errors, shipped charts, property wake-ups, copies."""

from __future__ import annotations

import copy
import pickle
from pathlib import Path

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

from rasm.statechart.fast import FastInterpreter, PropertyListener
from tests.statechart_fast import harness

CHARTS = Path(__file__).resolve().parents[2] / "statecharts"


def chart(text: str):
    return import_from_yaml(text)


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

PROPERTY = chart("""
statechart:
  name: never b twice
  root state:
    name: root
    initial: idle
    states:
    - name: idle
      transitions:
      - {target: seen, event: state entered, guard: event.state == 'b'}
    - name: seen
      transitions:
      - {target: fail, event: state entered, guard: event.state == 'b'}
      - {target: idle, event: state entered, guard: event.state == 'c'}
    - name: fail
      type: final
""")


CYCLE = chart("""
statechart:
  name: cycle
  root state:
    name: root
    initial: a
    states:
    - name: a
      transitions:
      - {target: b, event: n}
    - name: b
      transitions:
      - {target: c, event: n}
    - name: c
      transitions:
      - {target: a, event: n}
""")


TOGGLE = chart("""
statechart:
  name: toggle
  root state:
    name: root
    initial: a
    states:
    - name: a
      transitions:
      - {target: b, event: n}
    - name: b
      transitions:
      - {target: a, event: n}
""")


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


@pytest.mark.skipif(not CHARTS.is_dir(), reason="no shipped statecharts")
@pytest.mark.parametrize("path", sorted(CHARTS.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_charts_run_identically(path):
    statechart = import_from_yaml(filepath=str(path))
    names = statechart.events_for() + ["unknown"]
    script = [(0.5 * (i % 3), names[(i * 7) % len(names)], {}) for i in range(60)]
    expected = harness.run(Interpreter, statechart, script)
    assert harness.run(FastInterpreter, statechart, script) == expected


def test_property_statechart_is_woken_only_when_it_can_react():
    delivered: list[str] = []

    class Counting(FastInterpreter):
        def queue(self, event, *events, **parameters):
            delivered.append(event.name)
            return super().queue(event, *events, **parameters)

    interp = FastInterpreter(CYCLE)
    listener = interp.bind_property_statechart(PROPERTY, interpreter_klass=Counting)
    assert isinstance(listener, PropertyListener)
    interp.execute()
    for _ in range(2):
        interp.queue("n")
        interp.execute()
    # Stock delivers every meta-event (step started/ended, event consumed, state exited/entered,
    # transition processed): about 20 here. The first delivery initialises the property; after
    # that it is executed only for the entries its guards accept: b (idle -> seen), then c
    # (seen -> idle), not for those of root, a (guards false) nor any other meta-event. Time
    # never advances, so no extra wake-up.
    assert delivered == ["step started", "state entered", "state entered"]
    assert listener.interpreter.configuration == ["root", "idle"]


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


MONITORS = Path(__file__).resolve().parents[2] / "monitors"
SETUP = ["configure", "configuration_done", "initialization_done"]
# adaptations, a replan, a rejection limit, quiet iterations, a failed stage, a tick while busy
LOOP = [
    "tick", "monitored", "anomaly", "planned", "accepted", "executed",
    "tick", "monitored", "no_anomaly",
    "tick", "monitored", "anomaly", "planned", "rejected", "planned", "accepted", "tick",
    "executed",
    "tick", "monitored", "anomaly", "planned", "rejected", "planned", "rejected", "planned",
    "rejected",
    "tick", "stage_failed", "tick", "monitored", "anomaly", "no_plan",
]


@pytest.mark.parametrize("monitor", sorted(MONITORS.glob("*.yaml")), ids=lambda p: p.stem)
def test_the_platform_monitors_watch_the_orchestrator_identically(monitor):
    # The orchestrator's MAPLE-K loop with one of the property statecharts the platform binds to
    # it, also through stage timeouts (the clock jumps past the stage budget mid-iteration):
    # here the listener decides most meta-events from the guards alone.
    orchestrator = import_from_yaml(filepath=str(CHARTS / "adaptation_orchestrator.yaml"))
    prop = import_from_yaml(filepath=str(monitor))
    script = [(0.1, name, {}) for name in SETUP]
    for round_ in range(4):
        script += [(0.1, name, {}) for name in LOOP]
        script += [(0.1, "tick", {}), (0.1, "monitored", {}), (2.0 + round_, "anomaly", {})]
    expected = harness.run(Interpreter, orchestrator, script, prop=prop)
    assert harness.run(FastInterpreter, orchestrator, script, prop=prop) == expected



WATCHING_NAMES = chart("""
statechart:
  name: entries named in NAMES
  preamble: NAMES = ('b',)
  root state:
    name: root
    initial: idle
    states:
    - name: idle
      transitions:
      - {target: seen, event: state entered, guard: event.state in NAMES}
    - name: seen
      transitions:
      - {target: idle, event: state entered, guard: event.state not in NAMES}
""")


def _watch_names(klass, rebind: bool) -> list[tuple[str, float]]:
    interp = klass(CYCLE)
    watcher = interp.bind_property_statechart(WATCHING_NAMES)._interpreter
    interp.execute()
    seen = []
    for step, names in enumerate([None, None, ("a",), None, ("c",), None, ("b", "c"), None]):
        if rebind and names is not None:
            watcher.context["NAMES"] = names
        interp.clock.time += step % 2
        interp.queue("n")
        interp.execute()
        seen.append((watcher.configuration[-1], watcher.time))
    return seen


def test_a_context_name_rebound_between_steps_is_seen_by_the_next_step():
    # The listener decides guards over NAMES from NAMES as it was bound when first read:
    # rebinding NAMES from outside between two steps must count.
    expected = _watch_names(Interpreter, rebind=True)
    assert expected != _watch_names(Interpreter, rebind=False)  # the rebinding matters
    assert _watch_names(FastInterpreter, rebind=True) == expected


ARMED_BY_EXIT = chart("""
statechart:
  name: armed when a is left, then b must not be named in NAMES
  preamble: NAMES = ('x',)
  root state:
    name: root
    initial: watching
    states:
    - name: watching
      transitions:
      - {target: armed, event: state exited, guard: event.state == 'a'}
    - name: armed
      transitions:
      - {target: watching, event: state entered, guard: event.state not in NAMES}
      - {target: named, event: state entered, guard: event.state in NAMES}
    - name: named
      type: final
""")


def _armed_by_exit(klass) -> list[tuple[str, float] | str]:
    interp = klass(CYCLE)
    watcher = interp.bind_property_statechart(ARMED_BY_EXIT)._interpreter
    interp.execute()
    seen: list[tuple[str, float] | str] = []
    for step in range(12):
        if step == 9:  # after three a -> b steps decided with NAMES = ('x',): now it names b
            watcher.context["NAMES"] = ("b",)
        interp.clock.time += 1
        interp.queue("n")
        try:
            interp.execute()
        except PropertyStatechartError:
            seen.append("failed")
            break
        seen.append((watcher.configuration[-1], watcher.time))
    return seen


def test_decided_guards_read_the_names_the_states_they_reach_read():
    # Leaving `a` moves the property to `armed`, whose guards read NAMES. Rebound between steps,
    # NAMES must be read anew there, not decided as it was when first read.
    expected = _armed_by_exit(Interpreter)
    assert expected[-1] == "failed"
    assert _armed_by_exit(FastInterpreter) == expected


TOGGLE_ATTACHING = chart("""
statechart:
  name: toggle that attaches a listener when told to
  preamble: |
    later = None
  root state:
    name: root
    initial: a
    states:
    - name: a
      transitions:
      - target: b
        event: n
        action: |
          if later is not None:
              attach(later)
              later = None
    - name: b
      transitions:
      - {target: a, event: n}
""")

ENTERING_B = chart("""
statechart:
  name: counts nothing, watches b entered
  root state:
    name: root
    initial: watching
    states:
    - name: watching
      transitions:
      - {target: seen, event: state entered, guard: event.state == 'b'}
    - name: seen
      transitions:
      - {target: watching, event: state exited, guard: event.state == 'b'}
""")


def _attached_mid_step(klass) -> list[tuple[str, object]]:
    interp = klass(TOGGLE_ATTACHING)
    interp.bind_property_statechart(ENTERING_B)
    interp.context["attach"] = interp.attach
    heard: list[tuple[str, object]] = []
    interp.execute()
    for step in range(10):
        if step == 8:  # the listeners' group has long been learnt for a -> b
            interp.context["later"] = lambda meta: heard.append((meta.name, dict(meta.data)))
        interp.clock.time += 1
        interp.queue("n")
        interp.execute()
    return heard


def test_a_listener_attached_within_a_step_hears_the_rest_of_it():
    # A listener attached by an action, in the middle of a step, must hear that step's later
    # meta-events, as with stock sismic.
    expected = _attached_mid_step(Interpreter)
    heard = ("transition processed", {"source": "a", "target": "b", "event": Event("n")})
    assert heard in expected  # the recorder heard the rest of the step it was attached in
    assert _attached_mid_step(FastInterpreter) == expected


NESTED = chart("""
statechart:
  name: nested cycle
  root state:
    name: root
    initial: a
    states:
    - name: a
      initial: a1
      transitions: [{target: b, event: n}]
      states: [{name: a1}]
    - name: b
      initial: b1
      transitions: [{target: a, event: n}]
      states: [{name: b1}]
""")

REBINDING_ITSELF = chart("""
statechart:
  name: a property that rebinds the names its guard reads
  preamble: NAMES = ('b1',)
  root state:
    name: root
    initial: watching
    states:
    - name: watching
      transitions:
      - {target: hit, event: state entered, guard: event.state in NAMES}
    - name: hit
      transitions:
      - target: watching
        event: state entered
        guard: event.state == 'a'
        action: NAMES = ('a1',)
""")


def test_a_property_that_rebinds_a_watched_name_is_seen_within_the_same_step():
    # Back in `watching` after rebinding NAMES, the entry of a1 in the same step must be decided
    # with the new NAMES, not with what was decided about `watching` before.
    script = [(0.1, "n", {}) for _ in range(4)]
    expected = harness.run(Interpreter, NESTED, script, prop=REBINDING_ITSELF)
    assert harness.run(FastInterpreter, NESTED, script, prop=REBINDING_ITSELF) == expected


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
