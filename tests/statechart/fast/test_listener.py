"""PropertyListener: a property statechart executed only when it can react, with the same
results as stock sismic (the platform's monitors, guards over context names, listeners attached
mid-step)."""

from __future__ import annotations

import pytest
from sismic.exceptions import PropertyStatechartError
from sismic.interpreter import Interpreter
from sismic.io import import_from_yaml
from sismic.model import Event

from rasm.statechart.fast import FastInterpreter, PropertyListener
from tests.statechart.fast import harness
from tests.statechart.fast.charts import MONITORS, STATECHARTS, chart, cycle, never_b_twice

PROPERTY = never_b_twice()
CYCLE = cycle()


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
    orchestrator = import_from_yaml(filepath=str(STATECHARTS / "adaptation_orchestrator.yaml"))
    prop = import_from_yaml(filepath=str(monitor))
    # (steps of 1/8 s: stock's binary arithmetic is exact there, see test_differential)
    script = [(0.125, name, {}) for name in SETUP]
    for round_ in range(4):
        script += [(0.125, name, {}) for name in LOOP]
        script += [(0.125, "tick", {}), (0.125, "monitored", {}), (2.0 + round_, "anomaly", {})]
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
    script = [(0.125, "n", {}) for _ in range(4)]
    expected = harness.run(Interpreter, NESTED, script, prop=REBINDING_ITSELF)
    assert harness.run(FastInterpreter, NESTED, script, prop=REBINDING_ITSELF) == expected
