"""The next deadline is known, and the live runner wakes for it without polling."""

from __future__ import annotations

import threading

import pytest
from sismic.clock import SimulatedClock

from rasm.statechart import ChartRunner, Interpreter, MonotonicClock, load_statechart

TIMERS = """
statechart:
  name: timers
  root state:
    name: root
    initial: a
    states:
      - name: a
        transitions:
          - target: b
            guard: after(wait)
          - target: c
            event: poke
            action: send('later', delay=0.75)
      - name: b
        transitions:
          - target: a
            guard: idle(3) and enabled
      - name: c
        transitions:
          - target: a
            event: later
"""


def test_next_deadline_follows_after_idle_and_delayed_events():
    clock = SimulatedClock()
    interp = Interpreter(
        load_statechart(text=TIMERS), clock=clock, initial_context={"wait": 2.0, "enabled": True}
    )
    assert interp.next_deadline() == 0  # not initialised: a step is due now
    interp.execute()
    assert interp.next_deadline() == 2.0
    clock.time = 1.0
    interp.execute()
    assert interp.next_deadline() == 2.0
    clock.time = 2.5
    interp.execute()
    assert interp.configuration == ["root", "b"]
    assert interp.next_deadline() == 5.5  # idle(3) counted from entering b at 2.5
    interp._evaluator._context["enabled"] = False
    clock.time = 6
    interp.execute()
    assert interp.configuration == ["root", "b"]
    # `idle(3) and enabled`: idle is already true, only an event can change `enabled`
    assert interp.next_deadline() is None


def test_next_deadline_includes_delayed_internal_events():
    clock = SimulatedClock()
    interp = Interpreter(
        load_statechart(text=TIMERS), clock=clock, initial_context={"wait": 100.0, "enabled": True}
    )
    interp.execute()
    clock.time = 1.0
    interp.queue("poke")
    interp.execute()
    assert interp.configuration == ["root", "c"]
    assert interp.next_deadline() == 1.75


@pytest.mark.slow
def test_runner_fires_timers_and_events_without_polling():
    interp = Interpreter(
        load_statechart(text=TIMERS),
        clock=MonotonicClock(),
        initial_context={"wait": 0.05, "enabled": False},
    )
    reached_b = threading.Event()
    back_in_a = threading.Event()

    def on_step(step):
        if "b" in step.entered_states:
            reached_b.set()
        if "a" in step.entered_states and reached_b.is_set():
            back_in_a.set()

    runner = ChartRunner(interp, on_step=on_step).start()
    try:
        assert reached_b.wait(5), "the after(0.05) transition never fired"
        # in b, `idle(3) and enabled` is false and nothing is queued: the runner sleeps with
        # no timeout (no polling) until an event arrives, then makes exactly one more pass.
        assert runner.wait_until_idle(5)
        passes = runner.wakeups
        runner.send("poke")  # ignored in b
        assert runner.wait_until_idle(5, after_wakeups=passes)
        assert runner.wakeups == passes + 1
    finally:
        runner.stop()
    assert runner.errors == []
    assert interp.configuration == ["root", "b"]
