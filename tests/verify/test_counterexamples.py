"""Planted bugs that only long, exact sequences reach: rasm verify finds each with a shortest
counterexample, and the counterexample replays, with rasm simulate and on stock sismic."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from sismic.clock import SimulatedClock
from sismic.interpreter import Interpreter as StockInterpreter
from sismic.model import Event

from rasm.cli import main
from rasm.statechart import load_statechart
from rasm.statechart.simulate import read_events, simulate
from rasm.verify import verify_chart

# a combination lock: the alarm needs the seven digits in order, each within 2 s of the last
# (a timer resets the entry), then the door held open 3 s: ten moves at least
LOCK = """
statechart:
  name: lock
  preamble: |
    code = [3, 1, 4, 1, 5, 9, 2]
    got = 0
  root state:
    name: root
    initial: closed
    states:
      - name: closed
        transitions:
          - event: key
            guard: got < 7 and event.data['digit'] == code[got]
            action: |
              got += 1
          - event: key
            guard: got < 7 and event.data['digit'] != code[got]
            action: |
              got = 0
          - target: unlocked
            guard: got == 7
          - guard: got > 0 and idle(2)
            action: |
              got = 0
      - name: unlocked
        transitions:
          - target: open
            event: push
          - target: closed
            guard: after(1)
            action: |
              got = 0
      - name: open
        transitions:
          - target: alarm
            guard: after(3)
          - target: closed
            event: pull
            action: |
              got = 0
      - name: alarm
        transitions:
          - target: closed
            event: reset
            action: |
              got = 0
"""

ENV = """
events:
  - name: key
    data: {digit: [1, 2, 3, 4, 5, 9]}
  - push
  - pull
  - reset
clock: [0.5, 1]
"""


@pytest.fixture
def lock(tmp_path: Path) -> tuple[Path, Path, Path]:
    chart = tmp_path / "lock.yaml"
    chart.write_text(LOCK)
    env = tmp_path / "env.yaml"
    env.write_text(ENV)
    props = tmp_path / "lock.rv"
    props.write_text('property no_alarm: always not in_state("alarm")\n')
    return chart, env, props


def _stock_configurations(chart: Path, cex: list[dict]) -> list[list[str]]:
    """Replay the events on stock sismic, driven as rasm simulate drives a chart."""
    statechart = load_statechart(chart)
    clock = SimulatedClock()
    interp = StockInterpreter(statechart, clock=clock)
    seen = [sorted(interp.configuration) for _ in interp.execute()]
    for line in cex:
        clock.time = max(clock.time, line["time"])
        if "event" in line:
            interp.queue(Event(line["event"], **line.get("data", {})))
        seen += [sorted(interp.configuration) for _ in interp.execute()]
    return seen


def test_a_bug_ten_moves_deep_is_found_with_a_shortest_replayable_counterexample(lock, tmp_path):
    chart, env, props = lock
    result = verify_chart(chart, environment=env, properties=props)
    assert result.complete
    (prop,) = result.properties
    assert prop.verdict == "violated"
    cex = prop.counterexample.events()
    keys = [line for line in cex if line.get("event") == "key"]
    assert [line["data"]["digit"] for line in keys] == [3, 1, 4, 1, 5, 9, 2]
    # seven keys, the push, and 3 s of clock in the fewest advances (1 s steps): 11 moves
    assert len(cex) == 11
    assert cex[-1] == {"time": 3} or cex[-1]["time"] == 3
    # written as rasm simulate's events, it replays there and on stock sismic
    events = tmp_path / "cex.jsonl"
    events.write_text(prop.counterexample.jsonl())
    steps = simulate(chart, read_events(events))
    assert steps[-1].configuration == ["alarm", "root"]
    assert _stock_configurations(chart, cex)[-1] == ["alarm", "root"]
    assert "in_state(\"alarm\") is true" in "\n".join(prop.counterexample.explanation)


def test_rasm_verify_writes_the_counterexample_and_exits_1(lock, tmp_path, capsys):
    chart, env, props = lock
    out = tmp_path / "cex"
    code = main(["verify", str(chart), "--env", str(env), "--properties", str(props),
                 "--counterexamples", str(out), "--format", "json"])
    assert code == 1
    report = json.loads(capsys.readouterr().out)
    assert report["verdict"] == "violated" and report["complete"] is True
    (prop,) = report["properties"]
    lines = (out / "property-no_alarm.jsonl").read_text().splitlines()
    written = [json.loads(line) for line in lines]
    assert written == prop["counterexample"]
    assert main(["simulate", str(chart), "--events", str(out / "property-no_alarm.jsonl"),
                 "--format", "json"]) == 0
    last = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert last["configuration"] == ["alarm", "root"]


RAISING = """
statechart:
  name: raising
  preamble: |
    n = 0
  root state:
    name: root
    initial: a
    states:
      - name: a
        transitions:
          - target: b
            event: go
            action: |
              n = min(n + 1, 5)
      - name: b
        transitions:
          - target: a
            event: back
          - target: c
            event: go
            guard: n == 3
            action: |
              ratio = 1 / (n - 3)
      - name: c
      - name: never
"""

STUCK = """
statechart:
  name: stuck
  root state:
    name: root
    initial: idle
    states:
      - name: idle
        transitions:
          - target: waiting
            event: start
      - name: waiting
        transitions:
          - target: idle
            guard: after(2) and False
      - name: done
        type: final
"""


def test_a_stable_state_with_no_way_out_is_stuck_and_a_final_one_is_not(tmp_path):
    chart = tmp_path / "stuck.yaml"
    chart.write_text(STUCK)
    result = verify_chart(chart)
    stuck = [f for f in result.problems if f.kind == "stuck"]
    assert [f.message for f in stuck] == [
        "stuck in root, waiting: every event is ignored and no timer is pending"
    ]
    # (until 2 s a timer is pending: its guard is only known false once after(2) holds)
    assert stuck[0].counterexample.events() == [{"time": 0, "event": "start"}, {"time": 2}]


def test_built_in_problems_each_with_its_counterexample(tmp_path):
    chart = tmp_path / "raising.yaml"
    chart.write_text(RAISING)
    result = verify_chart(chart)
    kinds = {f.kind: f for f in result.problems}
    assert set(kinds) == {"raising code", "unreachable"}
    raising = kinds["raising code"].counterexample.events()
    assert [line["event"] for line in raising] == ["go", "back", "go", "back", "go", "go"]
    assert "division by zero" in kinds["raising code"].message
    # c is entered on no path: the only step into it raises, and is rolled back
    assert result.complete and result.unreachable == ["c", "never"]
    assert result.exit_code == 1
