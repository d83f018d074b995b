"""The TurtleBot's two charts explored by hypothesis (rasm.testing.statechart_machine): its
navigation modes under any sequence of records, its Analyse chart under any sequence of
iterations, on every kind of knowledge it can read."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings
from hypothesis import strategies as st

from rasm.testing import statechart_machine

from .conftest import APP

MODES = APP / "statecharts" / "navigation_modes.yaml"
ANALYSE = APP / "statecharts" / "analyse.yaml"
TOP = {"navigate", "spin", "blocked", "arrived"}

# what /odom, /robot_state and /collision records carry, alone or together
RECORDS = st.fixed_dictionaries(
    {},
    optional={
        "nav_mode": st.sampled_from(["navigate", "spin", "arrived"]),
        "velocity": st.sampled_from([0.0, 0.01, 0.1, 0.3]),
        "collision": st.just(True),
    },
)


def one_mode(state) -> bool:
    """Exactly one of the four modes is active; moving and stopped only while navigating."""
    assert len(state.configuration & TOP) == 1, sorted(state.configuration)
    if state.configuration & {"moving", "stopped"}:
        assert state.active("navigate")
    return True


TestNavigationModes = statechart_machine(
    MODES, events={"record": RECORDS}, monitors=[], invariant=one_mode
).TestCase
TestNavigationModes.settings = settings(max_examples=60, stateful_step_count=25, deadline=None)


def arrived_for_good(state) -> bool:
    """Once a record saying arrived has been taken, the chart is in arrived. (The latest
    event may still be waiting for a timer's step to be taken first.)"""
    taken = state.events[:-1]
    if any(e.get("data", {}).get("nav_mode") == "arrived" for e in taken):
        return state.configuration & TOP == {"arrived"}
    return True


def test_arrived_is_for_good():
    """Whatever comes after arrival, the modes chart stays in arrived (spin_config never
    applies again)."""
    machine = statechart_machine(
        MODES, events={"record": RECORDS}, monitors=[], invariant=arrived_for_good
    )
    test = machine.TestCase
    test.settings = settings(max_examples=40, stateful_step_count=20, deadline=None)
    test().runTest()


# driving into space no scan has seen free (its robustness below the margin: a look is due)
BLIND = {"velocity": 0.3, "robustness_keeps_clearance": 0.1, "clearance": 0.4,
         "clearance_ahead": 0.3, "clearance_unseen": True}


@pytest.mark.parametrize("occlusion", ["unknown", "clear", "covered", "uncovered"])
@pytest.mark.parametrize("nav_mode", ["navigate", "arrived"])
@pytest.mark.parametrize("driving", [{}, BLIND], ids=["standing", "blind"])
def test_the_analyse_chart_answers_every_iteration_exactly_once(occlusion, nav_mode, driving):
    knowledge = {
        "occlusion": occlusion,
        "nav_mode": nav_mode,
        "occluded_sectors": "121 deg wide at 0 deg",
        "occluded_windows": [[300, 121]],
        "rays": 360,
        "spin_rotation": 66.0,
        **driving,
    }
    machine = statechart_machine(
        ANALYSE,
        events=["analyse"],
        monitors=[Path(__file__).with_name("answers_once.yaml")],
        initial_context={"knowledge": knowledge},
        delays=[0.0, 0.2, 0.5, 1.0, 1.2],
        invariant=lambda s: len(s.configuration & {"clear", "occluded", "recovering"}) == 1,
    )
    test = machine.TestCase
    test.settings = settings(max_examples=25, stateful_step_count=15, deadline=None)
    test().runTest()
