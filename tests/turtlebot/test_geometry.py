"""The simulator's geometry: the ray caster agrees with brute-force marching along the ray, and
the scanner puts debris, range limits and angles where they belong."""

from __future__ import annotations

import math
import random

from hypothesis import assume, given, settings
from hypothesis import strategies as st
from tb4.geometry import Box, Circle, cast, distance_to, inside, wrap
from tb4.lidar import Lidar, occluded_rays, ray_angle

coord = st.floats(-3.0, 3.0, allow_nan=False)
circles = st.builds(Circle, coord, coord, st.floats(0.1, 1.0))
boxes = st.builds(
    lambda x, y, w, h: Box(x, y, x + w, y + h),
    coord,
    coord,
    st.floats(0.1, 2.0),
    st.floats(0.1, 2.0),
)
shapes = st.lists(st.one_of(circles, boxes), min_size=1, max_size=5)
STEP = 2e-3
MAX_RANGE = 5.0


def march(ox, oy, angle, world):
    """Brute force: the first sample along the ray (every STEP m) strictly inside a shape."""
    dx, dy = math.cos(angle), math.sin(angle)
    for k in range(int(MAX_RANGE / STEP) + 1):
        s = k * STEP
        if any(inside(ox + s * dx, oy + s * dy, shape) for shape in world):
            return s
    return None


def grazes(ox, oy, angle, shape):
    """A ray along a box's edge line: the caster takes a ray within 1e-12 of an axis for
    parallel to it, so one running a hair inside an edge (marching finds it inside) is
    ambiguous at that tolerance."""
    if not isinstance(shape, Box):
        return False
    dx, dy = math.cos(angle), math.sin(angle)
    near = 1e-6
    along_x = abs(dy) < 1e-12 and min(abs(oy - shape.y0), abs(oy - shape.y1)) < near
    along_y = abs(dx) < 1e-12 and min(abs(ox - shape.x0), abs(ox - shape.x1)) < near
    return along_x or along_y


@settings(max_examples=150, deadline=None)
@given(world=shapes, ox=coord, oy=coord, angle=st.floats(-math.pi, math.pi))
def test_ray_cast_matches_marching(world, ox, oy, angle):
    assume(all(distance_to(ox, oy, shape) > 1e-3 for shape in world))
    assume(not any(grazes(ox, oy, angle, shape) for shape in world))
    d = cast(ox, oy, angle, world, MAX_RANGE)
    first_inside = march(ox, oy, angle, world)
    dx, dy = math.cos(angle), math.sin(angle)
    if first_inside is not None:  # marching found a shape: the caster found one no later
        assert d is not None and d <= first_inside + 1e-9
    if d is not None:
        assert 0.0 < d <= MAX_RANGE
        # the hit lies on a shape ...
        px, py = ox + d * dx, oy + d * dy
        assert min(distance_to(px, py, shape) for shape in world) <= 1e-6
        # ... and nothing comes before it
        for k in range(int(d / STEP)):
            s = k * STEP
            assert not any(inside(ox + s * dx, oy + s * dy, shape) for shape in world)


@given(world=shapes, angle=st.floats(-math.pi, math.pi))
def test_a_ray_from_inside_a_shape_hits_at_once(world, angle):
    shape = world[0]
    x, y = (
        (shape.x, shape.y)
        if isinstance(shape, Circle)
        else ((shape.x0 + shape.x1) / 2, (shape.y0 + shape.y1) / 2)
    )
    assert cast(x, y, angle, world, MAX_RANGE) == 0.0


@given(st.floats(-100.0, 100.0))
def test_wrap_keeps_the_direction(angle):
    w = wrap(angle)
    assert -math.pi < w <= math.pi
    assert math.isclose(math.cos(w), math.cos(angle), abs_tol=1e-9)
    assert math.isclose(math.sin(w), math.sin(angle), abs_tol=1e-9)


@given(
    windows=st.lists(st.tuples(st.floats(-180, 180), st.floats(1, 120)), max_size=3),
    rays=st.sampled_from([90, 360, 720]),
)
def test_a_ray_is_occluded_exactly_when_a_window_contains_its_angle(windows, rays):
    mask = occluded_rays(windows, rays)
    for i, blocked in enumerate(mask):
        angle = ray_angle(i, rays)
        within = [abs((angle - c + 180) % 360 - 180) <= w / 2 for c, w in windows]
        assert blocked == any(within)


@settings(deadline=None)
@given(
    x=st.floats(1.0, 8.0),
    y=st.floats(1.0, 4.0),
    yaw=st.floats(-math.pi, math.pi),
    window=st.tuples(st.floats(-180, 180), st.floats(10, 200)),
)
def test_a_noiseless_scan_is_the_ray_cast_outside_the_debris(x, y, yaw, window):
    room = [
        Box(-0.1, -0.1, 9.1, 0.0),
        Box(-0.1, 5.0, 9.1, 5.1),
        Box(-0.1, 0.0, 0.0, 5.0),
        Box(9.0, 0.0, 9.1, 5.0),
    ]
    lidar = Lidar(rays=72, max_range=12.0, noise=0.0, dropout=0.0)
    mask = occluded_rays([window], 72)
    scan = lidar.scan(x, y, yaw, room, mask, random.Random(0))
    for i, r in enumerate(scan):
        if mask[i]:
            assert r is None
        else:  # inside a closed room every clear ray hits a wall within range
            expected = cast(x, y, yaw + math.radians(ray_angle(i, 72)), room, 12.0)
            assert r == round(expected, 3)


def test_nothing_beyond_the_maximum_range_comes_back():
    lidar = Lidar(rays=4, max_range=2.0, noise=0.0, dropout=0.0)
    far_wall = [Box(5.0, -10.0, 6.0, 10.0)]
    assert lidar.scan(0.0, 0.0, 0.0, far_wall, [False] * 4, random.Random(0)) == [None] * 4
