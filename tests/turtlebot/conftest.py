"""The TurtleBot demonstrator's tests import its ``tb4`` package from the app folder."""

from __future__ import annotations

import sys
from pathlib import Path

APP = Path(__file__).resolve().parents[2] / "examples" / "turtlebot"
if str(APP) not in sys.path:
    sys.path.insert(0, str(APP))

# the ROS 2 tests' foreign peers (tests/ros2/peer.py), for the demonstrator over ROS 2
from tests.ros2.conftest import peers  # noqa: E402, F401
