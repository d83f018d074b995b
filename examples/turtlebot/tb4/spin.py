"""Plan's geometry: stops and rotations that bring every occluded sector into view.

The debris is fixed on the robot, so turning the robot by ``a`` degrees puts world direction
``psi`` (relative to the heading at the stop) on body ray ``psi - a``. A spin sweeps ``a`` over
``[-rotation, +rotation]``; it *covers* an occluded direction when some ``a`` in the sweep puts it
on a ray that is clear of every window by ``margin`` rays. :func:`required_rotation` is the least
such ``rotation`` (in rays).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from .occlusion import Window

__all__ = ["covered", "dilate", "mask_of", "required_rotation", "spin_plan"]


def mask_of(windows: Sequence[Window], total: int) -> list[bool]:
    """The rays inside any window."""
    mask = [False] * total
    for w in windows:
        for i in w.rays(total):
            mask[i] = True
    return mask


def dilate(mask: Sequence[bool], margin: int) -> list[bool]:
    """``mask`` widened by ``margin`` rays on both sides (on the circle)."""
    n = len(mask)
    out = list(mask)
    for i, m in enumerate(mask):
        if m:
            for k in range(1, margin + 1):
                out[(i + k) % n] = True
                out[(i - k) % n] = True
    return out


def required_rotation(mask: Sequence[bool], margin: int = 5) -> int | None:
    """Least sweep half-angle (in rays) that covers every occluded ray, or None if no sweep can
    (nothing is clear once widened by ``margin``). 0 when nothing is occluded."""
    n = len(mask)
    blocked = dilate(mask, margin)
    if all(blocked):
        return None if any(mask) else 0
    # circular distance transform: rays to the nearest clear ray
    dist = [0 if not b else n for b in blocked]
    for _ in range(2):
        for i in range(n):
            dist[i] = min(dist[i], dist[i - 1] + 1)
        for i in range(n - 1, -1, -1):
            dist[i] = min(dist[i], dist[(i + 1) % n] + 1)
    return max((dist[i] for i in range(n) if mask[i]), default=0)


def covered(mask: Sequence[bool], rotation: int, margin: int = 5) -> bool:
    """Whether a sweep of ``[-rotation, +rotation]`` rays shows every occluded ray on a clear one
    (the definition, checked by brute force; :func:`required_rotation` computes its least
    ``rotation``)."""
    n = len(mask)
    blocked = dilate(mask, margin)
    return all(
        any(not blocked[(psi - a) % n] for a in range(-rotation, rotation + 1))
        for psi in range(n)
        if mask[psi]
    )


def spin_plan(
    windows: Sequence[Window],
    total: int,
    *,
    angular_velocity: float = 90.0,
    cruise: float = 0.3,
    mark_range: float = 2.0,
    lookahead: float = 0.8,
    margin: int = 5,
) -> dict | None:
    """The plan for ``/spin_config``: sweep half-angle ``rotation`` (deg) at ``angular_velocity``
    (deg/s), taking ``spin_duration`` s, once every ``stop_every`` s of driving (the robot must see
    what lies ahead while it is within ``mark_range`` and still ``lookahead`` m away), and the
    ``cruise`` speed in between. None when no sweep can cover the windows."""
    step = 360.0 / total
    rays = required_rotation(mask_of(windows, total), margin)
    if rays is None:
        return None
    rotation = round(rays * step, 3)
    if rotation == 0:
        return {
            "rotation": 0.0,
            "angular_velocity": 0.0,
            "spin_duration": 0.0,
            "stop_every": 0.0,
            "cruise": cruise,
        }
    return {
        "rotation": rotation,
        "angular_velocity": float(angular_velocity),
        # rounded up to the millisecond (and a hair more, so float products stay above the
        # sweep at exact boundaries): the duration always fits the sweep
        "spin_duration": math.ceil(4000.0 * rotation / angular_velocity + 1e-6) / 1000.0,
        "stop_every": round((mark_range - lookahead) / cruise, 3),
        "cruise": cruise,
    }
