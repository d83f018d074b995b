"""The simulated TurtleBot 4 as a ROS 2 robot of its own, over Zenoh or Cyclone DDS.

    python examples/turtlebot/robot.py zenoh://127.0.0.1:7447   # listens there, as rmw_zenohd
    python examples/turtlebot/robot.py dds://?domain=0

It runs the simulator of ``tb4`` on the wall clock (the world and debris of ``app.yaml``'s
scenario) and speaks ROS 2 as a robot does:

- publishes ``sensor_msgs/msg/LaserScan`` on ``/scan`` (5 Hz; ``inf`` where nothing came
  back), ``nav_msgs/msg/Odometry`` on ``/odom`` and its ``turtlebot/msg/RobotState`` on
  ``/robot_state`` (10 Hz), and ``std_msgs/msg/Bool`` on ``/collision`` when its bumper fires,
  all stamped with its clock;
- takes spin plans (``turtlebot/msg/SpinConfig``, from ``msg/``) on ``/spin_config`` and
  velocity commands (``geometry_msgs/msg/Twist``) on ``/cmd_vel``, which override its local
  planner for half a second; ``std_msgs/msg/Bool`` true on ``/dock_command`` docks it: it
  leaves its route and stays parked. (``controller.py`` serves the ``/spin`` action and the
  ``/dock`` service on top of these, as a Nav2 controller does.)

Over Zenoh it listens on ``HOST:PORT``: the managing side (``rasm run examples/turtlebot/
ros2.yaml``) and ROS 2 tools connect to it there. It prints ``ready`` once its topics exist and
stops after ``--duration`` seconds, on Ctrl-C or on SIGTERM.
"""

from __future__ import annotations

import argparse
import json
import math
import queue
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:  # the app folder holds the tb4 package
    sys.path.insert(0, str(HERE))

from tb4.simulator import TurtleBotSimulator  # noqa: E402

from rasm.comm import Message, Transport, open_transport  # noqa: E402
from rasm.platform.manifest import load_manifest  # noqa: E402
from rasm.platform.messages import app_type_store  # noqa: E402

PERIOD = 0.1  # s per simulator step, as app.yaml's managed_system.period
TOPICS = {
    "/scan": "sensor_msgs/msg/LaserScan",
    "/odom": "nav_msgs/msg/Odometry",
    "/robot_state": "turtlebot/msg/RobotState",
    "/collision": "std_msgs/msg/Bool",
    "/spin_config": "turtlebot/msg/SpinConfig",
    "/cmd_vel": "geometry_msgs/msg/Twist",
    "/dock_command": "std_msgs/msg/Bool",
}
PARKED = {"velocity": 0.0, "yaw_rate": 0.0}  # a docked robot's command, every step


def header(stamp: float, frame: str) -> dict[str, Any]:
    ns = round(stamp * 1e9)
    return {"stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9}, "frame_id": frame}


def ros_messages(
    readings: dict[str, dict[str, Any]], stamp: float, robot: TurtleBotSimulator
) -> dict[str, dict[str, Any]]:
    """The simulator's readings of one step as ROS 2 messages, topic -> message."""
    out: dict[str, dict[str, Any]] = {}
    scan = readings.get("/safe-scan")
    if scan is not None:
        step = 2 * math.pi / len(scan["ranges"])
        out["/scan"] = {
            "header": header(stamp, "base_scan"),
            "angle_min": 0.0,
            "angle_max": 2 * math.pi - step,
            "angle_increment": step,
            "range_min": robot.lidar.range_min,
            "range_max": robot.lidar.max_range,
            "ranges": [math.inf if r is None else r for r in scan["ranges"]],
        }
    odom = readings["/odom"]
    yaw = math.radians(odom["yaw"])
    out["/odom"] = {
        "header": header(stamp, "odom"),
        "child_frame_id": "base_link",
        "pose": {"pose": {
            "position": {"x": odom["x"], "y": odom["y"]},
            "orientation": {"z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
        }},
        "twist": {"twist": {"linear": {"x": odom["velocity"]}, "angular": {"z": odom["yaw_rate"]}}},
    }
    out["/robot_state"] = {
        "header": header(stamp, "base_link"),
        **{key: odom[key] for key in ("nav_mode", "waypoint", "spin_plan", "spin_rotation",
                                      "spins", "debris")},
        "collisions": robot.collisions,
    }
    if "/collision" in readings:
        out["/collision"] = {"data": True}
    return out


def open_robot_transport(url: str) -> Transport:
    store = app_type_store(HERE)
    options: dict[str, Any] = {"types": TOPICS, "store": store, "node_name": "turtlebot"}
    if url.startswith("zenoh://"):
        from rasm.ros2.zenoh import parse_zenoh_url

        host, port, _ = parse_zenoh_url(url)
        options["listen"] = [f"tcp/{host}:{port}"]
    return open_transport(url, **options)


def run(url: str, *, seed: int, duration: float | None, stop: threading.Event) -> int:
    scenario = load_manifest(HERE).scenario
    robot = TurtleBotSimulator(scenario, seed=seed)
    commands: queue.Queue[tuple[str, dict[str, Any]]] = queue.Queue()
    transport = open_robot_transport(url)
    # commands arrive on the transport's thread; the simulator takes them between its steps
    transport.subscribe("/spin_config", lambda m: commands.put(("spin_config", m.payload)))
    transport.subscribe("/cmd_vel", lambda m: commands.put(("cmd_vel", twist(m))))
    docked = threading.Event()
    transport.subscribe("/dock_command", lambda m: docked.set() if m.payload["data"] else None)
    transport.connect()
    try:
        for topic in ("/scan", "/odom", "/robot_state", "/collision"):
            transport.advertise(topic)
        print("ready", flush=True)
        start = time.monotonic()
        wall = time.time() - start  # wall-clock stamps on the monotonic timeline
        step = 0
        while not stop.is_set():
            now = step * PERIOD
            if duration is not None and now >= duration:
                break
            while not commands.empty():
                effector, payload = commands.get()
                robot.apply(effector, payload, now)
            if docked.is_set():
                robot.apply("cmd_vel", PARKED, now)
            readings = robot.step(now, PERIOD)
            for topic, message in ros_messages(readings, start + wall + now, robot).items():
                transport.publish(topic, message)
            step += 1
            stop.wait(max(0.0, start + step * PERIOD - time.monotonic()))
    finally:
        transport.close()
    print(json.dumps({"collisions": robot.collisions, "spins": robot.spin.spins,
                      "docked": docked.is_set()}), flush=True)
    return 0


def twist(message: Message) -> dict[str, float]:
    """A Twist as the simulator's velocity command."""
    return {
        "velocity": message.payload["linear"]["x"],
        "yaw_rate": message.payload["angular"]["z"],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("transport", help="zenoh://HOST:PORT[?domain=N] or dds://[?domain=N]")
    parser.add_argument("--seed", type=int, default=0, help="the simulator's seed (default 0)")
    parser.add_argument("--duration", type=float, default=None, help="seconds to run")
    args = parser.parse_args(argv)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        return run(args.transport, seed=args.seed, duration=args.duration, stop=stop)
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
