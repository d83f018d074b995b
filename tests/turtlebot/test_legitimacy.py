"""Legitimate's inline simulation: braking and sweeping on the map the scans give."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st
from tb4.legitimacy import map_points, simulate_spin

PLAN = {"rotation": 60.0, "angular_velocity": 90.0, "spin_duration": 2.667}


def test_map_points_place_hits_with_the_pose_of_their_scan():
    scan = [1.0, None, 2.0, None]  # rays at 0, 90, 180, 270 deg
    points = map_points([scan], [(1.0, 1.0, math.pi / 2)])
    assert [(round(x, 9), round(y, 9)) for x, y in points] == [(1.0, 2.0), (1.0, -1.0)]


def test_a_spin_in_open_space_is_legitimate():
    assert simulate_spin(PLAN, (0.0, 0.0, 0.0), 0.3, [(3.0, 0.0), (0.0, 2.0)]) == (True, "")


@given(st.floats(0.05, 0.3))
def test_braking_into_a_mapped_obstacle_is_not(velocity):
    # the robot needs v^2 / 2a to stop; an obstacle at the stop point is touched
    stop = velocity**2 / 2.0
    ok, why = simulate_spin(PLAN, (0.0, 0.0, 0.0), velocity, [(stop + 0.17, 0.0)])
    assert not ok and "obstacle" in why


def test_a_sweep_that_cannot_finish_in_its_duration_is_not():
    ok, why = simulate_spin({**PLAN, "spin_duration": 2.0}, (0.0, 0.0, 0.0), 0.0, [])
    assert not ok and "more than the planned" in why


def test_a_sweep_faster_than_the_robot_turns_is_not():
    ok, why = simulate_spin({**PLAN, "angular_velocity": 120.0}, (0.0, 0.0, 0.0), 0.0, [])
    assert not ok and "turn rate" in why
