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

from rasm import Action, Anomaly, Plan

_HERE = str(Path(__file__).resolve().parent)
if _HERE not in sys.path:  # the app folder holds the tb4 package
    sys.path.insert(0, _HERE)

from tb4.legitimacy import map_points, simulate_spin  # noqa: E402
from tb4.navigation import LIMITS  # noqa: E402
from tb4.occlusion import Window, detect  # noqa: E402
from tb4.simulator import TurtleBotSimulator  # noqa: E402
from tb4.spin import mask_of, required_rotation, spin_plan  # noqa: E402

__all__ = [
    "OcclusionAnalyse",
    "RosSpinLegitimate",
    "ScanMonitor",
    "SpinExecute",
    "SpinLegitimate",
    "SpinPlan",
    "TurtleBotSimulator",
]

MARGIN_RAYS = 5  # a sector counts as seen when a ray at least this far from the debris sees it


class ScanMonitor:
    """The scans are in knowledge (Telegraf stores ``/safe-scan``, or ``/scan`` over ROS 2);
    Monitor adds two signals of the latest scan for the trace: how many rays came back empty
    and the nearest echo."""

    def monitor(self, ctx):
        ranges = ctx.knowledge.read_knowledge("ranges")
        if not ranges:
            return None
        valid = [r for r in ranges if r is not None and r < math.inf]  # inf: ROS's "no echo"
        return {
            "invalid_rays": len(ranges) - len(valid),
            "nearest": min(valid) if valid else -1.0,
        }


class OcclusionAnalyse:
    """Occlusion probability per ray over the last ``WINDOW`` scans, thresholded and clustered.

    An anomaly when the windows found are not covered by the spin plan in force (the robot
    echoes it as ``spin_rotation``), or when the occlusion is gone and a plan is still in force.
    After raising one, Analyse waits ``SETTLE`` seconds for the robot to take the plan up.
    """

    WINDOW = 10  # scans (2 s at 5 Hz)
    THRESHOLD = 0.7
    MIN_RAYS = 3
    SETTLE = 1.0

    def __init__(self) -> None:
        self.raised_at = -math.inf

    def analyse(self, ctx):
        k = ctx.knowledge
        scans = [s.value for s in k.history("ranges", last=self.WINDOW)]
        if len(scans) < self.WINDOW or k.read_knowledge("nav_mode") == "arrived":
            return None
        if ctx.time - self.raised_at < self.SETTLE:
            return None
        rays = len(scans[-1])
        windows = detect(scans, self.THRESHOLD, self.MIN_RAYS)
        active = float(k.read_knowledge("spin_rotation", 0.0))
        data = {"windows": [[w.start, w.length] for w in windows], "rays": rays}
        if not windows:
            if active > 0.0:
                self.raised_at = ctx.time
                return Anomaly("the LiDAR is clear again: stop spinning", data)
            return None
        need = required_rotation(mask_of(windows, rays), MARGIN_RAYS)
        if need is not None and active + 1e-9 >= need * 360.0 / rays:
            return None  # the plan in force already covers every window
        self.raised_at = ctx.time
        described = []
        for w in windows:
            centre, width = w.degrees(rays)
            described.append(f"{width:.0f} deg wide at {centre:.0f} deg")
        sectors = ", ".join(described)
        return Anomaly(f"LiDAR occluded: {sectors}", data)


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

    FIELDS = ("rotation", "angular_velocity", "stop_every", "spin_duration")

    def execute(self, ctx):
        return Action("spin_config", {f: ctx.plan[f] for f in self.FIELDS})
