"""statechart_machine: finds planted bugs with their shortest sequences; no false alarms."""

from __future__ import annotations

import json

import pytest
from hypothesis import Phase, settings
from hypothesis import strategies as st

from rasm.cli import main
from rasm.resources import platform_chart, platform_monitors
from rasm.statechart import load_statechart
from rasm.testing import (
    ChartFailure,
    applicable_monitors,
    statechart_machine,
    watched_states,
)
from rasm.testing.machine import chart_events, timer_delays
from rasm.times import format_seconds

from . import charts

# no explain phase: it re-runs the failure under a tracer, which only slows these tests down
PHASES = [Phase.explicit, Phase.reuse, Phase.generate, Phase.target, Phase.shrink]
# derandomized: the search is the same on every run, so a planted bug is found every time
BUDGET = settings(
    max_examples=200, stateful_step_count=10, deadline=None, database=None, phases=PHASES,
    derandomize=True,
)
# the platform monitors cost a property-chart step per meta-event: a smaller budget
MONITORED = settings(
    max_examples=80, stateful_step_count=8, deadline=None, database=None, phases=PHASES,
    derandomize=True,
)


def run(machine, budget=BUDGET):
    """Run a machine's TestCase as pytest would; return the failure it reports, if any."""
    machine.TestCase.settings = budget
    try:
        machine.TestCase().runTest()
    except ChartFailure as failure:
        return failure
    return None


def write(tmp_path, name, text):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return str(path)


def replay(chart, events_file, capsys):
    """The JSON steps `rasm simulate CHART --events FILE --format json` prints."""
    capsys.readouterr()
    code = main(["simulate", chart, "--events", str(events_file), "--format", "json"])
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    return code, lines


def never_open_and_bolted(state):
    return not {"open", "bolted"} <= state.configuration


def sequence(failure):
    return [e["event"] for e in failure.events]


# --------------------------------------------------------------------------- planted bugs


def test_door_bug_is_found_with_its_two_event_sequence_and_replays(tmp_path, capsys):
    chart = write(tmp_path, "door", charts.DOOR_BUGGY)
    failure = run(statechart_machine(chart, invariant=never_open_and_bolted))
    assert failure is not None, "the explorer missed the planted bug"
    assert sequence(failure) == ["open", "bolt"]
    assert failure.configuration >= {"open", "bolted"}
    # the message lists the sequence and names the events file that replays it
    message = str(failure)
    assert "1. t=0  open" in message and "2. t=0  bolt" in message
    assert f"rasm simulate {chart} --events {failure.saved}" in message
    assert failure.saved.parent.name.startswith("rasm-failures")
    code, steps = replay(chart, failure.saved, capsys)
    assert code == 0
    assert set(steps[-1]["configuration"]) == set(failure.configuration)
    assert [s["event"] for s in steps] == [None, "open", "bolt"]


def test_an_invariant_sees_the_events_sent_as_events_file_lines(tmp_path):
    chart = write(tmp_path, "door", charts.DOOR_FIXED)
    seen = []

    def bolt_is_never_sent(state):
        seen.append(state.events)
        return "bolt" not in [e["event"] for e in state.events]

    failure = run(statechart_machine(chart, invariant=bolt_is_never_sent))
    assert failure is not None and sequence(failure) == ["bolt"]
    # each sent event is a dict with its time and name, in the order sent
    sent = [events for events in seen if events]
    assert sent and all(set(e) >= {"time", "event"} for events in sent for e in events)
    assert all(events[i]["time"] <= events[i + 1]["time"]
               for events in sent for i in range(len(events) - 1))


def test_door_fixed_gives_no_false_alarm(tmp_path):
    chart = write(tmp_path, "door", charts.DOOR_FIXED)
    assert run(statechart_machine(chart, invariant=never_open_and_bolted)) is None


@pytest.mark.slow
def test_safe_back_door_needs_four_events_and_reads_the_context(tmp_path, capsys):
    chart = write(tmp_path, "safe", charts.SAFE_BUGGY)
    failure = run(statechart_machine(chart, invariant=charts.safe_invariant))
    assert failure is not None
    assert sequence(failure) == ["lock", "pull", "pull", "pull"]
    assert "invariant safe_invariant() returned False" in failure.reason
    code, steps = replay(chart, failure.saved, capsys)
    assert steps[-1]["configuration"] == ["open", "safe"]


@pytest.mark.slow
def test_safe_fixed_gives_no_false_alarm(tmp_path):
    chart = write(tmp_path, "safe", charts.SAFE_FIXED)
    assert run(statechart_machine(chart, invariant=charts.safe_invariant)) is None


def test_timer_bug_is_found_by_waiting_and_replays_at_the_same_times(tmp_path, capsys):
    chart = write(tmp_path, "valve", charts.VALVE_BUGGY)
    failure = run(statechart_machine(chart, invariant=lambda s: not s.active("jammed")))
    assert failure is not None
    # open, then any event sent at least `timeout` (4 s) later: the timer fires first
    assert len(failure.events) == 2 and failure.events[0]["event"] == "open"
    assert failure.events[1]["time"] - failure.events[0]["time"] >= 4.0
    code, steps = replay(chart, failure.saved, capsys)
    assert "jammed" in steps[-1]["configuration"]


def test_valve_fixed_gives_no_false_alarm(tmp_path):
    chart = write(tmp_path, "valve", charts.VALVE_FIXED)
    assert run(statechart_machine(chart, invariant=lambda s: not s.active("jammed"))) is None


def test_contract_violation_is_a_failure(tmp_path):
    failure = run(statechart_machine(charts.COUNTER_BUGGY))
    assert failure is not None
    assert "contract" in failure.reason and "count <= 3" in failure.reason
    assert sequence(failure) == ["add"] * 4
    assert failure.configuration == {"counter", "counting"}  # rolled back: last good one


@pytest.mark.slow
def test_contract_holds_on_the_fixed_counter():
    assert run(statechart_machine(charts.COUNTER_FIXED)) is None


def test_platform_monitors_catch_a_loop_that_skips_legitimate(tmp_path, capsys):
    chart = write(tmp_path, "mini_loop", charts.MINI_LOOP_BUGGY)
    failure = run(statechart_machine(chart), MONITORED)
    assert failure is not None
    assert "property statechart" in failure.reason
    assert "accepted_before_executing" in failure.reason
    assert sequence(failure) == ["tick", "monitored", "anomaly", "planned"]
    # the step that broke the monitor was rolled back: the chart still plans
    assert "planning" in failure.configuration
    code, steps = replay(chart, failure.saved, capsys)
    assert "executing" in steps[-1]["configuration"]  # stock replay shows the forbidden entry


def test_the_fixed_loop_satisfies_the_platform_monitors(tmp_path):
    chart = write(tmp_path, "mini_loop", charts.MINI_LOOP_FIXED)
    assert run(statechart_machine(chart), MONITORED) is None


@pytest.mark.slow
def test_no_monitors_when_asked_for_none(tmp_path):
    chart = write(tmp_path, "mini_loop", charts.MINI_LOOP_BUGGY)
    assert run(statechart_machine(chart, monitors=[])) is None


def test_event_data_from_strategies_is_sent_saved_and_replayed(tmp_path, capsys):
    chart = write(tmp_path, "register", charts.REGISTER)
    machine = statechart_machine(
        chart,
        events={"set": st.fixed_dictionaries({"value": st.integers(0, 10)})},
        invariant=lambda s: s.context["value"] != 7,
    )
    failure = run(machine)
    assert failure is not None
    assert failure.events == [{"time": 0.0, "event": "set", "data": {"value": 7}}]
    assert json.loads(failure.saved.read_text()) == failure.events[0]
    code, steps = replay(chart, failure.saved, capsys)
    assert code == 0 and steps[-1]["event"] == "set"


def test_an_invariant_may_assert(tmp_path):
    def invariant(state):
        assert state.context["count"] < 2, f"count is {state.context['count']}"

    failure = run(statechart_machine(charts.COUNTER_FIXED, invariant=invariant))
    assert failure is not None and "count is 2" in failure.reason
    assert sequence(failure) == ["add", "add"]


def test_shipped_orchestrator_gives_no_false_alarm_with_its_monitors():
    chart = platform_chart("adaptation_orchestrator")
    budget = settings(max_examples=20, stateful_step_count=20, deadline=None, database=None)
    assert run(statechart_machine(chart), budget) is None


def test_machine_runs_as_a_pytest_testcase_class(tmp_path):
    machine = statechart_machine(charts.DOOR_FIXED, invariant=never_open_and_bolted)
    case = machine.TestCase
    assert case.__name__ == "DoorMachine.TestCase"
    assert hasattr(case, "runTest") and case.settings.stateful_step_count == 20


# --------------------------------------------------------------------------- which monitors apply


def test_watched_states_of_the_platform_monitors():
    watched = {p.stem: watched_states(load_statechart(p)) for p in platform_monitors()}
    stages = {"monitoring", "analysing", "planning", "legitimating", "executing"}
    assert watched == {
        "accepted_before_executing": {"legitimating", "executing"},
        "stage_outcome": stages,
    }


@pytest.mark.parametrize(
    "chart, expected",
    [
        ("adaptation_orchestrator", {"accepted_before_executing", "stage_outcome"}),
        ("core", set()),
        ("adaptation_manager", set()),
    ],
)
def test_monitors_apply_only_where_every_watched_state_exists(chart, expected):
    found = applicable_monitors(load_statechart(platform_chart(chart)))
    assert {m.name for m in found} == expected


def test_a_chart_sharing_one_state_name_gets_no_monitor():
    # `idle` alone is not the orchestrator
    chart = load_statechart(text=charts.VALVE_FIXED.replace("shut", "idle"))
    assert applicable_monitors(chart) == []


# --------------------------------------------------------------------------- inputs


def test_events_and_delays_come_from_the_chart():
    valve = load_statechart(text=charts.VALVE_FIXED)
    assert chart_events(valve) == ["close", "open"]
    assert timer_delays(valve, {"timeout": 4.0}) == [0.0, 2.0, 4.0]
    assert timer_delays(load_statechart(text=charts.DOOR_FIXED)) == [0.0, 1.0]


def test_a_chart_without_events_asks_for_them():
    chart = charts.VALVE_FIXED.replace("event: open", "guard: 1 == 1").replace(
        "event: close", "guard: 1 == 2"
    )
    with pytest.raises(ValueError, match=r"pass events=\[\.\.\.\]"):
        statechart_machine(chart)


def test_a_missing_chart_file_says_what_to_pass(tmp_path):
    with pytest.raises(FileNotFoundError, match="YAML path, the YAML text, or a Statechart"):
        statechart_machine(str(tmp_path / "nope.yaml"))


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"events": 5}, TypeError, "events must be a list of event names (or a dict), not int"),
        ({"invariant": 5}, TypeError, "invariant must be a function of the chart's state"),
        ({"initial_context": 5}, TypeError, "initial_context must be a dict of the chart's vari"),
        ({"steps": 0}, ValueError, "steps must be an int >= 1 (the longest sequence), not 0"),
    ],
)
def test_bad_arguments_say_what_to_pass(kwargs, error, message):
    # these failed later and deeper: "'int' object is not iterable" in sismic, hypothesis'
    # InvalidArgument, or (invariant=5) only once the test ran
    with pytest.raises(error) as caught:
        statechart_machine(charts.DOOR_FIXED, **kwargs)
    assert str(caught.value).startswith(message)


LONG_TIMER = """
statechart:
  name: kiln
  root state:
    name: kiln
    initial: cold
    states:
      - name: cold
        transitions:
          - target: firing
            event: light
      - name: firing
        transitions:
          - target: cracked
            guard: after(1000000.5)
          - target: cold
            event: quench
      - name: cracked
"""


def test_the_sequence_names_its_times_exactly(tmp_path):
    """The failure message writes each event's time as the decimal it is (1000000.5, not
    1e+06), so the sequence can be read and replayed as written."""
    chart = write(tmp_path, "kiln", LONG_TIMER)
    failure = run(statechart_machine(chart, invariant=lambda s: "cracked" not in s.configuration))
    assert failure is not None
    times = [e["time"] for e in failure.events]
    assert times[-1] - times[0] >= 1000000.5
    message = str(failure)
    for k, event in enumerate(failure.events, start=1):
        assert f"{k}. t={format_seconds(event['time'])}  {event['event']}" in message
    assert "e+" not in message
