"""The robot's world: a walled room with obstacles, a route of waypoints, debris on a schedule.

A scenario is plain data (the ``managed_system.scenario`` of ``app.yaml``, or
:func:`generate_scenario` for the benchmark)::

    room: [9.0, 5.0]                  # width and depth (m); walls 0.1 m thick around it
    start: [1.0, 2.5, 0.0]            # x, y (m), yaw (deg)
    waypoints: [[4.5, 2.7], [8.0, 2.5]]
    obstacles: [{circle: [4.6, 2.6, 0.25]}, {box: [6.9, 2.3, 7.3, 2.8]}]
    occlusions: [{start: 1.0, center: 0.0, width: 120.0}]   # debris on the robot body (deg),
                                                            # optional `end` (s)
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import Any

from .geometry import Box, Circle, Shape

__all__ = ["Debris", "World", "generate_scenario"]

WALL = 0.1


@dataclass(frozen=True)
class Debris:
    """An occluding window fixed to the robot body: ``center``/``width`` in degrees (0 = ahead,
    counter-clockwise), present from ``start`` until ``end`` seconds."""

    start: float
    center: float
    width: float
    end: float = float("inf")

    def active(self, time: float) -> bool:
        return self.start <= time < self.end


@dataclass
class World:
    """Everything the simulator needs to know about the environment."""

    shapes: list[Shape]
    start: tuple[float, float, float]
    waypoints: list[tuple[float, float]]
    debris: list[Debris] = field(default_factory=list)
    room: tuple[float, float] = (10.0, 5.0)

    @classmethod
    def from_scenario(cls, scenario: dict[str, Any]) -> World:
        w, h = (float(v) for v in scenario.get("room", (10.0, 5.0)))
        shapes: list[Shape] = [
            Box(-WALL, -WALL, w + WALL, 0.0),
            Box(-WALL, h, w + WALL, h + WALL),
            Box(-WALL, 0.0, 0.0, h),
            Box(w, 0.0, w + WALL, h),
        ]
        for item in scenario.get("obstacles", []):
            if "circle" in item:
                shapes.append(Circle(*(float(v) for v in item["circle"])))
            else:
                shapes.append(Box(*(float(v) for v in item["box"])))
        x, y, yaw = (float(v) for v in scenario.get("start", (1.0, h / 2, 0.0)))
        waypoints = [(float(a), float(b)) for a, b in scenario.get("waypoints", [(w - 1, h / 2)])]
        debris = [
            Debris(
                float(d["start"]),
                float(d.get("center", 0.0)),
                float(d["width"]),
                float(d.get("end", float("inf"))),
            )
            for d in scenario.get("occlusions", [])
        ]
        return cls(shapes, (x, y, yaw), waypoints, debris, (w, h))


def generate_scenario(seed: int) -> dict[str, Any]:
    """A random but reproducible scenario: two or three obstacles squarely on the route, a wide
    debris window ahead early on, sometimes more debris next to it later."""
    rng = random.Random(seed)
    h = 5.0
    y0 = round(rng.uniform(2.0, 3.0), 2)
    mid_y = round(min(max(y0 + rng.uniform(-0.6, 0.6), 1.2), 3.8), 2)
    waypoints = [[4.5, mid_y], [8.0, y0]]
    obstacles = []
    xs = [3.7, 5.3, 6.8]
    count = rng.choice((2, 3, 3))
    for x in rng.sample(xs, count):
        x = round(x + rng.uniform(-0.3, 0.3), 2)
        # on the straight line between the waypoints around x, give or take a few cm
        ax, ay, bx, by = (1.0, y0, 4.5, mid_y) if x < 4.5 else (4.5, mid_y, 8.0, y0)
        y = ay + (by - ay) * (x - ax) / (bx - ax) + rng.uniform(-0.08, 0.08)
        if rng.random() < 0.7:
            obstacles.append({"circle": [x, round(y, 2), round(rng.uniform(0.18, 0.3), 2)]})
        else:
            half = round(rng.uniform(0.15, 0.25), 2)
            obstacles.append({"box": [x - half, round(y - half, 2), x + half, round(y + half, 2)]})
    occlusions = [
        {
            "start": round(rng.uniform(0.5, 1.5), 2),
            "center": round(rng.uniform(-10.0, 10.0), 1),
            "width": round(rng.uniform(100.0, 140.0), 1),
        }
    ]
    if rng.random() < 0.4:  # more debris later, next to the first: a wider blocked sector
        first = occlusions[0]
        side = rng.choice((-1, 1))
        width = round(rng.uniform(25.0, 45.0), 1)
        centre = first["center"] + side * (first["width"] + width) / 2.0
        occlusions.append(
            {"start": round(rng.uniform(8.0, 16.0), 2), "center": round(centre, 1), "width": width}
        )
    return {
        "room": [9.0, h],
        "start": [1.0, y0, 0.0],
        "waypoints": waypoints,
        "obstacles": obstacles,
        "occlusions": occlusions,
    }
