"""The managed system's modes chart: what it writes in the trace, that a failing step leaves no
mode vouched for, and that in the loop its timers fire on the loop's clock."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.knowledge import KnowledgeBase
from rasm.platform.modes import ManagedSystemModes, ModesRunner, mode_signals
from rasm.platform.scheduler import Scheduler
from rasm.statechart import SimulatedClock, load_statechart

DOCK = """statechart:
  name: dock
  root state:
    name: robot
    initial: driving
    states:
      - name: driving
        transitions:
          - target: docking
            event: record
            guard: event.data.get('dock') is True
      - name: docking
        initial: approaching
        transitions:
          - target: driving
            event: record
            guard: event.data.get('dock') is False
        states:
          - name: approaching
            transitions:
              - target: charging
                event: record
                guard: event.data.get('contact') is True and 1 / event.data.get('volts', 1) > 0
          - name: charging
"""

RECORDS = st.lists(
    st.fixed_dictionaries(
        {}, optional={"dock": st.booleans(), "contact": st.booleans(), "volts": st.just(0)}
    ),
    max_size=30,
)


def modes() -> ManagedSystemModes:
    return ManagedSystemModes(load_statechart(text=DOCK), KnowledgeBase())


@pytest.mark.slow
@given(RECORDS)
def test_the_trace_records_follow_the_active_states(records):
    """For any records, replaying the mode_<state> keys of the change records gives the
    chart's active states, and `mode` names its active leaves."""
    chart = modes()
    first = chart.start(0.0)
    assert set(first) == set(mode_signals(chart.chart))  # every state has a value at once
    seen = {key: value for key, value in first.items() if key.startswith("mode_")}
    for i, record in enumerate(records):
        change = chart.observe(float(i + 1), record)
        if change is None:
            continue
        seen.update({k: v for k, v in change.items() if k.startswith("mode_")})
        assert change["mode"] == ",".join(chart.leaves)
    active = {key.removeprefix("mode_") for key, value in seen.items() if value}
    assert active == set(chart.active)


def test_a_failing_step_leaves_no_mode_vouched_for_until_a_record_goes_through():
    chart = modes()
    chart.start(0.0)
    assert chart.observe(1.0, {"dock": True}) == {
        "mode": "approaching", "mode_approaching": True, "mode_docking": True,
        "mode_driving": False,
    }
    assert chart.observe(2.0, {"contact": True, "volts": 0}) is None  # 1 / 0 in the guard
    assert chart.failing and chart.failures == 1
    assert chart.active == {"docking", "approaching"}  # rolled back: as before the record
    chart.observe(3.0, {"contact": True})
    assert not chart.failing and "charging" in chart.active


TIMED = """statechart:
  name: lidar
  root state:
    name: lidar
    initial: fresh
    states:
      - name: fresh
        transitions:
          - target: stale
            guard: after(2.0)
          - target: fresh
            event: record
            guard: event.data.get('scan') is True
      - name: stale
        transitions:
          - target: fresh
            event: record
            guard: event.data.get('scan') is True
"""


def runner(kb: KnowledgeBase, records: list, refused: list) -> tuple[ModesRunner, Scheduler]:
    """The timed chart in a real loop: a scheduler on a simulated clock, real knowledge."""
    clock = SimulatedClock()
    scheduler = Scheduler(clock)
    run = ModesRunner(
        ManagedSystemModes(load_statechart(text=TIMED), kb),
        register_values=kb.register_values,
        refused=lambda key, value, exc: refused.append((key, value)),
        emit=lambda time, record: records.append((time, record)),
        at=scheduler.at,
        clock=clock,
    )
    return run, scheduler


def test_a_timer_of_the_modes_chart_fires_on_the_loops_clock_without_a_record():
    kb, records, refused = KnowledgeBase(), [], []
    run, scheduler = runner(kb, records, refused)
    run.start(0.0)
    assert records == [(0.0, {"mode": "fresh", "mode_fresh": True, "mode_stale": False})]
    assert kb.read_knowledge("mode") == "fresh" and run.mode == {"fresh"}
    scheduler.run_until(5.0)  # no record at all: the timer alone leaves `fresh`
    assert records[1:] == [(2.0, {"mode": "stale", "mode_stale": True, "mode_fresh": False})]
    assert kb.read_knowledge("mode") == "stale" and refused == []


def test_a_record_steps_the_chart_and_rearms_its_timer_from_there():
    kb, records, refused = KnowledgeBase(), [], []
    run, scheduler = runner(kb, records, refused)
    run.start(0.0)
    scheduler.run_until(1.5)
    assert run.observe(1.5, {"scan": True}) is None  # fresh again: no change to record
    scheduler.run_until(5.0)
    # the timer counts from the re-entry at 1.5; the one armed for 2.0 finds nothing to do
    assert [(t, r["mode"]) for t, r in records] == [(0.0, "fresh"), (3.5, "stale")]
    scheduler.run_until(6.0)
    change = run.observe(6.0, {"scan": True})
    assert change == {"mode": "fresh", "mode_fresh": True, "mode_stale": False}
    assert kb.read_knowledge("mode") == "fresh"
    assert len(records) == 2  # the change goes in the record that caused it, not one of its own


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 10**7).map(lambda k: k / 10))  # a 10 Hz record, up to about 12 days
def test_the_timer_fires_at_its_deadline_whatever_the_time_of_the_record(time):
    # re-entered at 7.7, after(2.0) holds at 9.7: the wake the runner arms finds it holding
    kb, records, refused = KnowledgeBase(), [], []
    run, scheduler = runner(kb, records, refused)
    run.start(0.0)
    scheduler.run_until(time)
    run.observe(time, {"scan": True})
    records.clear()
    scheduler.run_until(time + 5.0)
    assert [(t, r["mode"]) for t, r in records] == [(float(f"{time + 2.0:.1f}"), "stale")]


def test_a_mode_knowledge_refuses_is_reported_not_stored():
    kb, records, refused = KnowledgeBase(), [], []
    kb.declare("mode", "int")
    run, _ = runner(kb, records, refused)
    run.start(0.0)
    assert refused == [("mode", "fresh")] and kb.read_knowledge("mode") is None
    assert records[0][1]["mode"] == "fresh"
