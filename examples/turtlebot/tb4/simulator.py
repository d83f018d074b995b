"""The managed system: a simulated TurtleBot 4 following waypoints with a LiDAR that debris
occludes. It publishes ``/safe-scan``, ``/odom`` and ``/collision`` and accepts spin plans on
``/spin_config`` (see ``app.yaml``); as a ROS 2 robot (``robot.py``) it also takes velocity
commands, as a base controller takes ``/cmd_vel``. Deterministic for a seed.
"""

from __future__ import annotations

import math
import random
from typing import Any

from .geometry import distance_to
from .lidar import Lidar, occluded_rays
from .navigation import LIMITS, Costmap, LocalPlanner, SpinController
from .world import World

__all__ = ["TurtleBotSimulator"]


class TurtleBotSimulator:
    """Differential drive on a 2D map; scans at ``scan_rate`` Hz; counts collisions."""

    def __init__(self, scenario: dict[str, Any] | None = None, seed: int = 0) -> None:
        scenario = scenario or {}
        self.world = World.from_scenario(scenario)
        self.rng = random.Random(seed)
        lidar = dict(scenario.get("lidar", {}))
        self.scan_rate = float(lidar.pop("rate", 5.0))
        self.lidar = Lidar(**lidar)
        self.limits = LIMITS
        self.costmap = Costmap()
        self.planner = LocalPlanner()
        self.spin = SpinController()
        x, y, yaw = self.world.start
        self.x, self.y, self.yaw = x, y, math.radians(yaw)
        self.v = 0.0
        self.w = 0.0
        self.waypoint = 0
        self.arrived_at: float | None = None
        self.collisions = 0
        self.in_contact = False
        self.next_scan = 0.0
        # a velocity command (v m/s, w rad/s, until when) overriding the local planner
        self.command: tuple[float, float, float] | None = None
        self.mask_key: tuple = ()
        self.mask = [False] * self.lidar.rays

    # ------------------------------------------------------------------ the managed system

    @property
    def mode(self) -> str:
        if self.arrived_at is not None:
            return "arrived"
        return "spin" if self.spin.spinning else "navigate"

    def _occlusion(self, time: float) -> list[bool]:
        windows = tuple((d.center, d.width) for d in self.world.debris if d.active(time))
        if windows != self.mask_key:
            self.mask_key = windows
            self.mask = occluded_rays(list(windows), self.lidar.rays)
        return self.mask

    def step(self, time: float, dt: float) -> dict[str, dict[str, Any]]:
        """Advance ``dt`` seconds from ``time``; return the messages to publish."""
        out: dict[str, dict[str, Any]] = {}
        if time + 1e-9 >= self.next_scan:
            self.next_scan = time + 1.0 / self.scan_rate - 1e-9
            ranges = self.lidar.scan(
                self.x, self.y, self.yaw, self.world.shapes, self._occlusion(time), self.rng
            )
            self.costmap.mark(self.x, self.y, self.yaw, ranges, time)
            out["/safe-scan"] = {
                "ranges": ranges,
                "scan_pose": [round(self.x, 4), round(self.y, 4), round(self.yaw, 5)],
            }
        self._control(time, dt)
        if self._move(dt, time):
            out["/collision"] = {"collision": True, "collisions": self.collisions}
        out["/odom"] = {
            "x": round(self.x, 4),
            "y": round(self.y, 4),
            "yaw": round(math.degrees(self.yaw), 3),
            "velocity": round(self.v, 4),
            "yaw_rate": round(self.w, 4),
            "nav_mode": self.mode,
            "waypoint": self.waypoint,
            "spin_plan": self.spin.plan,
            "spin_rotation": self.spin.rotation if self.spin.active else 0.0,
            "spins": self.spin.spins,
            "debris": len(self.mask_key),
        }
        return out

    def _control(self, time: float, dt: float) -> None:
        lim = self.limits
        if self.arrived_at is not None:
            v_cmd, w_cmd = 0.0, 0.0
        elif self.command is not None and time < self.command[2]:
            v_cmd = min(max(self.command[0], 0.0), lim.cruise)
            w_cmd = min(max(self.command[1], -lim.turn_rate), lim.turn_rate)
        elif self.spin.spins_now(self.yaw):
            v_cmd = 0.0
            w_cmd = self.spin.turn(self.yaw, dt) if self.v == 0.0 else 0.0
        else:
            goal = self.world.waypoints[self.waypoint]
            if math.hypot(goal[0] - self.x, goal[1] - self.y) < 0.25:
                if self.waypoint + 1 == len(self.world.waypoints):
                    self.arrived_at = time
                    self.v = self.w = 0.0
                    return
                self.waypoint += 1
                goal = self.world.waypoints[self.waypoint]
            points = self.costmap.points_near(self.x, self.y, self.planner.horizon + 0.3, time)
            v_cmd, w_cmd = self.planner.command((self.x, self.y, self.yaw), goal, points)
            self.spin.drove(dt)
        dv = max(-lim.accel * dt, min(lim.accel * dt, v_cmd - self.v))
        self.v = max(0.0, self.v + dv)
        if abs(self.v) < 1e-9:
            self.v = 0.0
        self.w = w_cmd

    def _move(self, dt: float, time: float) -> bool:
        """Integrate the unicycle; on contact, stay put, mark the bump; True on a new collision."""
        x = self.x + self.v * math.cos(self.yaw) * dt
        y = self.y + self.v * math.sin(self.yaw) * dt
        self.yaw = math.atan2(math.sin(self.yaw + self.w * dt), math.cos(self.yaw + self.w * dt))
        r = self.limits.radius
        hit = any(distance_to(x, y, s) < r for s in self.world.shapes)
        if not hit:
            self.x, self.y = x, y
            self.in_contact = False
            return False
        # the bumper: stop, and the contact point goes into the costmap like an obstacle
        self.costmap.mark_point(x + r * math.cos(self.yaw), y + r * math.sin(self.yaw), time)
        self.v = 0.0
        new = not self.in_contact
        self.in_contact = True
        if new:
            self.collisions += 1
        return new

    COMMAND_TIMEOUT = 0.5  # s a velocity command holds, as a base controller's cmd_vel timeout

    def apply(self, effector: str, payload: dict[str, Any], time: float) -> None:
        """An action from the Trustworthiness Checker (``spin_config``), or a velocity command
        (``cmd_vel``: ``velocity`` m/s and ``yaw_rate`` rad/s, within the robot's limits) that
        overrides the local planner for :data:`COMMAND_TIMEOUT` seconds."""
        if effector == "spin_config":
            self.spin.configure(payload, self.yaw)
        elif effector == "cmd_vel":
            until = time + self.COMMAND_TIMEOUT
            self.command = (float(payload["velocity"]), float(payload["yaw_rate"]), until)
