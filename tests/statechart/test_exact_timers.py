"""Exact timers: ``after()``, ``idle()`` and delayed events fire at their deadline, whatever the
entry time, on rasm's interpreter and on the fast one.

Stock sismic compares ``time - seconds >= entry`` in binary floating point: entered at 7.7,
``after(2)`` is false at 9.7. rasm compares the decimals the times stand for, in integer
nanoseconds (:mod:`rasm.statechart.timers`); that is its one departure from stock's semantics.
"""

from __future__ import annotations

import json
from decimal import Decimal

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sismic.clock import SimulatedClock
from sismic.interpreter import Interpreter as StockInterpreter

from rasm.cli import main
from rasm.statechart import Interpreter, load_statechart
from rasm.statechart.fast import FastInterpreter
from rasm.statechart.simulate import TimedEvent, format_steps, simulate
from rasm.statechart.timers import deadline, elapsed

CHART = """\
statechart:
  name: timers
  preamble: |
    setdefault('d', 2)
  root state:
    name: root
    initial: off
    states:
      - name: off
        transitions:
          - {target: after, event: after}
          - {target: idle, event: idle}
          - {target: delayed, event: delayed}
      - name: after
        transitions:
          - {target: done, guard: after(d)}
      - name: idle
        transitions:
          - {event: poke}
          - {target: done, guard: idle(d)}
      - name: delayed
        on entry: |
          send('tick', delay=d)
        transitions:
          - {target: done, event: tick}
      - name: done
"""
STATECHART = load_statechart(text=CHART)
LIMIT = 2**21 * 10**9  # ns: below about 24 days a float holds any time with nine decimals


def seconds(ns: int) -> float:
    """The float a user writing ``ns`` nanoseconds as a decimal number of seconds gets."""
    return float(f"{Decimal(ns).scaleb(-9):f}")


@st.composite
def nine_decimals(draw, low: int, high: int) -> int:
    """A time in nanoseconds, written with 0 to 9 decimals."""
    scale = 10 ** (9 - draw(st.integers(0, 9)))
    return max(low, draw(st.integers(low, high)) // scale * scale)


def state(interp) -> str:
    (leaf,) = set(interp.configuration) - {"root"}
    return leaf


@pytest.mark.parametrize("klass", [Interpreter, FastInterpreter])
@settings(max_examples=300, deadline=None)
@given(
    entry=nine_decimals(0, LIMIT),
    delay=nine_decimals(1, 10_000 * 10**9),
    poked=nine_decimals(0, 10_000 * 10**9),
    timer=st.sampled_from(["after", "idle", "delayed"]),
)
def test_a_timer_fires_exactly_at_entry_plus_delay(klass, entry, delay, poked, timer):
    clock = SimulatedClock()
    interp = klass(STATECHART, clock=clock, initial_context={"d": seconds(delay)})
    interp.execute()
    clock.time = seconds(entry)
    interp.queue(timer).execute()
    assert state(interp) == timer
    start = entry
    if timer == "idle":  # an internal transition before the deadline restarts idle()
        start = entry + min(poked, delay - 1)
        clock.time = seconds(start)
        interp.queue("poke").execute()
        assert state(interp) == timer
    if klass is Interpreter:
        assert interp.next_deadline() == seconds(start + delay)
    clock.time = seconds(start + delay - 1)  # a nanosecond early
    interp.execute()
    assert state(interp) == timer
    clock.time = seconds(start + delay)
    interp.execute()
    assert state(interp) == "done"


def test_entered_at_7_7_after_2_holds_at_9_7_where_stock_sismic_misses_it():
    def run(klass) -> str:
        clock = SimulatedClock()
        interp = klass(STATECHART, clock=clock)
        interp.execute()
        clock.time = 7.7
        interp.queue("after").execute()
        clock.time = 9.7
        interp.execute()
        return state(interp)

    assert run(StockInterpreter) == "after"  # 9.7 - 2 is 7.699999999999999 < 7.7
    assert run(FastInterpreter) == run(Interpreter) == "done"


def test_a_clock_moved_in_float_sums_keeps_its_decimal_time():
    # 0.1 + 0.2 is 0.30000000000000004: the interpreter's time is the float of "0.3"
    clock = SimulatedClock()
    interp = Interpreter(STATECHART, clock=clock, initial_context={"d": 0.2})
    interp.execute()
    clock.time = 0.1
    interp.queue("delayed").execute()
    clock.time = 0.1 + 0.2
    (step,) = interp.execute()
    assert step.time == 0.3 and state(interp) == "done"


@pytest.mark.parametrize(
    ("since", "now", "delay", "expected"),
    [(7.7, 9.7, 2, True), (7.7, 9.699999999, 2, False), (0, 1, float("inf"), False),
     (0, 1, float("nan"), False), (1, 1, 0, True), (0.1, 0.3, 0.2, True)],
)
def test_elapsed_is_exact_and_stock_where_the_delay_is_no_finite_number(since, now, delay,
                                                                          expected):
    assert elapsed(since, now, delay) is expected


def test_a_delay_that_is_no_number_fails_as_stock_does():
    with pytest.raises(TypeError, match="unsupported operand"):
        elapsed(0.0, 1.0, "2")
    with pytest.raises(TypeError, match="unsupported operand"):
        deadline(0.0, "2")


@settings(max_examples=200, deadline=None)
@given(
    since=nine_decimals(0, 10**18),
    delay=nine_decimals(1, 10**12),
)
def test_a_deadline_is_never_early_beyond_the_floats_precision(since, delay):
    # epoch-like times: floats are coarser than a nanosecond, so the deadline is the first float
    # at which the timer holds; a runner waking the chart there finds it holding
    start = seconds(since)
    due = deadline(start, seconds(delay))
    assert elapsed(start, due, seconds(delay))


def test_simulate_fires_a_timer_at_its_deadline_on_a_line_that_only_moves_the_clock(
    tmp_path, capsys
):
    chart = tmp_path / "timers.yaml"
    chart.write_text(CHART)
    events = tmp_path / "events.jsonl"
    events.write_text('{"time": 7.7, "event": "after"}\n{"time": 9.7}\n')
    assert main(["simulate", str(chart), "--events", str(events), "--format", "json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(s["time"], s["event"], s["entered"]) for s in lines] == [
        (0, None, ["root", "off"]), (7.7, "after", ["after"]), (9.7, None, ["done"]),
    ]
    assert main(["simulate", str(chart), "--events", str(events)]) == 0
    assert "       9.7  (no event)            done, root" in capsys.readouterr().out


def test_a_line_that_only_moves_the_clock_carries_no_data(tmp_path, capsys):
    chart = tmp_path / "timers.yaml"
    chart.write_text(CHART)
    events = tmp_path / "events.jsonl"
    events.write_text('{"time": 1, "event": "after"}\n{"time": 2, "data": {"v": 1}}\n')
    assert main(["simulate", str(chart), "--events", str(events)]) == 2
    err = capsys.readouterr().err
    assert f"{events}:2:1: " in err and '"data" belongs to an event' in err
    assert "Traceback" not in err


def test_simulate_writes_times_as_their_decimals():
    steps = simulate(STATECHART, [TimedEvent(1234567.125, "delayed"), TimedEvent(1234569.5, None)])
    assert [(step.time, step.event) for step in steps] == [
        (0, None), (1234567.125, "delayed"), (1234569.5, "tick"),
    ]
    text = format_steps(steps)
    assert " 1234569.5  tick" in text and "e+06" not in text  # not :g's 1.23457e+06


CONTRACT = """\
statechart:
  name: contract
  root state:
    name: root
    initial: off
    states:
      - name: off
        transitions:
          - {target: on, event: go}
      - name: on
        contract:
          - always: not after(2)
        transitions:
          - {event: poke}
"""


@pytest.mark.parametrize("klass", [Interpreter, FastInterpreter])
def test_after_in_a_contract_is_exact_too(klass):
    clock = SimulatedClock()
    interp = klass(load_statechart(text=CONTRACT), clock=clock)
    interp.execute()
    clock.time = 7.7
    interp.queue("go").execute()
    clock.time = 9.699999999
    interp.queue("poke").execute()  # the invariant holds a nanosecond before
    clock.time = 9.7
    with pytest.raises(Exception, match="not after\\(2\\)"):
        interp.queue("poke").execute()
