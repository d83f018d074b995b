"""The TurtleBot 4 LiDAR-occlusion demonstrator: MAPLE-K components and the
simulated managed system.

The robot follows waypoints through a room with obstacles; debris on the scanner blocks a sector
of its LiDAR, and its local planner cannot avoid what it does not see. The managing system
finds the blocked sectors in the scans and has the robot stop now and then and turn so that its
clear sectors look where the debris is (``/spin_config``), after checking by inline simulation
that the manoeuvre is safe.

The domain code lives in the ``tb4`` package beside this file; see its docstring.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from rasm import Action, Plan

_HERE = str(Path(__file__).resolve().parent)
if _HERE not in sys.path:  # the app folder holds the tb4 package
    sys.path.insert(0, _HERE)

from tb4.clearance import UNSEEN, SeenSpace, clearance  # noqa: E402
from tb4.legitimacy import map_points, simulate_spin  # noqa: E402
from tb4.navigation import LIMITS  # noqa: E402
from tb4.occlusion import Window, detect  # noqa: E402
from tb4.simulator import TurtleBotSimulator  # noqa: E402
from tb4.spin import mask_of, required_rotation, spin_plan  # noqa: E402

__all__ = [
    "RosScanMonitor",
    "RosSpinExecute",
    "RosSpinLegitimate",
    "ScanMonitor",
    "SpinExecute",
    "SpinLegitimate",
    "SpinPlan",
    "TurtleBotSimulator",
]

MARGIN_RAYS = 5  # a sector counts as seen when a ray at least this far from the debris sees it


class ScanMonitor:
    """The scans are in knowledge (Telegraf stores ``/safe-scan``, or ``/scan`` over ROS 2).
    Monitor adds what the latest scans show: how many rays of the last scan came back empty,
    the nearest echo, and the occlusion over the last ``WINDOW`` scans for the Analyse chart
    (``statecharts/analyse.yaml``).

    The occlusion: the probability per ray that it is blocked, thresholded and clustered into
    windows (``tb4.occlusion``). ``occlusion`` is ``unknown`` until ``WINDOW`` scans are in,
    then ``clear`` (no window), ``covered`` (the spin plan in force, echoed by the robot as
    ``spin_rotation``, already looks into every window) or ``uncovered``.

    The clearance: how far the robot can drive straight ahead through space that the last
    ``MEMORY`` scans saw free (``tb4.clearance``). The ``keeps_clearance`` property compares
    it with the robot's speed, and the Analyse chart adapts on its robustness.
    """

    WINDOW = 10  # scans (2 s at 5 Hz)
    THRESHOLD = 0.7
    MIN_RAYS = 3
    MEMORY = 50  # scans (10 s) the clearance remembers: the history of ``ranges``

    def monitor(self, ctx):
        k = ctx.knowledge
        ranges = k.read_knowledge("ranges")
        if not ranges:
            return None
        valid = [r for r in ranges if r is not None and r < math.inf]  # inf: ROS's "no echo"
        signals = {
            "invalid_rays": len(ranges) - len(valid),
            "nearest": min(valid) if valid else -1.0,
            "rays": len(ranges),
            **self._clearance(k),
        }
        scans = [s.value for s in k.history("ranges", last=self.WINDOW)]
        if len(scans) < self.WINDOW:
            return {**signals, "occlusion": "unknown", "occluded_windows": [],
                    "occluded_sectors": ""}
        windows = detect(scans, self.THRESHOLD, self.MIN_RAYS)
        signals["occluded_windows"] = [[w.start, w.length] for w in windows]
        signals["occluded_sectors"] = ", ".join(
            "{1:.0f} deg wide at {0:.0f} deg".format(*w.degrees(len(ranges))) for w in windows
        )
        signals["occlusion"] = _occlusion(windows, len(ranges), k.read_knowledge("spin_rotation"))
        return signals

    def _clearance(self, k) -> dict:
        """``clearance`` (m seen free straight ahead), ``clearance_ahead`` (the same from where
        the robot will be in ``AHEAD`` seconds at its present speed and turn rate) and
        ``clearance_unseen`` (what ends the shorter of the two is space no scan has seen, not
        an echo). 0 before the robot's pose is known (fail closed: what is not known to be
        free is not)."""
        scans = k.history("ranges", last=self.MEMORY)[::-1]
        poses = k.history("scan_pose", last=self.MEMORY)[::-1]
        if k.read_knowledge("x") is None or not poses:
            return {"clearance": 0.0, "clearance_ahead": 0.0, "clearance_unseen": True}
        n = min(len(scans), len(poses))
        pose = (k.read_knowledge("x"), k.read_knowledge("y"), math.radians(k.read_knowledge("yaw")))
        return self._measure(k, pose, [s.value for s in scans[:n]], [p.value for p in poses[:n]])

    AHEAD = 0.5  # s

    def _measure(self, k, pose, scans, poses) -> dict:
        v = k.read_knowledge("velocity", 0.0) or 0.0
        w = k.read_knowledge("yaw_rate", 0.0) or 0.0
        x, y, yaw = pose
        turn = w * self.AHEAD
        later = (x + v * self.AHEAD * math.cos(yaw + turn / 2),
                 y + v * self.AHEAD * math.sin(yaw + turn / 2), yaw + turn)
        space = SeenSpace(scans, poses)
        now, limit_now = clearance(pose, space)
        ahead, limit_ahead = clearance(later, space)
        return {"clearance": now, "clearance_ahead": ahead,
                "clearance_unseen": (limit_ahead if ahead < now else limit_now) == UNSEEN}


class RosScanMonitor(ScanMonitor):
    """:class:`ScanMonitor` for the robot on ROS 2 (``ros2.yaml``): a LaserScan carries no pose,
    so the clearance places each scan at the odometry pose of its time stamp, as
    :class:`RosSpinLegitimate` does."""

    def _clearance(self, k) -> dict:
        odometry = _odometry(k)
        if not odometry:
            return {"clearance": 0.0, "clearance_ahead": 0.0, "clearance_unseen": True}
        # only scans the odometry covers: one placed at a wrong pose would show free space
        # that was never seen
        scans = [s for s in k.history("ranges", last=self.MEMORY)[::-1]
                 if s.time >= odometry[0][0] - 1e-9]
        poses = [_pose_at(odometry, s.time) for s in scans]
        return self._measure(k, _pose_at(odometry, math.inf), [s.value for s in scans], poses)


def _occlusion(windows, rays, spin_rotation):
    """``clear``, ``covered`` or ``uncovered``: whether the sweep in force (degrees) looks
    into every window."""
    if not windows:
        return "clear"
    need = required_rotation(mask_of(windows, rays), MARGIN_RAYS)
    active = float(spin_rotation or 0.0)
    if need is not None and active + 1e-9 >= need * 360.0 / rays:
        return "covered"
    return "uncovered"


class SpinPlan:
    """Stops and rotations covering every occluded window (see ``tb4.spin``); after a rejection,
    a gentler turn rate."""

    ANGULAR_VELOCITY = 90.0  # deg/s

    def plan(self, ctx):
        data = ctx.anomaly.data
        rays = int(data["rays"])
        windows = [Window(int(s), int(n)) for s, n in data["windows"]]
        rate = self.ANGULAR_VELOCITY * 0.75 ** len(ctx.rejections)
        values = spin_plan(
            windows, rays, angular_velocity=round(rate, 3), cruise=LIMITS.cruise, margin=MARGIN_RAYS
        )
        if values is None:
            return None
        values["occluded"] = round(sum(w.length for w in windows) * 360.0 / rays, 1)
        if values["rotation"] == 0:
            why = "no occlusion left: drive without stops"
        else:
            why = (
                f"{ctx.anomaly.reason}; stop every {values['stop_every']} s and look "
                f"±{values['rotation']} deg at {values['angular_velocity']} deg/s "
                f"({values['spin_duration']} s)"
            )
        return Plan(values, explanation=why)


class SpinLegitimate:
    """Inline simulation on the current map (the hit points of the last scans): braking to the
    stop and the sweep must keep clear of obstacles, and the sweep must fit its duration."""

    SCANS = 5

    def legitimate(self, ctx):
        k = ctx.knowledge
        scans = [s.value for s in k.history("ranges", last=self.SCANS)]
        poses = [s.value for s in k.history("scan_pose", last=self.SCANS)]
        n = min(len(scans), len(poses))
        points = map_points(scans[len(scans) - n :], poses[len(poses) - n :])
        pose = (
            k.read_knowledge("x", 0.0),
            k.read_knowledge("y", 0.0),
            math.radians(k.read_knowledge("yaw", 0.0)),
        )
        return simulate_spin(dict(ctx.plan.values), pose, k.read_knowledge("velocity", 0.0), points)


class RosSpinLegitimate(SpinLegitimate):
    """:class:`SpinLegitimate` for the robot on ROS 2 (``ros2.yaml``): a LaserScan carries no
    pose, so each scan is placed at the odometry pose of its time stamp (both are stamped by
    the robot's clock), the heading taken from the orientation quaternion."""

    def legitimate(self, ctx):
        k = ctx.knowledge
        poses = _odometry(k)
        if not poses:
            return False, "no odometry yet: the robot's pose is unknown"
        scans = k.history("ranges", last=self.SCANS)
        points = map_points([s.value for s in scans], [_pose_at(poses, s.time) for s in scans])
        pose = _pose_at(poses, math.inf)
        return simulate_spin(dict(ctx.plan.values), pose, k.read_knowledge("velocity", 0.0), points)


def _odometry(k):
    """[(time, (x, y, yaw in radians))] of the recent odometry, oldest first: the times at
    which all of x, y and the quaternion's z and w were stored (one /odom message each)."""
    series = [{s.time: s.value for s in k.history(key, last=100)} for key in ("x", "y", "qz", "qw")]
    xs, ys, qzs, qws = series
    times = sorted(set(xs).intersection(ys, qzs, qws))
    return [(t, (xs[t], ys[t], 2.0 * math.atan2(qzs[t], qws[t]))) for t in times]


def _pose_at(poses, time):
    """The pose of the last odometry at or before ``time`` (the first one if none is)."""
    chosen = poses[0][1]
    for at, pose in poses:
        if at > time + 1e-9:
            break
        chosen = pose
    return chosen


class SpinExecute:
    """One ``/spin_config`` message for the robot's controller plugin."""

    EFFECTOR = "spin_config"
    FIELDS = ("rotation", "angular_velocity", "stop_every", "spin_duration")

    def execute(self, ctx):
        return Action(self.EFFECTOR, {f: ctx.plan[f] for f in self.FIELDS})


class RosSpinExecute(SpinExecute):
    """The spin plan as a goal of the controller's ``/spin`` action (``ros2.yaml``)."""

    EFFECTOR = "spin"
