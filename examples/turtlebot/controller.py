"""A Nav2-style controller for the ROS 2 TurtleBot, written with eclipse-zenoh and rosbags only
(no rasm): the action and service servers the managing side commands the robot through.

    python examples/turtlebot/controller.py zenoh://127.0.0.1:7447   # connects to the robot

It speaks rmw_zenoh's conventions (key expressions, CDR, the rmw attachment) and serves:

- the action ``/spin`` (``turtlebot/action/Spin``, from ``action/``): a goal is a spin plan.
  The controller hands it to the robot (``turtlebot/msg/SpinConfig`` on ``/spin_config``),
  sends the robot's navigation mode as feedback while the robot takes it up, and ends the goal
  as succeeded once the robot's ``/robot_state`` shows the plan in force. A newer goal
  preempts a running one (which ends aborted); a cancelled goal ends spinning (a plan of
  rotation 0 goes to the robot) and ends as cancelled.
- the service ``/dock`` (``turtlebot/srv/Dock``, from ``srv/``): the robot leaves its route and
  stays parked (``std_msgs/msg/Bool`` on ``/dock_command``).

It prints ``ready`` once it serves, and stops on SIGTERM, Ctrl-C or after ``--duration`` s.
"""

from __future__ import annotations

import argparse
import json
import signal
import struct
import sys
import threading
import time
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np
import zenoh
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

HERE = Path(__file__).resolve().parent
SPIN = "turtlebot/action/Spin"
DOCK = "turtlebot/srv/Dock"
# goal statuses (action_msgs/msg/GoalStatus)
SUCCEEDED, CANCELED, ABORTED = 4, 5, 6
# rmw_zenoh's default node session: gossip scouting, so the managing side finds this node
SESSION = {
    "mode": "peer",
    "listen/endpoints": ["tcp/127.0.0.1:0"],
    "scouting/multicast/enabled": False,
    "scouting/gossip/enabled": True,
    "scouting/gossip/target": {"router": ["router", "peer"], "peer": ["router"]},
    "scouting/gossip/autoconnect": {"router": [], "peer": ["router", "peer"]},
    "timestamping/enabled": True,
}


def types():
    """rosbags' ROS 2 store with the robot's messages and the action's and service's parts."""
    store = get_typestore(Stores.ROS2_JAZZY)
    defs = {}
    for name in ("SpinConfig", "RobotState"):
        defs.update(get_types_from_msg((HERE / "msg" / f"{name}.msg").read_text(),
                                       f"turtlebot/msg/{name}"))
    goal, result, feedback = (HERE / "action" / "Spin.action").read_text().split("---")
    request, response = (HERE / "srv" / "Dock.srv").read_text().split("---")
    for text, typename in ((goal, f"{SPIN}_Goal"), (result, f"{SPIN}_Result"),
                           (feedback, f"{SPIN}_Feedback"), (request, f"{DOCK}_Request"),
                           (response, f"{DOCK}_Response")):
        # (rosbags would name a pkg/srv/Name_Request pkg/srv/msg/Name_Request: keep the name)
        defs[typename] = next(iter(get_types_from_msg(text, typename).values()))

    def name(target):
        return (Nodetype.NAME, target)

    uuid = ("goal_id", name("unique_identifier_msgs/msg/UUID"))
    defs.update({
        f"{SPIN}_SendGoal_Request": ([], [uuid, ("goal", name(f"{SPIN}_Goal"))]),
        f"{SPIN}_SendGoal_Response": ([], [("accepted", (Nodetype.BASE, ("bool", 0))),
                                           ("stamp", name("builtin_interfaces/msg/Time"))]),
        f"{SPIN}_GetResult_Request": ([], [uuid]),
        f"{SPIN}_GetResult_Response": ([], [("status", (Nodetype.BASE, ("int8", 0))),
                                            ("result", name(f"{SPIN}_Result"))]),
        f"{SPIN}_FeedbackMessage": ([], [uuid, ("feedback", name(f"{SPIN}_Feedback"))]),
        "action_msgs/srv/CancelGoal_Request": ([], [("goal_info",
                                                     name("action_msgs/msg/GoalInfo"))]),
        "action_msgs/srv/CancelGoal_Response": ([], [
            ("return_code", (Nodetype.BASE, ("int8", 0))),
            ("goals_canceling", (Nodetype.SEQUENCE, (name("action_msgs/msg/GoalInfo"), 0)))]),
    })
    store.register(defs)
    return store


class Controller:
    """The action and service servers on one Zenoh session (see the module doc)."""

    def __init__(self, session: zenoh.Session, domain: int = 0) -> None:
        self.store = types()
        self.messages = self.store.types
        self.session = session
        self.domain = domain
        self.lock = threading.Lock()
        self.goals: dict[str, dict] = {}  # goal id (hex) -> its goal, outcome, waiting queries
        self.sequence = 0
        self.gid = bytes(range(16, 32))
        self.spin_config = self._publisher("/spin_config", "turtlebot/msg/SpinConfig")
        self.dock_command = self._publisher("/dock_command", "std_msgs/msg/Bool")
        base = f"{domain}/spin/_action"
        fb = f"{SPIN}_FeedbackMessage"
        self.feedback = session.declare_publisher(
            f"{base}/feedback/{dds(fb)}/{self.store.hash_rihs01(fb)}")
        # the services answer on any type hash: the request's type is checked by decoding it
        self.entities = [
            session.declare_queryable(f"{base}/send_goal/*/*", self.on_send_goal),
            session.declare_queryable(f"{base}/get_result/*/*", self.on_get_result),
            session.declare_queryable(f"{base}/cancel_goal/*/*", self.on_cancel),
            session.declare_queryable(f"{domain}/dock/*/*", self.on_dock),
            session.declare_subscriber(
                f"{domain}/robot_state/{dds('turtlebot/msg/RobotState')}/*",
                self.on_robot_state),
            self.spin_config, self.dock_command, self.feedback,
        ]

    # -- the wire ----------------------------------------------------------------------------
    def _publisher(self, topic: str, typename: str):
        key = f"{self.domain}/{topic.strip('/')}/{dds(typename)}/{self.store.hash_rihs01(typename)}"
        return self.session.declare_publisher(key)

    def encode(self, typename: str, **fields) -> bytes:
        return bytes(self.store.serialize_cdr(self.messages[typename](**fields), typename))

    def decode(self, data: bytes, typename: str):
        return self.store.deserialize_cdr(data, typename)

    def publish(self, publisher, data: bytes) -> None:
        with self.lock:
            self.sequence += 1
            sequence = self.sequence
        publisher.put(data, attachment=struct.pack("<qqB16s", sequence, time.time_ns(), 16,
                                                   self.gid))

    def send_plan(self, plan: dict) -> None:
        self.publish(self.spin_config, self.encode("turtlebot/msg/SpinConfig", **plan))

    # -- the action ---------------------------------------------------------------------------
    def on_send_goal(self, query) -> None:
        request = self.decode(query.payload.to_bytes(), f"{SPIN}_SendGoal_Request")
        goal_id = bytes(request.goal_id.uuid).hex()
        plan = {f: float(getattr(request.goal, f))
                for f in ("rotation", "angular_velocity", "stop_every", "spin_duration")}
        accepted = plan["rotation"] >= 0
        query.reply(query.key_expr, self.encode(
            f"{SPIN}_SendGoal_Response", accepted=accepted,
            stamp=self.messages["builtin_interfaces/msg/Time"](sec=0, nanosec=0)),
            attachment=query.attachment)
        if not accepted:
            return
        with self.lock:
            running = [g for g in self.goals.values() if g["outcome"] is None]
            self.goals[goal_id] = {"id": goal_id, "plan": plan, "outcome": None, "results": []}
        for older in running:  # a newer plan replaces the one being taken up
            self.finish(older, ABORTED)
        self.send_plan(plan)
        print(f"goal {goal_id}: spin {plan['rotation']} deg", flush=True)

    def on_robot_state(self, sample) -> None:
        state = self.decode(sample.payload.to_bytes(), "turtlebot/msg/RobotState")
        with self.lock:
            running = [g for g in self.goals.values() if g["outcome"] is None]
        for goal in running:
            self.publish(self.feedback, self.encode(
                f"{SPIN}_FeedbackMessage", goal_id=self.uuid(goal["id"]),
                feedback=self.messages[f"{SPIN}_Feedback"](nav_mode=state.nav_mode)))
            if abs(state.spin_rotation - goal["plan"]["rotation"]) < 1e-9:
                self.finish(goal, SUCCEEDED, float(state.spin_rotation), int(state.spins))

    def finish(self, goal: dict, status: int, rotation: float = 0.0, spins: int = 0) -> None:
        with self.lock:
            if goal["outcome"] is not None:
                return
            goal["outcome"] = (status, rotation, spins)
            waiting, goal["results"] = goal["results"], []
        for query in waiting:
            self.reply_result(query, goal["outcome"])

    def reply_result(self, query, outcome) -> None:
        status, rotation, spins = outcome
        query.reply(query.key_expr, self.encode(
            f"{SPIN}_GetResult_Response", status=status,
            result=self.messages[f"{SPIN}_Result"](rotation_in_force=rotation, spins=spins)),
            attachment=query.attachment)
        query.drop()

    def on_get_result(self, query) -> None:
        request = self.decode(query.payload.to_bytes(), f"{SPIN}_GetResult_Request")
        with self.lock:
            goal = self.goals.get(bytes(request.goal_id.uuid).hex())
            outcome = goal["outcome"] if goal else (0, 0.0, 0)  # unknown goal
            if goal is not None and outcome is None:
                goal["results"].append(query)
        if outcome is not None:
            self.reply_result(query, outcome)

    def on_cancel(self, query) -> None:
        request = self.decode(query.payload.to_bytes(), "action_msgs/srv/CancelGoal_Request")
        goal_id = bytes(request.goal_info.goal_id.uuid).hex()
        with self.lock:
            goal = self.goals.get(goal_id)
        if goal is not None and goal["outcome"] is None:
            self.send_plan({"rotation": 0.0, "angular_velocity": 0.0, "stop_every": 0.0,
                            "spin_duration": 0.0})
            self.finish(goal, CANCELED)
            print(f"goal {goal_id}: cancelled", flush=True)
        query.reply(query.key_expr, self.encode(
            "action_msgs/srv/CancelGoal_Response", return_code=0 if goal else 2,
            goals_canceling=[request.goal_info] if goal else []), attachment=query.attachment)

    def uuid(self, goal_id: str):
        return self.messages["unique_identifier_msgs/msg/UUID"](
            uuid=np.frombuffer(bytes.fromhex(goal_id), dtype=np.uint8))

    # -- the service --------------------------------------------------------------------------
    def on_dock(self, query) -> None:
        request = self.decode(query.payload.to_bytes(), f"{DOCK}_Request")
        self.publish(self.dock_command, self.encode("std_msgs/msg/Bool", data=True))
        print(f"dock {request.dock_id} at {request.speed} m/s", flush=True)
        query.reply(query.key_expr, self.encode(
            f"{DOCK}_Response", success=True,
            message=f"docking at {request.dock_id} at {request.speed:g} m/s"),
            attachment=query.attachment)

    def close(self) -> None:
        for entity in self.entities:
            entity.undeclare()


def dds(typename: str) -> str:
    package, kind, name = typename.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("transport", help="zenoh://HOST:PORT: the robot's (or a router's)")
    parser.add_argument("--duration", type=float, default=None, help="seconds to run")
    args = parser.parse_args(argv)
    url = urlsplit(args.transport)
    config = zenoh.Config()
    for key, value in {**SESSION, "connect/endpoints": [f"tcp/{url.hostname}:{url.port}"]}.items():
        config.insert_json5(key, json.dumps(value))
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    session = zenoh.open(config)
    controller = Controller(session)
    print("ready", flush=True)
    try:
        stop.wait(args.duration)
    except KeyboardInterrupt:
        pass
    controller.close()
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
