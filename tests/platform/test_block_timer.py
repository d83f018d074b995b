"""A block asks to be woken (on_deadline) once per new timer of its chart: not for a chart with no
timer, not again for a timer already asked for, and never for a time already past (a spin)."""

from __future__ import annotations

from pathlib import Path

from sismic.clock import SimulatedClock

from rasm.platform.block import Block

CHART = """\
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
    chart.write_text(CHART)
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
