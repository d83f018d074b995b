"""Recordings made by ROS 2 itself: the test bags of the ros2/rosbag2 repository (Apache-2.0),
read where a checkout of that repository is (``RASM_ROSBAG2=/path/to/rosbag2``); they are not
copied into this repository. Without the variable these tests are skipped.

The talker bags were recorded by ``ros2 bag record`` (rosbag2 version 4, no type hashes; the
QoS text of their ``metadata.yaml`` differs from their storage's); the cdr_test bags hold
test_msgs types the standard interfaces lack, defined in the bag; topics_and_services also
records service events, which do not decode.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from rasm.cli import main
from rasm.ros2 import BagReader

ROOT = Path(os.environ.get("RASM_ROSBAG2", "/nonexistent"))
pytestmark = pytest.mark.skipif(
    not (ROOT / "rosbag2_py").is_dir(), reason="RASM_ROSBAG2 names no rosbag2 checkout"
)
TALKER = ["rosbag2_py/test/resources/mcap/talker", "rosbag2_py/test/resources/sqlite3/talker",
          "rosbag2_py/test/resources/mcap/talker/talker.mcap",
          "rosbag2_py/test/resources/sqlite3/talker/talker.db3"]
CDR = ["rosbag2_tests/resources/mcap/cdr_test", "rosbag2_tests/resources/sqlite3/cdr_test"]


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("bag", TALKER)
def test_the_talker_bags_are_checked_and_replayed(tmp_path, capsys, bag):
    props = write(tmp_path / "talker.rv", 'input said: str\nproperty hello: always (said != "")\n')
    topics = write(tmp_path / "topics.yaml", "probes:\n  - topic: /topic\n"
                   "    type: std_msgs/msg/String\n    signals:\n      said: {field: data, "
                   "type: str}\n")
    code = main(["check", str(props), str(ROOT / bag), "--topics", str(topics), "--format",
                 "json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["records"] == 10
    said = [r.message["data"] for r in BagReader(ROOT / bag, topics=["/topic"])]
    assert said == [f"Hello, world! {i}" for i in range(10)]


@pytest.mark.parametrize("bag", CDR)
def test_types_only_the_bag_defines_are_read(tmp_path, capsys, bag):
    props = write(tmp_path / "basic.rv", "input f: float\ninput flag: bool\n"
                  "property fine: always (f >= 0.0)\n")
    topics = write(tmp_path / "topics.yaml", "probes:\n  - topic: /test_topic\n"
                   "    type: test_msgs/msg/BasicTypes\n    signals:\n"
                   "      f: {field: float64_value, type: float}\n"
                   "      flag: {field: bool_value, type: bool}\n")
    code = main(["check", str(props), str(ROOT / bag), "--topics", str(topics), "--format",
                 "json"])
    assert code == 0 and json.loads(capsys.readouterr().out)["records"] == 3
    arrays = [r.message for r in BagReader(ROOT / bag, topics=["/array_topic"])]
    assert len(arrays) == 4 and len(arrays[0]["float64_values"]) == 3


def test_service_events_are_left_out_of_a_whole_reading():
    bag = ROOT / "rosbag2_cpp/test/rosbag2_cpp/bags/topics_and_services.mcap"
    reader = BagReader(bag)
    assert set(reader.undecodable) == {"/add_two_ints/_service_event",
                                       "/add_two_ints2/_service_event"}
    assert {r.topic for r in reader} == {"/parameter_events"}


APP = """\
name: talk
components:
  monitor: components:Quiet
  analyse: components:Heard
  plan:
    component: components:Answer
    produces: {turn: float}
  execute: components:Drive
probes:
  - topic: /topic
    type: std_msgs/msg/String
    signals:
      said: {field: data, type: str}
effectors:
  drive:
    topic: /cmd_vel
    type: geometry_msgs/msg/Twist
    fields: {angular.z: turn}
knowledge: memory
timing: off
loop:
  period: 0.1
"""
COMPONENTS = """\
from rasm import Action, Anomaly, Plan


class Quiet:
    def monitor(self, ctx):
        return None


class Heard:
    # one anomaly per new sentence
    def __init__(self):
        self.last = None

    def analyse(self, ctx):
        said = ctx.knowledge.read_knowledge("said")
        if said is None or said == self.last:
            return None
        self.last = said
        return Anomaly(said, {"n": int(said.rsplit(" ", 1)[1])})


class Answer:
    def plan(self, ctx):
        return Plan({"turn": float(ctx.anomaly.data["n"])})


class Drive:
    def execute(self, ctx):
        return Action("drive", {"turn": ctx.plan["turn"]})
"""


@pytest.mark.parametrize("bag", TALKER[:2])
def test_a_replay_of_the_talker_records_an_answer_to_each_sentence(tmp_path, monkeypatch, bag):
    monkeypatch.chdir(tmp_path)
    app = tmp_path / "talk"
    app.mkdir()
    write(app / "app.yaml", APP)
    write(app / "components.py", COMPONENTS)
    trace = tmp_path / "replay.jsonl"
    # (an answer every half second is oscillation to the loop's own properties: exit 1)
    assert main(["run", str(app), "--replay", str(ROOT / bag), "--trace", str(trace)]) in (0, 1)
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    turns = [r["recorded_action"]["payload"]["angular"]["z"] for r in records
             if "recorded_action" in r]
    assert turns == [float(i) for i in range(10)]
