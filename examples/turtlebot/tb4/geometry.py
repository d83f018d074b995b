"""Plane geometry for the simulated world: circles and axis-aligned boxes, rays cast onto them.

Angles are radians here; the scanner and the plans speak degrees (see :mod:`.lidar`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Box", "Circle", "Shape", "cast", "distance_to", "inside", "wrap"]


@dataclass(frozen=True)
class Circle:
    """A round obstacle (a pillar, a bin) centred on ``(x, y)``."""

    x: float
    y: float
    r: float


@dataclass(frozen=True)
class Box:
    """An axis-aligned rectangle ``[x0, x1] x [y0, y1]`` (walls are thin boxes)."""

    x0: float
    y0: float
    x1: float
    y1: float


Shape = Circle | Box


def wrap(angle: float) -> float:
    """``angle`` in radians brought into ``(-pi, pi]``."""
    a = math.fmod(angle + math.pi, 2 * math.pi)
    if a <= 0:
        a += 2 * math.pi
    return a - math.pi


def _ray_circle(ox: float, oy: float, dx: float, dy: float, c: Circle) -> float | None:
    fx, fy = ox - c.x, oy - c.y
    b = fx * dx + fy * dy
    q = fx * fx + fy * fy - c.r * c.r
    if q <= 0:  # the origin is inside (or on) the circle
        return 0.0
    disc = b * b - q
    if disc < 0:
        return None
    t = -b - math.sqrt(disc)
    return t if t >= 0 else None


def _ray_box(ox: float, oy: float, dx: float, dy: float, b: Box) -> float | None:
    # the slab method, unrolled for x and y (this is the scanner's inner loop)
    lo, hi = 0.0, math.inf
    if -1e-12 < dx < 1e-12:
        if ox < b.x0 or ox > b.x1:
            return None
    else:
        t0, t1 = (b.x0 - ox) / dx, (b.x1 - ox) / dx
        if t0 > t1:
            t0, t1 = t1, t0
        if t0 > lo:
            lo = t0
        if t1 < hi:
            hi = t1
        if lo > hi:
            return None
    if -1e-12 < dy < 1e-12:
        if oy < b.y0 or oy > b.y1:
            return None
    else:
        t0, t1 = (b.y0 - oy) / dy, (b.y1 - oy) / dy
        if t0 > t1:
            t0, t1 = t1, t0
        if t0 > lo:
            lo = t0
        if t1 < hi:
            hi = t1
        if lo > hi:
            return None
    return lo


def cast(ox: float, oy: float, angle: float, shapes: list[Shape], max_range: float) -> float | None:
    """Distance from ``(ox, oy)`` along ``angle`` to the first shape, or None beyond
    ``max_range`` (0.0 when the origin is inside a shape)."""
    dx, dy = math.cos(angle), math.sin(angle)
    best = max_range
    hit = False
    for s in shapes:
        t = _ray_box(ox, oy, dx, dy, s) if isinstance(s, Box) else _ray_circle(ox, oy, dx, dy, s)
        if t is not None and t <= best:
            best, hit = t, True
    return best if hit else None


def distance_to(x: float, y: float, s: Shape) -> float:
    """Distance from a point to a shape's boundary region (0 inside)."""
    if isinstance(s, Circle):
        return max(0.0, math.hypot(x - s.x, y - s.y) - s.r)
    dx = max(s.x0 - x, 0.0, x - s.x1)
    dy = max(s.y0 - y, 0.0, y - s.y1)
    return math.hypot(dx, dy)


def inside(x: float, y: float, s: Shape) -> bool:
    """Whether the point is strictly inside the shape."""
    if isinstance(s, Circle):
        return (x - s.x) ** 2 + (y - s.y) ** 2 < s.r * s.r
    return s.x0 < x < s.x1 and s.y0 < y < s.y1
