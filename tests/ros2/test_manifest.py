"""ROS 2 in app.yaml: interface types, field paths, QoS, header stamps and the app's own .msg
files are checked against the type store when the manifest loads, so `rasm lint` and `rasm run`
name every mistake at its file, line and column."""

from __future__ import annotations

import textwrap

import pytest

from rasm.cli import main
from rasm.errors import SourceErrors
from rasm.platform.manifest import load_manifest, load_topic_map
from tests.ros2.conftest import DATA

GOOD = """\
name: rover
components:
  monitor: components:M
  analyse: components:A
  plan: components:P
  execute: components:E
probes:
  - topic: /odom
    type: nav_msgs/msg/Odometry
    stamp: header
    qos: {reliability: best_effort, depth: 5}
    signals:
      speed: {field: twist.twist.linear.x, type: float}
      frame: {field: header.frame_id, type: str}
  - topic: /scan
    type: sensor_msgs/msg/LaserScan
    signals:
      ranges: {type: json}
      ahead: {field: "ranges[0]", type: float}
effectors:
  drive:
    topic: /cmd_vel
    type: geometry_msgs/msg/Twist
    fields: {linear.x: speed, angular.z: turn}
  beep:
    topic: /beep
    type: rover/msg/Beep
    fields: {tone: pitch}
"""
BEEP = "uint16 tone  # Hz\nstring why\n"


def write_app(tmp_path, text, beep=BEEP):
    tmp_path.mkdir(exist_ok=True)
    (tmp_path / "app.yaml").write_text(textwrap.dedent(text))
    (tmp_path / "components.py").write_text("class M: pass\nclass A: pass\nclass P: pass\n"
                                             "class E: pass\n")
    if beep is not None:
        (tmp_path / "msg").mkdir(exist_ok=True)
        (tmp_path / "msg" / "Beep.msg").write_text(beep)
    return tmp_path


def errors(tmp_path, text, beep=BEEP):
    with pytest.raises(SourceErrors) as info:
        load_manifest(write_app(tmp_path / "rover", text, beep))
    return [(e.location.line, e.location.col, e.message) for e in info.value.errors]


def test_a_ros_manifest_loads_with_its_types_and_the_apps_own(tmp_path):
    manifest = load_manifest(write_app(tmp_path / "rover", GOOD))
    odom, scan = manifest.probes
    assert (odom.type, odom.stamp, odom.qos) == (
        "nav_msgs/msg/Odometry", "header", {"reliability": "best_effort", "depth": 5})
    assert odom.signals["speed"].field == "twist.twist.linear.x"
    assert scan.signals["ranges"].field is None  # the signal's name is its field
    drive, beep = manifest.effectors["drive"], manifest.effectors["beep"]
    assert drive.message_fields == {"linear.x": "speed", "angular.z": "turn"}
    # the payload keys take the types of the fields they fill (what rules may read)
    assert drive.fields == {"speed": "float", "turn": "float"}
    assert beep.fields == {"pitch": "int"} and beep.type == "rover/msg/Beep"
    assert "rover/msg/Beep" in manifest.types
    assert manifest.ros_topics["/cmd_vel"] == ("geometry_msgs/msg/Twist", None)


@pytest.mark.parametrize(
    "old, new, line, col, message",
    [
        ("type: nav_msgs/msg/Odometry", "type: nav_msgs/msg/Odometri", 9, 11,
         "unknown message type 'nav_msgs/msg/Odometri': did you mean nav_msgs/msg/Odometry?"),
        ("twist.twist.linear.x", "twist.twist.linear.w", 13, 22,
         "signal 'speed': field path 'twist.twist.linear.w' of nav_msgs/msg/Odometry: "
         "twist.twist.linear (geometry_msgs/msg/Vector3) has no field 'w'"),
        ("frame_id, type: str", "frame_id, type: float", 14, 45,
         "signal 'frame' is float but header.frame_id of nav_msgs/msg/Odometry is string (str)"),
        ("ranges: {type: json}", "ranges: {type: float}", 18, 22,
         "signal 'ranges' is float but ranges of sensor_msgs/msg/LaserScan is float32[]"),
        ("ranges: {type: json}", "rangez: {type: json}", 18, 7,
         "signal 'rangez': field path 'rangez' of sensor_msgs/msg/LaserScan: "
         "sensor_msgs/msg/LaserScan has no field 'rangez'"),
        ('"ranges[0]"', '"ranges.x"', 19, 22, "ranges is float32[], not a message"),
        ("angular.z: turn", "angular.q: turn", 24, 31,
         "effector drive: field path 'angular.q' of geometry_msgs/msg/Twist"),
        ("angular.z: turn", "angular.z: 3turn", 24, 42, "is not valid under any of the given"),
        ("type: rover/msg/Beep", "type: rover/msg/Boop", 27, 11,
         "unknown message type 'rover/msg/Boop': did you mean rover/msg/Beep?"),
        ("topic: /odom", "topic: odom", 8, 12, "'odom' is not an absolute ROS topic name"),
        ("depth: 5}", "depth: 0}", 11, 44, "probes.0.qos.depth: 0 is less than the minimum"),
    ],
)
def test_each_mistake_is_reported_at_its_place(tmp_path, old, new, line, col, message):
    assert old in GOOD
    found = errors(tmp_path, GOOD.replace(old, new, 1))
    assert len(found) == 1, found
    assert found[0][:2] == (line, col), found
    assert message in found[0][2]


def test_stamp_header_needs_a_header(tmp_path):
    text = GOOD.replace("type: sensor_msgs/msg/LaserScan",
                        "type: sensor_msgs/msg/LaserScan\n    stamp: header")
    text = text.replace("type: nav_msgs/msg/Odometry\n    stamp: header",
                        "type: geometry_msgs/msg/Twist\n    stamp: header")
    text = text.replace("twist.twist.linear.x", "linear.x").replace(
        "      frame: {field: header.frame_id, type: str}\n", "")
    found = errors(tmp_path, text)
    assert found == [(10, 12, "probe /odom: stamp: header, but geometry_msgs/msg/Twist has no "
                      "std_msgs/msg/Header field 'header' (leave stamp out: records are timed "
                      "on arrival)")]


def test_ros_settings_on_an_untyped_topic_are_refused(tmp_path):
    text = GOOD.replace("    type: nav_msgs/msg/Odometry\n", "").replace(
        "    type: geometry_msgs/msg/Twist\n", "")
    found = errors(tmp_path, text)
    messages = [m for _, _, m in found]
    assert (9, 5) in [f[:2] for f in found]  # stamp
    assert any("stamp belongs to a ROS 2 topic" in m for m in messages)
    assert any("qos belongs to a ROS 2 topic" in m for m in messages)
    assert any("signal 'speed': a field path reads a ROS 2 message" in m for m in messages)
    # an untyped effector's fields are value types: a payload key there is a mistake
    assert any("effector drive: field 'linear.x' has the type 'speed'" in m for m in messages)


def test_a_bad_msg_file_is_reported_at_its_line(tmp_path):
    found = errors(tmp_path, GOOD, beep="uint16 tone\nfloat64[ broken\n")
    assert len(found) == 1
    assert found[0][:2] == (2, 1) and "not a valid message definition" in found[0][2]


def test_rasm_lint_prints_them_as_file_line_col(tmp_path, capsys):
    app = write_app(tmp_path / "rover", GOOD.replace("twist.twist.linear.x", "twist.linear.x"))
    assert main(["lint", str(app)]) == 1
    out = capsys.readouterr().out.strip().splitlines()
    assert out == [
        f"{app / 'app.yaml'}:13:22: signal 'speed': field path 'twist.linear.x' of "
        "nav_msgs/msg/Odometry: twist (geometry_msgs/msg/TwistWithCovariance) has no field "
        "'linear' (its fields: twist, covariance)"
    ]
    assert main(["lint", str(DATA / "guard")]) == 0


def test_a_topic_map_is_a_probes_list(tmp_path):
    good = tmp_path / "map.yaml"
    good.write_text("probes:\n  - topic: /odom\n    type: nav_msgs/msg/Odometry\n    signals:\n"
                    "      speed: {field: twist.twist.linear.x, type: float}\n")
    probes, store = load_topic_map(good)
    assert probes[0].signals["speed"].field == "twist.twist.linear.x"
    assert store.resolve("nav_msgs/msg/Odometry")
    bad = tmp_path / "bad.yaml"
    bad.write_text("probes:\n  - topic: /odom\n    type: nav_msgs/msg/Odometry\n    signals:\n"
                   "      speed: {field: twist.twist.linear.v, type: float}\n")
    with pytest.raises(SourceErrors) as info:
        load_topic_map(bad)
    assert str(info.value.errors[0].location) == f"{bad}:5:22"
    other = tmp_path / "other.yaml"
    other.write_text("velocity: robot/odometry\n")
    with pytest.raises(SourceErrors) as info:
        load_topic_map(other)
    assert "'probes' is a required property" in info.value.errors[0].message


CALLS = GOOD + """\
  lamp:
    service: /lamp
    type: std_srvs/srv/SetBool
    fields: {data: lamp_on}
    response: {success: lamp_ok}
    timeout: 2.5
  go:
    action: /go
    type: rover/action/Go
    fields: {x: goal_x}
    response: {reached: arrived}
    feedback: {left: distance_left}
"""
GO = "float64 x\n---\nbool reached\n---\nfloat32 left\n"


def write_calls(tmp_path, text=CALLS):
    app = write_app(tmp_path / "rover", text)
    (app / "action").mkdir(exist_ok=True)
    (app / "action" / "Go.action").write_text(GO)
    return app


def test_service_and_action_effectors_load_with_their_answers_typed(tmp_path):
    manifest = load_manifest(write_calls(tmp_path))
    lamp, go = manifest.effectors["lamp"], manifest.effectors["go"]
    assert (lamp.call, lamp.topic, lamp.timeout) == ("service", "/lamp", 2.5)
    assert lamp.message_type == "std_srvs/srv/SetBool_Request"
    assert lamp.fields == {"lamp_on": "bool"}
    assert {k: (s.field, s.type) for k, s in lamp.response.items()} == {
        "lamp_ok": ("success", "bool")}
    assert (go.call, go.message_type, go.answer_type, go.timeout) == (
        "action", "rover/action/Go_Goal", "rover/action/Go_Result", 60.0)
    assert go.fields == {"goal_x": "float"}
    assert go.feedback["distance_left"].type == "float"
    # the answers' values are knowledge, declared as the probes' are; no topic for a call
    assert {"lamp_ok", "arrived", "distance_left"} <= set(manifest.signals)
    assert "/lamp" not in manifest.ros_topics and "/go" not in manifest.ros_topics


@pytest.mark.parametrize(
    "old, new, line, col, message",
    [
        ("type: std_srvs/srv/SetBool", "type: std_msgs/msg/Bool", 31, 11,
         "effector lamp: std_msgs/msg/Bool is a message type, so the effector needs a topic:"),
        ("type: rover/action/Go", "type: std_srvs/srv/SetBool", 37, 11,
         "effector go: std_srvs/srv/SetBool is a service type, so the effector needs a "
         "service:"),
        ("{data: lamp_on}", "{date: lamp_on}", 32, 14,
         "effector lamp: field path 'date' of std_srvs/srv/SetBool_Request"),
        ("{success: lamp_ok}", "{succes: lamp_ok}", 33, 16,
         "effector lamp: response: field path 'succes' of std_srvs/srv/SetBool_Response"),
        ("{left: distance_left}", "{right: distance_left}", 40, 16,
         "effector go: feedback: field path 'right' of rover/action/Go_Feedback"),
        ("    timeout: 2.5\n", "    feedback: {message: m}\n", 34, 5,
         "effector lamp: feedback belongs to an action (a service answers once: use response)"),
        ("    service: /lamp\n", "    service: /lamp\n    topic: /lamp\n", 29, 3,
         "effector lamp: give it one topic, service or action (where its actions go), not "
         "topic and service"),
        ("    type: std_srvs/srv/SetBool\n", "", 30, 5,
         "effector lamp: a service needs its type (type: pkg/srv/Name)"),
        ("{reached: arrived}", "{reached: speed}", 39, 25,
         "effector go: 'speed' is bool here but probe /odom gives it as float"),
        ("timeout: 2.5", "timeout: 0", 34, 14, "effectors.lamp.timeout: 0 is less than or equal"),
    ],
)
def test_each_call_effector_mistake_is_reported_at_its_place(
    tmp_path, old, new, line, col, message
):
    assert old in CALLS
    with pytest.raises(SourceErrors) as info:
        load_manifest(write_calls(tmp_path, CALLS.replace(old, new, 1)))
    found = [(e.location.line, e.location.col, e.message) for e in info.value.errors]
    assert len(found) == 1, found
    assert found[0][:2] == (line, col), found
    assert message in found[0][2]


def test_a_topic_effector_keeps_a_topic_only_setting(tmp_path):
    text = GOOD.replace("fields: {tone: pitch}", "fields: {tone: pitch}\n    timeout: 3")
    found = errors(tmp_path, text)
    assert found == [(29, 5, "effector beep: timeout belongs to a service or an action")]
