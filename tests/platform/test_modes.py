"""The managed system's modes chart: what it writes in the trace, and that a failing step
leaves no mode vouched for."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from rasm.knowledge import KnowledgeBase
from rasm.platform.modes import ManagedSystemModes, mode_signals
from rasm.statechart import load_statechart

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
