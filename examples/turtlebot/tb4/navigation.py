"""Navigation on the simulated robot: a local costmap, a local planner, the spin controller.

Like Nav2's local costmap, :class:`Costmap` only marks what the LiDAR saw nearby
(``mark_range``) and forgets marks after ``decay`` seconds (an obstacle layer with observation
persistence): what a ray blocked by debris does not see is not avoided. :class:`LocalPlanner`
drives towards the next waypoint along the freest heading of a small fan, slowing down in front of
marked obstacles. :class:`SpinController` plays the Nav2 controller plugin of the RoboSAPIENS
TurtleBot scenario: it inserts the stops and rotations of a ``/spin_config`` plan into the motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from .geometry import wrap

__all__ = ["Costmap", "LocalPlanner", "RobotLimits", "SpinController", "sweep_targets"]


@dataclass(frozen=True)
class RobotLimits:
    """The TurtleBot 4's body and motion limits used by the simulator and by Legitimate."""

    radius: float = 0.17  # m, round footprint
    cruise: float = 0.3  # m/s (the TurtleBot 4 tops at 0.31 m/s)
    accel: float = 1.0  # m/s^2, also the braking deceleration
    turn_rate: float = 1.0  # rad/s, local planner
    spin_rate_max: float = 90.0  # deg/s, allowed for spins (rules/turtlebot.yaml)


LIMITS = RobotLimits()


class Costmap:
    """Obstacle cells (``cell`` m) marked from scan hits within ``mark_range``, with decay."""

    def __init__(self, cell: float = 0.05, mark_range: float = 2.0, decay: float = 8.0) -> None:
        self.cell = cell
        self.mark_range = mark_range
        self.decay = decay
        self.cells: dict[tuple[int, int], float] = {}

    def mark(self, x: float, y: float, yaw: float, ranges: list[float | None], time: float) -> None:
        """Mark the hits of one scan taken at pose ``(x, y, yaw)``."""
        step = 2 * math.pi / len(ranges)
        c = self.cell
        for i, r in enumerate(ranges):
            if r is None or r > self.mark_range:
                continue
            a = yaw + i * step
            self.cells[(int((x + r * math.cos(a)) // c), int((y + r * math.sin(a)) // c))] = time

    def mark_point(self, px: float, py: float, time: float) -> None:
        """Mark one point (a bumper contact)."""
        self.cells[(int(px // self.cell), int(py // self.cell))] = time

    def points_near(
        self, x: float, y: float, radius: float, time: float
    ) -> list[tuple[float, float]]:
        """Centres of the live cells within ``radius`` of ``(x, y)``; expired cells are dropped."""
        c, r2 = self.cell, radius * radius
        out, expired = [], []
        for key, seen in self.cells.items():
            if time - seen > self.decay:
                expired.append(key)
                continue
            px, py = (key[0] + 0.5) * c, (key[1] + 0.5) * c
            if (px - x) ** 2 + (py - y) ** 2 <= r2:
                out.append((px, py))
        for key in expired:
            del self.cells[key]
        return out


def free_distance(
    x: float,
    y: float,
    heading: float,
    points: list[tuple[float, float]],
    half_width: float,
    horizon: float,
) -> float:
    """How far the robot can go along ``heading`` before a point enters its swept corridor."""
    ch, sh = math.cos(heading), math.sin(heading)
    best = horizon
    for px, py in points:
        dx, dy = px - x, py - y
        forward = dx * ch + dy * sh
        if 0.0 < forward < best and abs(dy * ch - dx * sh) < half_width:
            best = forward
    return best


@dataclass
class LocalPlanner:
    """Goal-directed reactive planner over a fan of headings (a DWA in miniature)."""

    limits: RobotLimits = LIMITS
    margin: float = 0.05  # clearance added to the radius for the corridor
    horizon: float = 1.5  # m looked ahead
    stop_at: float = 0.35  # m: free distance under which the robot does not advance
    fan: tuple[float, ...] = tuple(math.radians(d) for d in range(-90, 91, 10))

    def command(
        self,
        pose: tuple[float, float, float],
        goal: tuple[float, float],
        points: list[tuple[float, float]],
    ) -> tuple[float, float]:
        """(linear m/s, angular rad/s) towards ``goal`` avoiding ``points``."""
        x, y, yaw = pose
        bearing = wrap(math.atan2(goal[1] - y, goal[0] - x) - yaw)
        half = self.limits.radius + self.margin
        best, best_score, ahead = 0.0, -math.inf, self.horizon
        for phi in self.fan:
            free = free_distance(x, y, yaw + phi, points, half, self.horizon)
            if phi == 0.0:
                ahead = free
            if free < self.stop_at + 0.1:
                continue
            score = math.cos(phi - bearing) + 0.6 * free / self.horizon - 0.1 * abs(phi)
            if score > best_score:
                best, best_score = phi, score
        if best_score == -math.inf:  # boxed in: turn on the spot towards the goal
            return 0.0, math.copysign(self.limits.turn_rate, bearing or 1.0)
        w = max(-self.limits.turn_rate, min(self.limits.turn_rate, 2.0 * best))
        slow = max(0.0, min(1.0, (ahead - self.stop_at) / 0.5))
        v = self.limits.cruise * max(0.0, math.cos(best)) * slow
        if abs(best) > math.radians(60):
            v = 0.0
        return v, w


def sweep_targets(rotation_deg: float) -> list[float]:
    """Headings (deg, relative to the heading at the stop) a spin visits: look left, look
    right, face ahead again."""
    return [rotation_deg, -rotation_deg, 0.0]


@dataclass
class SpinController:
    """Inserts a spin plan into the motion: after every ``stop_every`` seconds of driving, stop,
    sweep ``+rotation``, ``-rotation``, back to the heading, at ``angular_velocity`` deg/s,
    holding each end of the sweep for ``dwell`` seconds: one scan period, so that a scan is
    taken there (at 90 deg/s the scans taken while turning are 18 deg apart, and the ends of the
    sweep, which show what lies straight ahead, would often go unscanned).

    A new plan starts with a spin at once (the occlusion was just found); ``rotation == 0``
    cancels spinning.
    """

    rotation: float = 0.0
    angular_velocity: float = 0.0
    stop_every: float = 0.0
    plan: str = ""
    driven: float = 0.0
    targets: list[float] = field(default_factory=list)
    base_yaw: float = 0.0
    spins: int = 0
    dwell: float = 0.2
    holding: float = 0.0

    def configure(self, payload: dict, yaw: float) -> None:
        self.rotation = float(payload.get("rotation", 0.0))
        self.angular_velocity = float(payload.get("angular_velocity", 0.0))
        self.stop_every = float(payload.get("stop_every", 0.0))
        self.plan = str(payload.get("plan", ""))
        self.targets = []
        self.holding = 0.0
        if self.active:
            self.driven = self.stop_every  # spin at once: the next step brakes for it

    @property
    def active(self) -> bool:
        return self.rotation > 0 and self.angular_velocity > 0

    @property
    def spinning(self) -> bool:
        return bool(self.targets)

    def drove(self, dt: float) -> None:
        """Account ``dt`` seconds of driving."""
        if self.active:
            self.driven += dt

    def spins_now(self, yaw: float) -> bool:
        """Whether this step belongs to a spin: one under way, or one due now, which starts from
        heading ``yaw`` (radians)."""
        if self.active and not self.targets and self.driven >= self.stop_every:
            self.targets = sweep_targets(self.rotation)
            self.base_yaw = yaw
            self.driven = 0.0
            self.spins += 1
        return self.spinning

    def turn(self, yaw: float, dt: float) -> float:
        """Angular velocity (rad/s) for this step of a spin; pops reached targets."""
        rate = math.radians(self.angular_velocity)
        while self.targets:
            if self.holding > 1e-9:
                self.holding -= dt
                return 0.0
            error = wrap(self.base_yaw + math.radians(self.targets[0]) - yaw)
            if abs(error) > 1e-6:
                return max(-rate, min(rate, error / dt))
            if self.targets.pop(0) != 0.0:  # an end of the sweep
                self.holding = self.dwell
        return 0.0
