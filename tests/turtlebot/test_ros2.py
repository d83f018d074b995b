"""The demonstrator over ROS 2: its robot (examples/turtlebot/robot.py) as a process of its own
speaking Zenoh or Cyclone DDS and its Nav2-style controller (examples/turtlebot/controller.py:
eclipse-zenoh and rosbags only) serving the /spin action and the /dock service, managed by a
plain `rasm run ros2.yaml --transport …`; foreign peers (tests/ros2/peer.py: eclipse-zenoh,
cyclonedds and rosbags only) watch the topics and drive the robot."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading

import pytest

from rasm.testing.servers import free_port
from tests.ros2.conftest import CYCLONE_LOOPBACK, wait_until
from tests.ros2.test_run import finish, rasm_run

from .conftest import APP

ROBOT = APP / "robot.py"
CONTROLLER = APP / "controller.py"
MSG = [[str(path), "turtlebot"] for path in sorted((APP / "msg").glob("*.msg"))]


class Robot:
    """A running robot.py (or ``script``, the controller); ``ready`` once its topics exist."""

    def __init__(self, url: str, duration: float, script=ROBOT) -> None:
        env = dict(os.environ, CYCLONEDDS_URI=CYCLONE_LOOPBACK, PYTHONUNBUFFERED="1")
        self.process = subprocess.Popen(
            [sys.executable, str(script), url, "--duration", str(duration)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        )
        self.lines: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()
        wait_until(lambda: "ready" in self.lines or self.process.poll() is not None,
                   what="the robot to start")
        assert "ready" in self.lines, self.process.stderr.read()

    def _read(self) -> None:
        for line in self.process.stdout:
            self.lines.append(line.strip())

    def stop(self) -> dict:
        self.process.terminate()
        self.process.wait(timeout=20)
        wait_until(lambda: self.lines and self.lines[-1].startswith("{"), what="its summary")
        return json.loads(self.lines[-1])


def ros_network(peers, middleware: str, watch: list[dict], duration: float = 30):
    """The robot, a foreign peer subscribed to ``watch``, and the URL rasm joins them by."""
    if middleware == "zenoh":
        port = free_port()
        url = f"zenoh://127.0.0.1:{port}"
        robot = Robot(url, duration)  # it listens there, as rmw_zenoh's router would
        watcher = peers({"middleware": "zenoh", "role": "sub",
                         "listen": f"tcp/127.0.0.1:{free_port()}",
                         "connect": [f"tcp/127.0.0.1:{port}"], "msg": MSG, "topics": watch})
        return robot, watcher, url
    domain = int.from_bytes(os.urandom(1), "big") % 200 + 20
    url = f"dds://?domain={domain}"
    robot = Robot(url, duration)
    watcher = peers({"middleware": "dds", "role": "sub", "domain": domain, "msg": MSG,
                     "topics": watch})
    return robot, watcher, url


@pytest.mark.slow
def test_rasm_run_sends_the_spin_plan_as_a_goal_the_controller_has_the_robot_take(
    peers, tmp_path
):
    watch = [{"topic": "/spin_config", "type": "turtlebot/msg/SpinConfig"},
             {"topic": "/robot_state", "type": "turtlebot/msg/RobotState"},
             {"topic": "/rasm/verdict/velocity_limit", "type": "std_msgs/msg/Bool"}]
    robot, watcher, url = ros_network(peers, "zenoh", watch)
    controller = Robot(url, 30, CONTROLLER)
    try:
        watcher.wait_ready()
        trace = tmp_path / "trace.jsonl"
        run = rasm_run(APP / "ros2.yaml", url, tmp_path, "--duration", "7", "--trace", str(trace))
        code, output = finish(run)
    finally:
        summary = robot.stop()
        controller.process.terminate()
        controller.process.wait(timeout=20)
    assert code == 0, output  # every property of the demonstrator holds
    # the front debris (from the robot's first second) is answered by a spin plan: a goal of
    # the controller's /spin action, which hands it to the robot on /spin_config
    assert any(line.startswith("goal ") for line in controller.lines), controller.lines
    plan = watcher.wait_for(lambda p: p.messages("/spin_config"), what="a spin plan")[0]["data"]
    assert plan["rotation"] > 0 and 20 <= plan["angular_velocity"] <= 90
    # ... which the robot takes up: its state says so, and it sweeps
    wait_until(lambda: any(m["data"]["spin_rotation"] == plan["rotation"]
                           for m in watcher.messages("/robot_state")), what="the plan in force")
    assert summary["spins"] >= 1 and summary["collisions"] == 0 and not summary["docked"]
    assert {m["data"]["data"] for m in watcher.messages("/rasm/verdict/velocity_limit")} == {True}
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    # the goal succeeded once the plan was in force: its result and feedback are knowledge
    assert any(r.get("effector_done") == "spin" for r in records), output
    assert any(r.get("spin_in_force") == plan["rotation"] for r in records)
    assert any("controller_nav_mode" in r for r in records)
    assert "effector spin calls: 1 succeeded" in output
    scans = [r for r in records if r.get("invalid_rays")]
    assert scans and all(60 <= r["invalid_rays"] <= 200 for r in scans[-5:])  # inf: no echo
    assert any(r.get("nav_mode") == "spin" for r in records)


@pytest.mark.slow
def test_a_bump_engages_the_fallback_and_the_robot_docks_through_the_service(peers, tmp_path):
    watch = [{"topic": "/spin_config", "type": "turtlebot/msg/SpinConfig"}]
    robot, watcher, url = ros_network(peers, "zenoh", watch)
    controller = Robot(url, 30, CONTROLLER)
    try:
        watcher.wait_ready()
        trace = tmp_path / "trace.jsonl"
        run = rasm_run(APP / "ros2.yaml", url, tmp_path, "--duration", "7", "--trace", str(trace))
        watcher.wait_for(lambda p: p.messages("/spin_config"), timeout=30, what="a spin plan")
        # the bumper fires (a foreign node reports it): the loop failed to keep the robot clear
        peers({"middleware": "zenoh", "role": "pub", "listen": f"tcp/127.0.0.1:{free_port()}",
               "connect": [url.replace("zenoh://", "tcp/")],
               "topics": [{"topic": "/collision", "type": "std_msgs/msg/Bool",
                           "messages": [{"data": True}]}]})
        code, output = finish(run)
    finally:
        summary = robot.stop()
        controller.process.terminate()
        controller.process.wait(timeout=20)
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    engaged = next(i for i, r in enumerate(records) if r.get("fallback") == "engaged")
    assert "no_collision" in records[engaged]["explanation"]
    # the fallback's plan: spinning ends (a rotation-0 goal) and the robot docks
    assert any(r.get("effector_done") == "dock" for r in records[engaged:]), output
    assert any(r.get("docked") is True for r in records[engaged:])
    assert any(line.startswith("dock home at 0.2 m/s") for line in controller.lines)
    assert summary["docked"]
    assert watcher.messages("/spin_config")[-1]["data"]["rotation"] == 0
    assert code == 1, output  # no_collision was violated


@pytest.mark.slow
@pytest.mark.parametrize("middleware", ["zenoh", "dds"])
def test_the_robot_obeys_a_foreign_twist_on_cmd_vel(peers, middleware):
    watch = [{"topic": "/odom", "type": "nav_msgs/msg/Odometry"}]
    robot, watcher, url = ros_network(peers, middleware, watch)
    turn = {"linear": {"x": 0.0}, "angular": {"z": 0.8}}
    try:
        watcher.wait_ready()
        if middleware == "zenoh":
            driver = peers({"middleware": "zenoh", "role": "pub", "repeat": True,
                            "listen": f"tcp/127.0.0.1:{free_port()}",
                            "connect": [url.replace("zenoh://", "tcp/")],
                            "topics": [{"topic": "/cmd_vel", "type": "geometry_msgs/msg/Twist",
                                        "messages": [turn]}]})
        else:
            driver = peers({"middleware": "dds", "role": "pub", "repeat": True,
                            "domain": int(url.rsplit("=", 1)[1]),
                            "topics": [{"topic": "/cmd_vel", "type": "geometry_msgs/msg/Twist",
                                        "messages": [turn]}]})
        driver.wait_ready()

        def turning(peer):
            return [m for m in peer.messages("/odom")
                    if m["data"]["twist"]["twist"]["angular"]["z"] == 0.8
                    and m["data"]["twist"]["twist"]["linear"]["x"] == 0.0]

        watcher.wait_for(turning, what="the robot turning on the spot as commanded")
    finally:
        robot.stop()
