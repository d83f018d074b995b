"""rosbag2 recordings written with rosbags alone, checked by `rasm check PROPS BAG` and replayed
by `rasm run APP --replay BAG`; the replay's MCAP trace read back with the mcap library."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from rasm.cli import main
from rasm.loop import MEASURED_KEYS
from rasm.platform.manifest import load_manifest
from rasm.platform.replay import recorded_trace
from tests.ros2 import peer
from tests.ros2.conftest import CUSTOM_MSG_DIR, DATA

GUARD = DATA / "guard"
PROPS = GUARD / "properties" / "guard.rv"
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
SUFFIX = {"mcap": ".mcap", "sqlite3": ".db3"}
T0 = 1_700_000_000_000_000_000  # ns: a log time of 2023, as a real recording has
STAMP_LAG = 5_000_000  # the odometry's header stamp is 5 ms before it was logged


def record(path: Path, storage: str = "mcap", speeds=None, ahead=None) -> Path:
    """A recording of the guard's topics (and one it does not read) written with rosbags."""
    speeds = [0.2] * 20 + [0.8] * 10 + [0.2] * 10 if speeds is None else speeds
    ahead = [2.0 if i < 20 else 0.4 for i in range(len(speeds))] if ahead is None else ahead
    with Writer(path, version=9, storage_plugin=STORAGES[storage]) as writer:
        types = {"/odom": "nav_msgs/msg/Odometry", "/scan": "sensor_msgs/msg/LaserScan",
                 "/chatter": "std_msgs/msg/String"}
        links = {t: writer.add_connection(t, ty, typestore=peer.STORE) for t, ty in types.items()}

        def write(topic, time_ns, message):
            data = peer.STORE.serialize_cdr(peer.to_object(types[topic], message), types[topic])
            writer.write(links[topic], time_ns, bytes(data))

        for i, (speed, near) in enumerate(zip(speeds, ahead, strict=True)):
            t = T0 + i * 100_000_000
            stamp = t - STAMP_LAG
            write("/odom", t, {
                "header": {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9}},
                "twist": {"twist": {"linear": {"x": speed}}},
            })
            write("/scan", t + 1_000, {"ranges": [near, float("inf"), 3.0]})
            write("/chatter", t + 2_000, {"data": "not read"})
    return path


def check_json(capsys, *args):
    code = main(["check", str(PROPS), *map(str, args), "--format", "json"])
    captured = capsys.readouterr()
    return code, json.loads(captured.out) if captured.out else None, captured.err


@pytest.mark.parametrize("storage", sorted(STORAGES))
@pytest.mark.parametrize("form", ["folder", "file"])
def test_rasm_check_reads_a_recording_with_the_apps_probes(tmp_path, capsys, storage, form):
    bag = record(tmp_path / "bag", storage)
    path = bag if form == "folder" else bag / f"bag{SUFFIX[storage]}"
    code, report, err = check_json(capsys, path, "--app", GUARD)
    assert code == 1  # 0.8 m/s with 0.4 m ahead
    verdicts = {p["name"]: p for p in report["properties"]}
    assert verdicts["speed_limit"]["verdict"] == "satisfied"
    assert verdicts["slow_near_obstacles"]["verdict"] == "violated"
    # an event is false where nothing sets it: the recording has no /bumper, no bump
    assert verdicts["no_bump"]["verdict"] == "satisfied"
    assert "no messages on /bumper in the recording" in err
    # one record per message the properties read (the chatter is no record): odom, scan, ...
    assert report["records"] == 80
    # the odometry is timed by its header stamp, the scan by its log time, to the nanosecond
    first = verdicts["slow_near_obstacles"]["violations"][0]
    assert first["time"] == pytest.approx((T0 + 20 * 100_000_000 + 1_000) / 1e9, abs=1e-9)
    odom_times = [v["time"] for v in verdicts["slow_near_obstacles"]["violations"]][1::2]
    assert odom_times[0] == pytest.approx((T0 + 21 * 100_000_000 - STAMP_LAG) / 1e9, abs=1e-9)


def test_a_loop_property_over_a_recording_is_said_to_be_vacuous(tmp_path, capsys):
    # a recording of the robot's topics holds no loop events: the timeliness of the loop was
    # never put to the test, and rasm check says so rather than a plain "satisfied"
    bag = record(tmp_path / "bag")
    props = tmp_path / "loop.rv"
    props.write_text("input speed: float\nevent anomaly\nevent executed\n"
                     "property timely: always (anomaly -> eventually[0, 5s] executed)\n"
                     "property slow: always (speed < 1)\n")
    code = main(["check", str(props), str(bag), "--app", str(GUARD), "--format", "json"])
    assert code == 0
    report = {p["name"]: p for p in json.loads(capsys.readouterr().out)["properties"]}
    assert report["timely"]["verdict"] == "satisfied" and report["timely"]["vacuous"] == ["anomaly"]
    assert report["slow"]["vacuous"] == []
    assert main(["check", str(props), str(bag), "--app", str(GUARD)]) == 0
    assert "timely: satisfied (vacuously: anomaly never happened)" in capsys.readouterr().out


def test_rasm_check_reads_a_recording_with_a_topic_map(tmp_path, capsys):
    bag = record(tmp_path / "bag")
    topics = tmp_path / "topics.yaml"
    topics.write_text(
        "probes:\n"
        "  - topic: /odom\n    type: nav_msgs/msg/Odometry\n    signals:\n"
        "      speed: {field: twist.twist.linear.x, type: float}\n"
        "  - topic: /scan\n    type: sensor_msgs/msg/LaserScan\n    signals:\n"
        "      ahead: {field: 'ranges[0]', type: float}\n"
    )
    code, report, _ = check_json(capsys, bag, "--topics", topics)
    assert code == 1
    verdicts = {p["name"]: p["verdict"] for p in report["properties"]}
    assert verdicts == {"speed_limit": "satisfied", "slow_near_obstacles": "violated",
                        "no_bump": "satisfied"}


def test_a_recording_without_its_probes_or_with_other_types_is_refused(tmp_path, capsys):
    bag = record(tmp_path / "bag")
    assert main(["check", str(PROPS), str(bag)]) == 2
    assert "--app APP" in capsys.readouterr().err
    trace = tmp_path / "trace.jsonl"
    trace.write_text('{"time": 0, "speed": 0.1}\n')
    assert main(["check", str(PROPS), str(trace), "--app", str(GUARD)]) == 2
    assert "a JSONL trace names its signals itself" in capsys.readouterr().err
    topics = tmp_path / "topics.yaml"
    topics.write_text("probes:\n  - topic: /odom\n    type: geometry_msgs/msg/Twist\n"
                      "    signals:\n      speed: {field: linear.x, type: float}\n")
    assert main(["check", str(PROPS), str(bag), "--topics", str(topics)]) == 2
    assert ("topic /odom is recorded as nav_msgs/msg/Odometry, but its probe reads "
            "geometry_msgs/msg/Twist") in capsys.readouterr().err


def test_a_topic_map_may_name_a_type_only_the_recording_defines(tmp_path, capsys):
    # a robot's own message type: its definition travels in the bag, no .msg file here
    typestore = get_typestore(Stores.ROS2_JAZZY)
    typestore.register(get_types_from_msg((CUSTOM_MSG_DIR / "SpinPlan.msg").read_text(),
                                          "rasm_demo/msg/SpinPlan"))
    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        plan = writer.add_connection("/spin_plan", "rasm_demo/msg/SpinPlan", typestore=typestore)
        for i, rate in enumerate([0.5, 0.75, 2.5]):
            message = typestore.types["rasm_demo/msg/SpinPlan"](
                header=typestore.types["std_msgs/msg/Header"](
                    stamp=typestore.types["builtin_interfaces/msg/Time"](sec=0, nanosec=0),
                    frame_id=""),
                turn_rate=rate, steps=i, reason="", skip_sectors=np.array([], dtype=bool))
            writer.write(plan, T0 + i, bytes(typestore.serialize_cdr(message,
                                                                     "rasm_demo/msg/SpinPlan")))
    props = tmp_path / "spin.rv"
    props.write_text("input rate: float\nproperty gentle: always (rate <= 1.0)\n")
    topics = tmp_path / "topics.yaml"
    topics.write_text("probes:\n  - topic: /spin_plan\n    type: rasm_demo/msg/SpinPlan\n"
                      "    signals:\n      rate: {field: turn_rate, type: float}\n")
    code = main(["check", str(props), str(bag), "--topics", str(topics), "--format", "json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 1 and report["records"] == 3
    assert report["properties"][0]["violations"][0]["time"] == pytest.approx((T0 + 2) / 1e9)


def read_mcap(path: Path) -> tuple[list[dict], dict[str, list]]:
    """The trace records of an MCAP trace and every channel's messages, each decoded by
    mcap-ros2-support (ROS 2's own decoder for MCAP: it decodes every channel or raises)."""
    from mcap_ros2.decoder import DecoderFactory

    channels: dict[str, list] = {}
    with path.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            assert (schema.encoding, channel.message_encoding) == ("ros2msg", "cdr")
            channels.setdefault(channel.topic, []).append((message.log_time, decoded))
    return [json.loads(m.data) for _, m in channels["/rasm/trace"]], channels


def test_a_replay_drives_the_loop_and_records_the_actions_instead_of_sending(tmp_path, capsys,
                                                                            monkeypatch):
    monkeypatch.chdir(tmp_path)
    bag = record(tmp_path / "bag")
    trace = tmp_path / "replay.mcap"
    assert main(["run", str(GUARD), "--replay", str(bag), "--trace", str(trace)]) == 1
    records, channels = read_mcap(trace)
    # the loop ran on the recording's own time, from its first message (0 s) to its last,
    # exact to the nanosecond: the first odometry's header stamp is 5 ms before it
    assert records[0]["time"] == -0.005
    assert records[-1]["time"] <= (39 * 100_000_000 + 2_000) / 1e9 + 0.1
    times = {r["time"] for r in records}
    assert {2.000001, 3.895} <= times  # a scan's log time, an odometry's stamp
    actions = [r for r in records if "recorded_action" in r]
    assert actions and actions[0]["recorded_action"] == {
        "effector": "drive", "topic": "/cmd_vel",
        "payload": {"linear": {"x": 0.1, "y": 0.0, "z": 0.0},
                    "angular": {"x": 0.0, "y": 0.0, "z": 0.5}},
    }
    assert actions[1]["recorded_action"]["payload"] == {"level": 2, "reason": "obstacle ahead"}
    executed = [r for r in records if r.get("executed")]
    assert executed and all("not sent (replay)" in r["explanation"] for r in executed)
    # each effector's messages in their own types on their own topics, at the actions' times
    apps = {"/rasm/trace", "/cmd_vel", "/guard_state", "/rasm/verdict/speed_limit",
            "/rasm/verdict/slow_near_obstacles", "/rasm/verdict/no_bump"}
    assert apps <= set(channels)
    # the rest: the verdicts of the platform's own properties (timeliness, ...) and every
    # property's robustness as std_msgs/msg/Float64, each value with the record carrying it
    rest = set(channels) - apps
    assert all(topic.startswith(("/rasm/verdict/", "/rasm/robustness/")) for topic in rest)
    assert "/rasm/verdict/stage_order" in channels
    carried = {
        (f"/rasm/robustness/{key.removeprefix('robustness_')}", round(r["time"] * 1e9), value)
        for r in records for key, value in r.items() if key.startswith("robustness_")
    }
    assert carried and carried == {
        (topic, when, m.data) for topic in rest if topic.startswith("/rasm/robustness/")
        for when, m in channels[topic]
    }
    (when, twist), *_ = channels["/cmd_vel"]
    assert (twist.linear.x, twist.angular.z) == (0.1, 0.5)
    assert when == round(actions[0]["time"] * 1e9)
    state = channels["/guard_state"][0][1]
    assert (state.level, state.reason) == (2, "obstacle ahead")
    # verdicts as std_msgs/msg/Bool when they change: the violation, at its time
    slow = [(t, m.data) for t, m in channels["/rasm/verdict/slow_near_obstacles"]]
    assert slow[0][1] is True and False in [value for _, value in slow]
    assert [m.data for _, m in channels["/rasm/verdict/speed_limit"]] == [True]
    # the first anomaly comes with the first fast odometry after the obstacle shows up
    anomaly = next(r for r in records if r.get("anomaly"))
    assert anomaly["time"] >= 2.0
    capsys.readouterr()
    # rasm check reads the MCAP trace back, and judges it as it judged the recording
    code, report, _ = check_json(capsys, trace)
    assert code == 1
    assert {p["name"]: p["verdict"] for p in report["properties"]} == {
        "speed_limit": "satisfied", "slow_near_obstacles": "violated", "no_bump": "satisfied"}


def test_two_replays_of_one_recording_give_the_same_trace(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    bag = record(tmp_path / "bag", "sqlite3")
    traces = []
    for n in (1, 2):
        out = tmp_path / f"replay{n}.jsonl"
        assert main(["run", str(GUARD), "--replay", str(bag), "--trace", str(out)]) == 1
        lines = [json.loads(line) for line in out.read_text().splitlines()]
        traces.append([{k: v for k, v in r.items() if k not in MEASURED_KEYS} for r in lines])
    assert traces[0] == traces[1] and len(traces[0]) > 100


@settings(
    max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(speeds=st.lists(st.floats(-5, 5, allow_nan=False, width=32), min_size=1, max_size=15))
def test_a_recorded_trace_holds_each_recorded_value_at_its_time(tmp_path_factory, speeds):
    bag = record(tmp_path_factory.mktemp("bag") / "bag", speeds=speeds, ahead=[1.0] * len(speeds))
    manifest = load_manifest(GUARD)
    got = list(recorded_trace(bag, manifest.probes, manifest.types, {"speed": "float"}))
    assert [r["speed"] for _, r in got] == speeds
    stamps = [T0 + i * 100_000_000 - STAMP_LAG for i in range(len(speeds))]
    assert [t.ns for t, _ in got] == stamps
