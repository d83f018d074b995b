"""Sample messages of the standard types the examples use, and a custom one, for the tests."""

from __future__ import annotations

from typing import Any

from rasm.ros2 import TypeStore
from tests.ros2.conftest import CUSTOM_MSG_DIR

# topic -> (type, one message as a dict); values exact in float32 where the field is float32
SAMPLES: dict[str, tuple[str, dict[str, Any]]] = {
    "/scan": ("sensor_msgs/msg/LaserScan", {
        "header": {"stamp": {"sec": 12, "nanosec": 500}, "frame_id": "base_scan"},
        "angle_min": -1.5, "angle_max": 1.5, "angle_increment": 0.25,
        "range_min": 0.125, "range_max": 8.0,
        "ranges": [0.5, 1.25, float("inf"), 3.0], "intensities": [1.0, 2.0, 0.0, 4.0],
    }),
    "/odom": ("nav_msgs/msg/Odometry", {
        "header": {"stamp": {"sec": 3, "nanosec": 7}, "frame_id": "odom"},
        "child_frame_id": "base_link",
        "pose": {"pose": {"position": {"x": 1.5, "y": -2.25, "z": 0.0},
                          "orientation": {"w": 1.0}},
                 "covariance": [0.1 * i for i in range(36)]},
        "twist": {"twist": {"linear": {"x": 0.25}, "angular": {"z": -0.5}}},
    }),
    "/cmd_vel": ("geometry_msgs/msg/Twist", {"linear": {"x": 0.2}, "angular": {"z": 0.1}}),
    "/bumper": ("std_msgs/msg/Bool", {"data": True}),
    "/chatter": ("std_msgs/msg/String", {"data": "héllo wörld ✓"}),
    "/spin_plan": ("rasm_demo/msg/SpinPlan", {
        "header": {"frame_id": "base_link"}, "turn_rate": 0.75, "steps": 12,
        "reason": "occluded", "skip_sectors": [False, True, False],
    }),
}

MSG_FILES = [[str(path), "rasm_demo"] for path in sorted(CUSTOM_MSG_DIR.glob("*.msg"))]


def app_store() -> TypeStore:
    """The standard interfaces plus the custom rasm_demo messages."""
    store = TypeStore()
    store.add_msg_dir(CUSTOM_MSG_DIR)
    return store


def expected(store: TypeStore, typename: str, message: dict[str, Any]) -> dict[str, Any]:
    """``message`` as a complete decoded dict (unset fields zero, float32 rounded)."""
    codec = store.codec(typename)
    return codec.decode(codec.encode(message))
