"""The clearance (tb4/clearance.py): what it calls seen free is free, whatever the debris, the
dropouts and the poses the scans were taken from; and what ends it is named rightly."""

from __future__ import annotations

import math
import random

from hypothesis import assume, given, settings
from hypothesis import strategies as st
from tb4.clearance import ECHO, FREE, UNSEEN, SeenSpace, clearance, seen
from tb4.geometry import Circle, distance_to
from tb4.lidar import Lidar, occluded_rays
from tb4.world import World

RADIUS = 0.17
ROOM = {"room": [6.0, 4.0]}
# obstacles as the scenarios have them (tb4.world.generate_scenario): circles of 0.18-0.3 m,
# boxes of 0.3-0.5 m
circles = st.builds(
    lambda x, y, r: {"circle": [x, y, r]},
    st.floats(0.5, 5.5), st.floats(0.5, 3.5), st.floats(0.18, 0.3),
)
boxes = st.builds(
    lambda x, y, w, h: {"box": [x, y, x + w, y + h]},
    st.floats(0.5, 5.0), st.floats(0.5, 3.0), st.floats(0.3, 0.5), st.floats(0.3, 0.5),
)
poses = st.tuples(st.floats(0.3, 5.7), st.floats(0.3, 3.7), st.floats(-math.pi, math.pi))
debris = st.lists(st.tuples(st.floats(-180, 180), st.floats(20, 160)), max_size=2)


def free(shapes, x, y, room=0.0):
    return all(distance_to(x, y, s) >= RADIUS + room for s in shapes)


@settings(max_examples=100, deadline=None)
@given(
    obstacles=st.lists(st.one_of(circles, boxes), max_size=3),
    taken=st.lists(st.tuples(poses, debris), min_size=1, max_size=4),
    robot=poses,
    seed=st.integers(0, 2**16),
)
def test_the_robot_can_drive_its_clearance_without_touching_anything(obstacles, taken, robot, seed):
    """Scans with the simulator's LiDAR (noise, 1 % dropouts, debris) from a few poses; from any
    free pose, the disc driven straight ahead by up to its clearance stays off every shape (to
    within the 3 cm its sampling allows: rays 1 deg apart, every 15 deg of its front)."""
    shapes = World.from_scenario({**ROOM, "obstacles": obstacles}).shapes
    assume(all(free(shapes, x, y) for (x, y, _), _ in taken) and free(shapes, *robot[:2]))
    lidar, rng = Lidar(), random.Random(seed)
    scans = [lidar.scan(x, y, yaw, shapes, occluded_rays(d, 360), rng) for (x, y, yaw), d in taken]
    distance, limit = clearance(robot, SeenSpace(scans, [p for p, _ in taken]))
    assert 0.0 <= distance <= 1.0 and limit in (FREE, ECHO, UNSEEN)
    x, y, yaw = robot
    for k in range(int(distance / 0.01) + 1):
        s = min(k * 0.01, distance)
        cx, cy = x + s * math.cos(yaw), y + s * math.sin(yaw)
        assert all(distance_to(cx, cy, shape) >= RADIUS - 0.03 for shape in shapes), s


ROOM4 = World.from_scenario({"room": [4.0, 4.0]}).shapes  # walls all around a 4 m room
HERE = (1.0, 2.0, 0.0)  # facing the wall at x = 4, 3 m ahead


def scan_from(x, y, yaw, shapes=ROOM4, blocked=()):
    """A scan without noise or dropouts."""
    lidar = Lidar(noise=0.0, dropout=0.0)
    return lidar.scan(x, y, yaw, shapes, occluded_rays(list(blocked), 360), random.Random(0))


def test_a_ray_shows_free_what_it_passed_an_echo_where_it_stopped_and_nothing_beyond():
    scans, at = [scan_from(*HERE)], [HERE]
    assert seen(2.5, 2.0, scans, at) == FREE
    assert seen(4.0, 2.0, scans, at) == ECHO
    assert seen(4.5, 2.0, scans, at) == UNSEEN


def test_a_blocked_ray_tells_nothing():
    scans, at = [scan_from(*HERE, blocked=[(0.0, 120.0)])], [HERE]
    assert seen(2.5, 2.0, scans, at) == UNSEEN
    assert seen(1.0, 3.5, scans, at) == FREE  # the clear ray at 90 deg passed it


def test_the_clearance_runs_to_an_echo_or_to_unseen_space_and_older_scans_count():
    assert clearance(HERE, SeenSpace([scan_from(*HERE)], [HERE])) == (1.0, FREE)  # the horizon
    near = (3.2, 2.0, 0.0)
    distance, limit = clearance(near, SeenSpace([scan_from(*near)], [near]))
    assert limit == ECHO and 0.8 - RADIUS - 0.1 <= distance <= 0.8 - RADIUS
    blocked = scan_from(*near, blocked=[(0.0, 120.0)])
    assert clearance(near, SeenSpace([blocked], [near])) == (0.0, UNSEEN)
    # an older scan, taken 2.2 m back with nothing on the LiDAR, saw the space ahead free
    older = SeenSpace([blocked, scan_from(*HERE)], [near, HERE])
    assert clearance(near, older) == (distance, ECHO)


def test_the_space_an_obstacle_hides_is_unseen():
    pillar = ROOM4 + [Circle(2.0, 2.0, 0.25)]
    space = SeenSpace([scan_from(*HERE, shapes=pillar)], [HERE])
    assert clearance(HERE, space)[1] == ECHO  # ends at the pillar
    beside = (2.0, 2.6, math.radians(-30.0))  # past it, heading into its shadow
    distance, limit = clearance(beside, space)
    assert limit == UNSEEN and distance < 0.5
