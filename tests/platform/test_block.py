"""A building block: its chart's states reach its hooks, its timers are asked for once, and a
chart file is loaded once per content."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sismic.clock import SimulatedClock

from rasm.platform.block import Block, shared_chart

CHART = """\
statechart:
  name: dispatch
  root state:
    name: lifecycle
    initial: instantiated
    states:
      - name: instantiated
        transitions:
          - target: outer
            event: go
            action: send('first', n=1)
      - name: outer
        initial: inner
        on entry: send('entering_outer')
        transitions:
          - target: instantiated
            event: back
        states:
          - name: inner
            on entry: send('entering_inner', depth=2)
            transitions:
              - target: last
                action: send('second')
          - name: last
"""


class Journal(Block):
    """Notes every state entered (an ``on_enter_<state>`` hook for any state) and every event
    its chart sends."""

    def __init__(self, chart: Path) -> None:
        self.journal: list[tuple[str, Any]] = []
        super().__init__("journal", chart=chart)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("on_enter_"):
            return lambda: self.journal.append(("enter", name[len("on_enter_") :]))
        raise AttributeError(name)

    def on_event_sent(self, name: str, data: dict[str, Any]) -> None:
        self.journal.append(("sent", (name, data)))


class Quiet(Block):
    """Same state names, no hooks: another class's hooks must not leak into it."""


@pytest.fixture
def chart(tmp_path: Path) -> Path:
    path = tmp_path / "dispatch.yaml"
    path.write_text(CHART)
    return path


def expected(steps: list[Any]) -> list[tuple[str, Any]]:
    """What the hooks should see: each macro step's entered states, then its sent events."""
    out: list[tuple[str, Any]] = []
    for step in steps:
        out.extend(("enter", state) for state in step.entered_states)
        out.extend(("sent", (e.name, dict(e.data))) for e in step.sent_events)
    return out


def test_hooks_see_entered_states_then_sent_events_in_macro_step_order(chart: Path) -> None:
    block = Journal(chart)
    block.journal.clear()
    steps = block.send("go")
    # several macro steps (the internal events are steps of their own), the first entering
    # outer and inner and sending events in more than one micro step
    assert len(steps) > 2 and len(steps[0].steps) > 1 and len(steps[0].entered_states) > 1
    assert len(steps[0].sent_events) > 1
    assert block.journal == expected(steps)
    assert ("sent", ("entering_inner", {"depth": 2})) in block.journal


def test_a_hook_set_on_the_instance_later_is_called(chart: Path) -> None:
    block = Journal(chart)
    block.send("go")
    block.send("back")
    calls: list[str] = []
    block.on_enter_last = lambda: calls.append("last")  # type: ignore[attr-defined]
    block.on_enter_inner = lambda: calls.append("instance inner")  # type: ignore[method-assign]
    block.send("go")
    assert calls == ["instance inner", "last"]
    quiet = Quiet("quiet", chart=chart)
    quiet.send("go")
    assert quiet.configuration == ["lifecycle", "outer", "last"]
    assert calls == ["instance inner", "last"]


TIMED = """\
statechart:
  name: timed
  root state:
    name: root
    initial: resting
    states:
      - name: resting
        transitions:
          - target: waiting
            event: go
      - name: waiting
        transitions:
          - target: resting
            guard: after(2)
          - target: waiting
            event: again
          - target: resting
            event: stop
"""


def test_deadlines_are_asked_for_once_each_and_never_in_the_past(tmp_path: Path) -> None:
    chart = tmp_path / "timed.yaml"
    chart.write_text(TIMED)
    clock = SimulatedClock()
    block = Block("timed", chart=chart, clock=clock)
    asked: list[float] = []
    block.on_deadline = lambda b, due: asked.append(due)
    block.send("stop")  # no timer in `resting`
    assert asked == []
    clock.time = 1.0
    block.send("go")
    assert asked == [3.0]
    block.send(None)  # the same timer: not asked for again
    assert asked == [3.0]
    clock.time = 1.5
    block.send("again")  # re-entered: a later timer, covered by the wake-up at 3.0
    assert asked == [3.0]
    clock.time = 3.0
    block.wake()  # too early for the 3.5 timer, which is asked for now
    assert block.configuration == ["root", "waiting"] and asked == [3.0, 3.5]
    clock.time = 3.5
    block.wake()
    assert block.configuration == ["root", "resting"] and asked == [3.0, 3.5]


@settings(max_examples=200, deadline=None)
@given(
    entry=st.integers(0, 2**21 * 10**5).map(lambda k: k / 10**5),  # up to five decimals
    delay=st.sampled_from([0.1, 0.3, 0.7, 1.1, 2, 2.5, 9.99]),
)
def test_a_wake_at_the_deadline_the_block_asked_for_fires_its_timer(tmp_path_factory, entry,
                                                                      delay):
    # whatever the entry time: entered at 7.7, after(2) holds at 9.7 (not in binary arithmetic,
    # where the wake would find nothing to do and no later one would be asked for)
    chart = tmp_path_factory.getbasetemp() / "timed_delay.yaml"
    chart.write_text(TIMED.replace("after(2)", f"after({delay})"))
    clock = SimulatedClock()
    block = Block("timed", chart=chart, clock=clock)
    asked: list[float] = []
    block.on_deadline = lambda b, due: asked.append(due)
    clock.time = entry
    block.send("go")
    assert asked == [float(f"{entry + delay:.5f}")]  # the decimal entry + delay
    clock.time = asked[0]
    block.wake()
    assert block.configuration == ["root", "resting"]


def test_a_chart_file_is_loaded_once_and_again_when_its_bytes_change(tmp_path):
    text = """\
statechart:
  name: toggle
  root state:
    name: root
    initial: off
    states:
      - name: off
        transitions: [{target: on, event: flip}]
      - name: on
        transitions: [{target: off, event: flip}]
"""
    path = tmp_path / "toggle.yaml"
    path.write_text(text, encoding="utf-8")
    first = shared_chart(path)
    assert shared_chart(path) is first  # shared: blocks never change a chart
    # same length, rewritten at once (the modification time may not move): loaded again
    path.write_text(text.replace("initial: off", "initial: on "), encoding="utf-8")
    changed = shared_chart(path)
    assert changed is not first
    assert changed.state_for("root").initial == "on"
    assert first.state_for("root").initial == "off"
