"""Analyse's model of the occlusion: how likely each ray is blocked, judged over
a sliding window of recent scans, thresholded and clustered into windows of adjacent rays.

A ray is *invalid* in a scan when it returned nothing (``None`` on the local bus, ``inf``
in a ROS 2 LaserScan) or less than the scanner's minimum range. Open space within the
scanner's range returns an echo, and random dropouts are rare, so a ray that stays invalid
scan after scan while the robot moves and turns is blocked by something on the robot itself.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["Window", "cluster", "detect", "occlusion_probability"]

RANGE_MIN = 0.05


@dataclass(frozen=True)
class Window:
    """``length`` adjacent rays from ray ``start`` (counter-clockwise, may wrap past ray 0)."""

    start: int
    length: int

    def rays(self, total: int) -> list[int]:
        return [(self.start + k) % total for k in range(self.length)]

    def degrees(self, total: int) -> tuple[float, float]:
        """(centre, width) in degrees, the centre in ``(-180, 180]``."""
        step = 360.0 / total
        centre = (self.start + (self.length - 1) / 2.0) * step
        centre = (centre + 180.0) % 360.0 - 180.0
        return (180.0 if centre == -180.0 else centre), self.length * step


def occlusion_probability(scans: Sequence[Sequence[float | None]]) -> list[float]:
    """Per ray, the fraction of ``scans`` in which it was invalid (all scans the same size)."""
    if not scans:
        return []
    n = len(scans)
    return [
        sum(1 for r in ray if r is None or not RANGE_MIN <= r < math.inf) / n
        for ray in zip(*scans, strict=True)
    ]


def cluster(mask: Sequence[bool], min_length: int = 1) -> list[Window]:
    """Maximal runs of adjacent ``True`` rays on the circle, at least ``min_length`` long, in order
    of their first ray. A run crossing ray 0 is one window; an all-``True`` mask is one window of
    every ray starting at 0."""
    n = len(mask)
    if n == 0 or not any(mask):
        return []
    if all(mask):
        return [Window(0, n)] if n >= min_length else []
    first_free = next(i for i in range(n) if not mask[i])
    windows = []
    run_start, run = None, 0
    for k in range(1, n + 1):  # walk once around, starting just after a free ray
        i = (first_free + k) % n
        if mask[i]:
            if run_start is None:
                run_start, run = i, 0
            run += 1
        elif run_start is not None:
            windows.append(Window(run_start, run))
            run_start = None
    return sorted((w for w in windows if w.length >= min_length), key=lambda w: w.start)


def detect(
    scans: Sequence[Sequence[float | None]], threshold: float = 0.7, min_length: int = 3
) -> list[Window]:
    """The occlusion windows seen in ``scans``: rays invalid in at least ``threshold`` of them,
    clustered, runs shorter than ``min_length`` rays dropped (a few dropouts are no debris)."""
    probability = occlusion_probability(scans)
    return cluster([p >= threshold for p in probability], min_length)
