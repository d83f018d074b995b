"""The 360-ray 2D LiDAR (an RPLIDAR A1 on the TurtleBot 4) with body-fixed debris.

Ray ``i`` looks at ``i * 360 / rays`` degrees from the robot's heading, counter-clockwise.
A reading is a range in metres, or ``None`` (the JSON ``null`` on ``/safe-scan``) when nothing
came back: beyond ``max_range``, a random dropout, or a ray blocked by debris on the scanner.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from .geometry import Shape, cast

__all__ = ["Lidar", "occluded_rays", "ray_angle"]


def ray_angle(i: int, rays: int) -> float:
    """Body-frame angle of ray ``i`` in degrees, in ``[0, 360)``."""
    return i * 360.0 / rays


def occluded_rays(windows: list[tuple[float, float]], rays: int) -> list[bool]:
    """Which rays fall inside any ``(center, width)`` window (degrees, body frame)."""
    mask = [False] * rays
    for center, width in windows:
        half = width / 2.0
        for i in range(rays):
            d = abs((ray_angle(i, rays) - center + 180.0) % 360.0 - 180.0)
            if d <= half:
                mask[i] = True
    return mask


@dataclass
class Lidar:
    """Casts ``rays`` rays; Gaussian range noise, random dropouts, ``None`` past ``max_range``."""

    rays: int = 360
    max_range: float = 12.0
    range_min: float = 0.05
    noise: float = 0.01
    dropout: float = 0.01

    def scan(
        self,
        x: float,
        y: float,
        yaw: float,
        shapes: list[Shape],
        occluded: list[bool],
        rng: random.Random,
    ) -> list[float | None]:
        """One sweep from pose ``(x, y, yaw)`` (yaw in radians)."""
        out: list[float | None] = []
        step = 2 * math.pi / self.rays
        for i in range(self.rays):
            if occluded[i]:
                out.append(None)
                continue
            r = cast(x, y, yaw + i * step, shapes, self.max_range)
            if r is None or rng.random() < self.dropout:
                out.append(None)
                continue
            r = min(max(r + rng.gauss(0.0, self.noise), self.range_min), self.max_range)
            out.append(round(r, 3))
        return out
