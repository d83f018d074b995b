"""How far the robot can drive ahead through space it has seen to be free.

The world is static, so a point that a ray once passed (the ray came back from further away)
holds no obstacle. The robot cannot hit anything while its footprint, moved straight ahead,
stays in such points: before any collision this *clearance* falls to 0. Debris does not fool
it: a blocked ray returns nothing, and nothing is what it tells. What ends the clearance is
either an echo (an obstacle the scans have seen: the robot's planner steers round it) or space
no scan has seen (looking again would show what is there).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["ECHO", "FREE", "UNSEEN", "SeenSpace", "clearance", "seen"]

RANGE_MIN = 0.05  # m, the scanner's minimum range (tb4.occlusion)
TOLERANCE = 0.05  # m a ray must reach beyond a point for the point to count as seen free
NEAR = 0.1  # m from an echo within which a point counts as the obstacle that echoed
REACH = 3.0  # m from a scan within which it shows space free (a costmap's raytrace range)

FREE, ECHO, UNSEEN = "free", "echo", "unseen"


class SeenSpace:
    """The scans (each with the ``(x, y, yaw_rad)`` it was taken from; newest first), asked
    point by point what they saw there. Neighbouring points are mostly shown free by the same
    scan, so the scan that answered last is asked first."""

    def __init__(
        self, scans: Sequence[Sequence[float | None]], poses: Sequence[Sequence[float]]
    ) -> None:
        self.scans = [
            (ranges, float(x), float(y), float(yaw), len(ranges) / (2 * math.pi))
            for ranges, (x, y, yaw) in zip(scans, poses, strict=True)
        ]
        self.last = 0

    def seen(self, px: float, py: float) -> str:
        """:data:`FREE` if some scan's ray towards ``(px, py)`` passed it (or, where that ray
        came back empty, a dropout, both rays next to that one did), else :data:`ECHO` if that
        ray came back from within :data:`NEAR` of it, else :data:`UNSEEN`. Only points within
        :data:`REACH` of a scan count: between rays 1 deg apart a point may lie up to 2.6 cm off
        the ray that passed it there."""
        scans, echo = self.scans, False
        order = range(len(scans))
        if 0 < self.last < len(scans):
            order = [self.last, *range(self.last), *range(self.last + 1, len(scans))]
        for index in order:
            ranges, sx, sy, syaw, per_radian = scans[index]
            dx, dy = px - sx, py - sy
            distance = math.hypot(dx, dy)
            if distance > REACH:
                continue
            n = len(ranges)
            ray = round((math.atan2(dy, dx) - syaw) * per_radian)
            r = _valid(ranges[ray % n])
            if r is None:  # a dropout between two echoes tells what its neighbours tell
                below, above = _valid(ranges[(ray - 1) % n]), _valid(ranges[(ray + 1) % n])
                if below is None or above is None:
                    continue
                r = min(below, above)
            if r >= distance + TOLERANCE:
                self.last = index
                return FREE
            echo = echo or abs(r - distance) <= NEAR
        return ECHO if echo else UNSEEN


def seen(
    px: float,
    py: float,
    scans: Sequence[Sequence[float | None]],
    poses: Sequence[Sequence[float]],
) -> str:
    """What ``scans`` (each with the ``(x, y, yaw_rad)`` it was taken from) saw at ``(px, py)``:
    see :meth:`SeenSpace.seen`."""
    return SeenSpace(scans, poses).seen(px, py)


def _valid(r: float | None) -> float | None:
    return r if r is not None and RANGE_MIN <= r < math.inf else None


def clearance(
    pose: Sequence[float],
    space: SeenSpace,
    *,
    radius: float = 0.17,
    horizon: float = 1.0,
    step: float = 0.05,
    lanes: int = 13,
) -> tuple[float, str]:
    """``(distance, limit)``: how far (m, at most ``horizon``) the robot at ``pose``
    ``(x, y, yaw_rad)``, a disc of ``radius``, can drive straight ahead with every point it
    sweeps seen free in ``space``, and what ends it there (:data:`ECHO` or :data:`UNSEEN`;
    :data:`FREE` at the horizon). The disc's front half is sampled at ``lanes`` points evenly
    spaced in angle (every 15 deg), every ``step`` m along: between the samples and the rays an
    obstacle of the scenarios' sizes can reach at most 3 cm into the disc
    (``tests/turtlebot/test_clearance.py``)."""
    x, y, yaw = pose
    ch, sh = math.cos(yaw), math.sin(yaw)
    angles = [math.pi * (k / (lanes - 1) - 0.5) for k in range(lanes)]
    front = [(radius * math.sin(a), radius * math.cos(a)) for a in angles]  # (across, ahead)
    driven = 0.0
    while driven < horizon - 1e-9:  # the disc moved ``driven`` ahead: its front, lane by lane
        points = [(x + (driven + ahead) * ch - across * sh, y + (driven + ahead) * sh + across * ch)
                  for across, ahead in front]
        if any(space.seen(px, py) != FREE for px, py in points):
            found = {space.seen(px, py) for px, py in points}
            return round(max(driven - step, 0.0), 3), UNSEEN if UNSEEN in found else ECHO
        driven += step
    return horizon, FREE
