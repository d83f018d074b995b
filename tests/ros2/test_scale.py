"""A probe signal may be scaled from its field (value = field x scale + offset): live, on a
recording, and in the manifest's schema."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.platform.manifest import Probe, Signal, load_manifest
from rasm.platform.messages import MessageReader
from rasm.platform.replay import recorded_trace
from tests.ros2.test_replay import GUARD, record

BATTERY = Probe(
    "/battery", {"percent": Signal("percent", "float", field="percentage", scale=100)},
    type="sensor_msgs/msg/BatteryState",
)


@given(fraction=st.floats(0, 1, width=32))
def test_a_live_message_is_scaled(fraction):
    values, missing = MessageReader(BATTERY).read({"percentage": fraction})
    assert values == {"percent": fraction * 100} and missing == []


@settings(max_examples=10, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(speeds=st.lists(st.floats(-5, 5, width=32), min_size=1, max_size=8),
       scale=st.floats(-10, 10), offset=st.floats(-10, 10))
def test_a_recording_is_read_scaled(tmp_path_factory, speeds, scale, offset):
    bag = record(tmp_path_factory.mktemp("bag") / "bag", speeds=speeds, ahead=[1.0] * len(speeds))
    odom = Probe("/odom", {"speed": Signal("speed", "float", field="twist.twist.linear.x",
                                           scale=scale, offset=offset)},
                 type="nav_msgs/msg/Odometry")
    got = list(recorded_trace(bag, [odom], load_manifest(GUARD).types, {"speed": "float"}))
    assert [r["speed"] for _, r in got] == [s * scale + offset for s in speeds]


def test_a_topic_map_gives_scale_and_offset(tmp_path, capsys):
    from rasm.cli import main

    bag = record(tmp_path / "bag", speeds=[0.2] * 5, ahead=[1.0] * 5)
    topics = tmp_path / "topics.yaml"
    topics.write_text(
        "probes:\n  - topic: /odom\n    type: nav_msgs/msg/Odometry\n    signals:\n"
        "      speed: {field: twist.twist.linear.x, type: float, scale: 10, offset: -1.5}\n"
    )
    props = tmp_path / "p.rv"
    props.write_text(
        "input speed: float\nproperty tenfold:\n    always (speed > 0.4 and speed < 0.6)\n"
    )
    assert main(["check", str(props), str(bag), "--topics", str(topics)]) == 0, (
        capsys.readouterr()
    )
