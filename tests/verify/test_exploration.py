"""rasm verify explores every reachable state: against a brute-force search over stock sismic,
with and without slicing, and never "satisfied" when it stopped early."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from sismic.io.datadict import import_from_dict

from rasm.statechart import load_statechart
from rasm.verify import EnvEvent, Environment, verify_chart
from rasm.verify.explore import ChartExplorer, explore
from tests.statechart.fast.strategies import chart_dicts
from tests.verify.reference import brute_force

# bounded data: the context takes finitely many values, so a brute force over the full context
# ends; no timers (the brute force would key on the absolute time)
GUARDS = [
    "x > 0",
    "x % 2 == 0",
    "y == 0",
    "x < 2",
    "active('s1')",
    "active('s4') or x > 1",
    "event is None or event.data.get('v', 0) >= 1",
    "event is not None and event.data.get('v', 0) == 2 and x != 1",
]
ACTIONS = [
    "x = (x + 1) % 3",
    "x = (x + 2) % 3",
    "y = 1 - y",
    "x = 0",
    "send('a')",
    "send('b', v=x)",
    "x = (x + 1) % 3\nsend('c')",
]
EVENTS = ["a", "b", "c"]
DATA = [0, 1, 2]


def _environment() -> Environment:
    return Environment(tuple(EnvEvent(name, (("v", tuple(DATA)),)) for name in EVENTS))


def _stock_moves() -> list[tuple[str, dict[str, Any]]]:
    return [(name, {"v": v}) for name in EVENTS for v in DATA]


def _failed(found) -> bool:
    return any(p.kind in ("raising code", "non-determinism", "contract", "no stable state")
               for p in found.problems)


# a move taking more macro steps never settles (internal sends forever): few, so that such
# charts are cheap to tell (a growing list copied at every one of 10,000 steps is not)
STEPS = 50

bounded_charts = chart_dicts(max_states=8, contracts=False, guards=GUARDS, actions=ACTIONS)


@pytest.mark.slow
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(bounded_charts)
def test_reachable_configurations_are_those_of_a_brute_force_over_stock_sismic(chart: dict) -> None:
    statechart = import_from_dict(chart)
    try:
        expected, _ = brute_force(statechart, _stock_moves(), max_states=2_000, max_steps=STEPS)
    except Exception:
        assume(False)  # a step stock sismic cannot take, or more states than the budget
    found = explore(ChartExplorer(statechart, _environment(), max_steps=STEPS), max_states=2_000)
    assume(not _failed(found))
    assert found.complete
    assert found.configurations == expected


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(bounded_charts, st.sampled_from(["z = z + 1", "log = log + [x]", "z = (z * 7 + x) % 1000"]))
def test_slicing_away_variables_no_guard_depends_on_reaches_the_same_configurations(
    chart: dict, bookkeeping: str
) -> None:
    # a variable only bookkeeping reads and writes (a counter, a log): sliced away, it changes
    # the number of states, never the configurations reached
    body = chart["statechart"]
    body["preamble"] += "\nz = 0\nlog = []"
    root = body["root state"]
    for transition in root.get("transitions", []):
        transition["action"] = (transition.get("action", "") + "\n" + bookkeeping).strip()
    statechart = import_from_dict(chart)
    sliced = explore(ChartExplorer(statechart, _environment(), max_steps=STEPS), max_states=1_000)
    whole = explore(
        ChartExplorer(statechart, _environment(), slice_context=False, max_steps=STEPS),
        max_states=1_000,
    )
    assume(whole.complete and not _failed(whole))
    assert sliced.complete
    assert sliced.configurations == whole.configurations
    assert sliced.states <= whole.states


COUNTER = """
statechart:
  name: counter
  preamble: |
    n = 0
  root state:
    name: root
    initial: counting
    states:
      - name: counting
        transitions:
          - event: tick
            action: |
              n += 1
          - target: done
            event: stop
            guard: n == -1
      - name: done
"""


def test_unbounded_data_ends_inconclusive_never_satisfied(tmp_path) -> None:
    chart = tmp_path / "counter.yaml"
    chart.write_text(COUNTER)
    props = tmp_path / "p.rv"
    props.write_text('property never_done: always not in_state("done")\n')
    result = verify_chart(chart, properties=props, max_states=50)
    assert not result.complete
    assert result.verdict == "inconclusive" and result.exit_code == 3
    assert [p.verdict for p in result.properties] == ["inconclusive"]
    assert result.states == 50


def test_every_platform_chart_verifies_completely() -> None:
    from rasm.resources import data_dir

    for path in sorted(data_dir("statecharts").glob("*.yaml")):
        result = verify_chart(path)
        assert (path.name, result.verdict, result.complete) == (path.name, "satisfied", True), [
            f"{f.kind}: {f.message}" for f in result.problems
        ]
        load_statechart(path)  # and it is the chart rasm run loads
