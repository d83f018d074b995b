"""Legitimate's inline simulation: play a spin plan on the current map before it
is executed.

The map is what the robot's own scans show: the hit points of the recent scans, each placed with
the pose it was taken from. The simulation brakes the robot to a stop from its current velocity
along its heading, then turns it through the sweep at the planned rate, and reports the first
problem: the footprint would touch a mapped point, the sweep would not finish within the planned
duration, or it would turn faster than the robot allows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from .navigation import LIMITS, RobotLimits, sweep_targets

__all__ = ["map_points", "simulate_spin"]


def map_points(
    scans: Sequence[Sequence[float | None]],
    poses: Sequence[Sequence[float]],
    max_range: float = 3.0,
) -> list[tuple[float, float]]:
    """World points hit by ``scans`` (each with its ``(x, y, yaw_rad)`` pose) within
    ``max_range``."""
    out = []
    for ranges, (x, y, yaw) in zip(scans, poses, strict=True):
        step = 2 * math.pi / len(ranges)
        for i, r in enumerate(ranges):
            if r is not None and r <= max_range:
                a = yaw + i * step
                out.append((x + r * math.cos(a), y + r * math.sin(a)))
    return out


def simulate_spin(
    plan: dict,
    pose: Sequence[float],
    velocity: float,
    points: Sequence[tuple[float, float]],
    *,
    limits: RobotLimits = LIMITS,
    clearance: float = 0.02,
    dt: float = 0.05,
) -> tuple[bool, str]:
    """(True, "") if the plan plays out safely from ``pose`` (x, y, yaw in radians), else
    (False, why)."""
    x, y, yaw = (float(v) for v in pose)
    need = limits.radius + clearance

    def touching(px: float, py: float) -> float | None:
        for qx, qy in points:
            d = math.hypot(qx - px, qy - py)
            if d < need:
                return d
        return None

    # 1. brake to a stop along the heading
    v, t = max(0.0, velocity), 0.0
    while v > 0.0:
        v = max(0.0, v - limits.accel * dt)
        x += v * math.cos(yaw) * dt
        y += v * math.sin(yaw) * dt
        t += dt
        d = touching(x, y)
        if d is not None:
            return False, f"braking for the stop touches an obstacle after {t:.2f} s ({d:.2f} m)"
    if touching(x, y) is not None:
        return False, "no room to turn at the stop"
    rotation = float(plan.get("rotation", 0.0))
    if rotation <= 0.0:
        return True, ""
    rate = float(plan.get("angular_velocity", 0.0))
    if rate <= 0.0 or rate > limits.spin_rate_max:
        return False, f"turn rate {rate} deg/s outside (0, {limits.spin_rate_max}]"
    # 2. the sweep, step by step (a round footprint turns in place without sweeping new ground,
    # but the check is written for the footprint's outline, so another robot shape would do)
    heading, elapsed = 0.0, 0.0
    reach = limits.radius + clearance
    near = [(qx, qy) for qx, qy in points if math.hypot(qx - x, qy - y) <= reach]
    outline = [
        (limits.radius * math.cos(k * math.pi / 8), limits.radius * math.sin(k * math.pi / 8))
        for k in range(16)
    ]
    for target in sweep_targets(rotation):
        while abs(target - heading) > 1e-9:
            turn = max(-rate * dt, min(rate * dt, target - heading))
            heading += turn
            elapsed += dt * abs(turn) / (rate * dt)
            a = yaw + math.radians(heading)
            for ox, oy in outline:
                px = x + ox * math.cos(a) - oy * math.sin(a)
                py = y + ox * math.sin(a) + oy * math.cos(a)
                if any(math.hypot(qx - px, qy - py) < clearance for qx, qy in near):
                    return False, f"the sweep touches an obstacle at {heading:.0f} deg"
    planned = float(plan.get("spin_duration", 0.0))
    if elapsed > planned + 1e-6:
        return False, f"the sweep takes {elapsed:.2f} s, more than the planned {planned:.2f} s"
    return True, ""
