"""The type store, the CDR codec and field paths: no network involved."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from rasm.errors import SourceError
from rasm.ros2 import (
    FieldPath,
    FieldPathError,
    MalformedMessage,
    MessageError,
    TypeStore,
    UnknownTypeError,
    field_type,
    normalize_type,
    read_field,
    set_fields,
)
from rasm.ros2.types import dds_type_name, ros_type_name
from tests.ros2 import peer
from tests.ros2.samples import SAMPLES, app_store

STORE = TypeStore()

# RIHS01 hashes that ROS 2 Jazzy publishes for these types
KNOWN_HASHES = {
    "std_msgs/msg/String":
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    "builtin_interfaces/msg/Time":
        "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
    "diagnostic_msgs/msg/KeyValue":
        "RIHS01_d68081eaa540288c5440753baecef0c4e16e81a5f78ad68902ded5100413bb42",
    "sensor_msgs/msg/JointState":
        "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
}


@pytest.mark.parametrize(("typename", "rihs01"), sorted(KNOWN_HASHES.items()))
def test_type_hashes_are_ros_2s(typename, rihs01):
    assert STORE.type_hash(typename) == rihs01


def test_type_names_and_dds_names():
    assert normalize_type("nav_msgs/Odometry") == "nav_msgs/msg/Odometry"
    assert dds_type_name("std_msgs/msg/String") == "std_msgs::msg::dds_::String_"
    assert ros_type_name("std_msgs::msg::dds_::String_") == "std_msgs/msg/String"
    assert ros_type_name("std_msgs::msg::String") is None
    for bad in ("Odometry", "nav_msgs//Odometry", "a/b/c/d", "", 3):
        with pytest.raises(UnknownTypeError, match="pkg/msg/Name"):
            normalize_type(bad)


@given(st.from_regex(r"[a-z][a-z0-9_]{0,12}", fullmatch=True),
       st.from_regex(r"[A-Z][A-Za-z0-9]{0,12}", fullmatch=True))
def test_dds_names_round_trip(package, name):
    assert ros_type_name(dds_type_name(f"{package}/{name}")) == f"{package}/msg/{name}"


def test_unknown_types_are_named_with_what_exists():
    with pytest.raises(UnknownTypeError, match="nav_msgs/msg/Odometry"):
        STORE.resolve("nav_msgs/msg/Odom")
    with pytest.raises(UnknownTypeError, match="no package 'foo_msgs'"):
        STORE.codec("foo_msgs/msg/Bar")
    assert "diagnostic_msgs/msg/DiagnosticArray" in STORE
    assert "rasm_demo/msg/SpinPlan" not in STORE


def test_an_apps_msg_files_add_types():
    store = app_store()
    assert "rasm_demo/msg/SpinPlan" in store
    assert str(store.fields("rasm_demo/msg/SpinPlan")["skip_sectors"]) == "bool[]"
    assert store.type_hash("rasm_demo/msg/SpinPlan").startswith("RIHS01_")


def test_a_bad_msg_file_names_file_line_and_column(tmp_path):
    folder = tmp_path / "my_pkg" / "msg"
    folder.mkdir(parents=True)
    (folder / "Plan.msg").write_text("# a plan\nfloat64 rate\n  Sector[] sectors\n")
    with pytest.raises(SourceError, match="unknown type 'my_pkg/msg/Sector'") as caught:
        TypeStore().add_msg_dir(folder)
    assert str(caught.value.location) == f"{folder / 'Plan.msg'}:3:3"
    (folder / "Plan.msg").write_text("float64 rate\n!!\n")
    with pytest.raises(SourceError, match="not a valid message definition") as caught:
        TypeStore().add_msg_dir(folder)
    assert str(caught.value.location) == f"{folder / 'Plan.msg'}:2:1"


# -- the codec ----------------------------------------------------------------------------------
@pytest.mark.parametrize("topic", [t for t in SAMPLES if t != "/spin_plan"])
def test_encoding_is_byte_identical_to_rosbags_own(topic):
    typename, message = SAMPLES[topic]
    theirs = bytes(peer.STORE.serialize_cdr(peer.to_object(typename, message), typename))
    codec = STORE.codec(typename)
    assert codec.encode(message) == theirs
    assert codec.decode(theirs) == peer.to_plain(peer.STORE.deserialize_cdr(theirs, typename))


def test_unset_fields_are_zero():
    twist = STORE.codec("geometry_msgs/msg/Twist")
    assert twist.decode(twist.encode({"linear": {"x": 0.5}})) == {
        "linear": {"x": 0.5, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0},
    }
    odom = STORE.codec("nav_msgs/msg/Odometry").decode(
        STORE.codec("nav_msgs/msg/Odometry").encode({}))
    assert odom["pose"]["covariance"] == [0.0] * 36
    assert odom["header"] == {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""}
    empty = STORE.codec("std_msgs/msg/Empty")
    assert empty.encode({}) == bytes.fromhex("0001000000")  # ROS's one placeholder byte
    assert empty.decode(empty.encode({})) == {}


@pytest.mark.parametrize(("typename", "message", "says"), [
    ("geometry_msgs/msg/Twist", {"linear": {"x": "fast"}},
     "field 'linear.x' of geometry_msgs/msg/Twist: expected float64, got 'fast'"),
    ("geometry_msgs/msg/Twist", {"linear": {"w": 1.0}},
     "field 'linear.w' of geometry_msgs/msg/Twist: geometry_msgs/msg/Vector3 has no field 'w'"),
    ("std_msgs/msg/Int8", {"data": 300}, "300 is out of range for int8"),
    ("std_msgs/msg/Bool", {"data": 1}, "expected bool, got 1"),
    ("std_msgs/msg/UInt32", {"data": 2.5}, "expected uint32"),
    ("std_msgs/msg/String", {"data": "a\x00b"}, "NUL"),
    ("nav_msgs/msg/Odometry", {"pose": {"covariance": [1.0]}},
     "field 'pose.covariance' of nav_msgs/msg/Odometry: expected float64\\[36\\], exactly 36"),
    ("sensor_msgs/msg/LaserScan", {"ranges": "far"}, "expected float32\\[\\] \\(a list\\)"),
    ("sensor_msgs/msg/LaserScan", {"ranges": [1.0, None, "x"]},
     "field 'ranges\\[2\\]' of sensor_msgs/msg/LaserScan: expected float32"),
    ("std_msgs/msg/Float32", {"data": 1e39},
     "field 'data' of std_msgs/msg/Float32: 1e\\+39 \\(float\\) is out of range for float32 "
     "\\(its largest finite value is 3.4028234663852886e\\+38\\)"),
    ("sensor_msgs/msg/LaserScan", {"ranges": [1.0, -4e38]},
     "field 'ranges\\[1\\]' of sensor_msgs/msg/LaserScan: -4e\\+38 \\(float\\) is out of range "
     "for float32"),
    ("std_msgs/msg/Float64", {"data": 10**400}, "1000.* \\(int\\) is out of range for float64"),
])
def test_messages_that_do_not_fit_their_type_are_refused(typename, message, says):
    with pytest.raises(MessageError, match=says):
        STORE.codec(typename).encode(message)


_FLOAT32_OVERFLOW = 2.0**128 - 2.0**103  # halfway past float32's largest: rounds to infinity


@given(st.floats(allow_nan=False, allow_infinity=False))
@example(3.4028235e38)  # above float32's largest, rounds to it
@example(-_FLOAT32_OVERFLOW)
@example(math.nextafter(_FLOAT32_OVERFLOW, 0))
def test_a_float32_field_takes_what_rounds_to_a_finite_float32_and_refuses_the_rest(x):
    codec = STORE.codec("std_msgs/msg/Float32")
    if abs(x) < _FLOAT32_OVERFLOW:
        assert codec.decode(codec.encode({"data": x}))["data"] == float(np.float32(x))
    else:
        with pytest.raises(MessageError, match="out of range for float32"):
            codec.encode({"data": x})


# strategies for a few types' values, to check encode/decode round trips for all inputs
_finite32 = st.floats(width=32, allow_nan=False)
_twist = st.fixed_dictionaries({
    "linear": st.fixed_dictionaries({"x": st.floats(allow_nan=False), "z": st.floats()}),
    "angular": st.fixed_dictionaries({"z": st.floats(allow_nan=False)}),
})
_scan = st.fixed_dictionaries({
    "header": st.fixed_dictionaries({
        "stamp": st.fixed_dictionaries({"sec": st.integers(-(2**31), 2**31 - 1),
                                        "nanosec": st.integers(0, 2**32 - 1)}),
        "frame_id": st.text(st.characters(blacklist_categories=["Cs"],
                                          blacklist_characters="\x00")),
    }),
    "ranges": st.lists(_finite32 | st.just(float("inf"))),
    "intensities": st.lists(_finite32, max_size=5),
})


def _same(a, b):
    if isinstance(a, dict):
        return a.keys() <= b.keys() and all(_same(v, b[k]) for k, v in a.items())
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and math.isnan(a):
        return math.isnan(b)
    return a == b


@given(_twist)
def test_twists_round_trip(message):
    codec = STORE.codec("geometry_msgs/msg/Twist")
    assert _same(message, codec.decode(codec.encode(message)))


@given(_scan)
def test_laser_scans_round_trip(message):
    codec = STORE.codec("sensor_msgs/msg/LaserScan")
    decoded = codec.decode(codec.encode(message))
    assert _same(message, decoded)
    assert isinstance(decoded["ranges"], list)


@settings(max_examples=300)
@given(st.binary(max_size=400), st.sampled_from(sorted({t for t, _ in SAMPLES.values()})))
def test_any_bytes_decode_or_raise_malformed(data, typename):
    codec = app_store_cached().codec(typename)
    try:
        message = codec.decode(data)
    except MalformedMessage:
        return
    assert isinstance(message, dict)
    codec.check(message)  # what decodes can be sent again


_APP_STORE: list[TypeStore] = []


def app_store_cached() -> TypeStore:
    if not _APP_STORE:
        _APP_STORE.append(app_store())
    return _APP_STORE[0]


# -- field paths --------------------------------------------------------------------------------
ODOM = STORE.codec("nav_msgs/msg/Odometry").decode(
    STORE.codec("nav_msgs/msg/Odometry").encode(SAMPLES["/odom"][1]))
SCAN = STORE.codec("sensor_msgs/msg/LaserScan").decode(
    STORE.codec("sensor_msgs/msg/LaserScan").encode(SAMPLES["/scan"][1]))


def test_field_paths_read_values_arrays_and_elements():
    assert read_field(ODOM, "pose.pose.position.x") == 1.5
    assert read_field(ODOM, "twist.twist.angular.z") == -0.5
    assert read_field(ODOM, "header.stamp") == {"sec": 3, "nanosec": 7}
    assert read_field(SCAN, "ranges") == [0.5, 1.25, float("inf"), 3.0]
    assert read_field(SCAN, "ranges[1]") == 1.25
    assert read_field(ODOM, FieldPath.parse("pose.covariance[35]")) == pytest.approx(3.5)


@pytest.mark.parametrize(("message", "path", "says"), [
    (ODOM, "pose.pose.postion.x", "pose.pose has no field 'postion' \\(its fields: position"),
    (SCAN, "ranges[9]", "index 9 is out of range, ranges has 4 elements"),
    (ODOM, "child_frame_id[0]", "child_frame_id is not an array"),
    (ODOM, "pose.pose.position.x.y", "pose.pose.position.x is not a message"),
])
def test_reading_a_missing_field_names_the_path(message, path, says):
    with pytest.raises(FieldPathError, match=says):
        read_field(message, path, "nav_msgs/msg/Odometry")


@pytest.mark.parametrize("text", ["", "pose..x", "ranges[-1]", "ranges[x]", "1abc", "a.b[2"])
def test_malformed_field_paths_are_refused(text):
    with pytest.raises(FieldPathError):
        FieldPath.parse(text)


@given(st.lists(st.tuples(st.from_regex(r"[a-z][a-z0-9_]{0,6}", fullmatch=True),
                          st.lists(st.integers(0, 99), max_size=2)), min_size=1, max_size=4))
def test_field_paths_parse_into_their_steps(parts):
    text = ".".join(name + "".join(f"[{i}]" for i in indexes) for name, indexes in parts)
    steps = tuple(step for name, indexes in parts for step in (name, *indexes))
    assert FieldPath.parse(text).steps == steps


def test_field_types_are_checked_against_the_store():
    assert str(field_type(STORE, "nav_msgs/msg/Odometry", "pose.pose.position.x")) == "float64"
    assert str(field_type(STORE, "sensor_msgs/msg/LaserScan", "ranges")) == "float32[]"
    assert str(field_type(STORE, "sensor_msgs/msg/LaserScan", "ranges[3]")) == "float32"
    assert str(field_type(STORE, "nav_msgs/msg/Odometry", "pose.covariance")) == "float64[36]"
    assert field_type(STORE, "nav_msgs/msg/Odometry", "pose.pose").base == "geometry_msgs/msg/Pose"
    with pytest.raises(FieldPathError, match="of nav_msgs/msg/Odometry: pose.pose "
                       "\\(geometry_msgs/msg/Pose\\) has no field 'postion'"):
        field_type(STORE, "nav_msgs/msg/Odometry", "pose.pose.postion.x")
    with pytest.raises(FieldPathError, match="index 36 is out of range for pose.covariance"):
        field_type(STORE, "nav_msgs/msg/Odometry", "pose.covariance[36]")
    with pytest.raises(FieldPathError, match="header.stamp.sec is int32, not a message"):
        field_type(STORE, "nav_msgs/msg/Odometry", "header.stamp.sec.x")


def test_set_fields_builds_a_message_from_a_flat_mapping():
    twist = set_fields(STORE, "geometry_msgs/msg/Twist", {"linear.x": 0.2, "angular.z": 0.1})
    assert twist == {"linear": {"x": 0.2, "y": 0.0, "z": 0.0},
                     "angular": {"x": 0.0, "y": 0.0, "z": 0.1}}
    scan = set_fields(STORE, "sensor_msgs/msg/LaserScan",
                      {"ranges": [1.0, 2.0], "ranges[1]": 5.0, "header.frame_id": "laser"})
    assert scan["ranges"] == [1.0, 5.0] and scan["header"]["frame_id"] == "laser"
    with pytest.raises(FieldPathError, match="geometry_msgs/msg/Vector3\\) has no field 'w'"):
        set_fields(STORE, "geometry_msgs/msg/Twist", {"linear.w": 1.0})
    with pytest.raises(MessageError, match="field 'linear.x' of geometry_msgs/msg/Twist"):
        set_fields(STORE, "geometry_msgs/msg/Twist", {"linear.x": "fast"})
    with pytest.raises(FieldPathError, match="index 0 is out of range, ranges has 0 elements"):
        set_fields(STORE, "sensor_msgs/msg/LaserScan", {"ranges[0]": 1.0})


@given(st.floats(allow_nan=False), st.floats(allow_nan=False))
def test_set_then_read_gives_the_values_back(x, z):
    twist = set_fields(STORE, "geometry_msgs/msg/Twist", {"linear.x": x, "angular.z": z})
    assert read_field(twist, "linear.x") == x and read_field(twist, "angular.z") == z


@given(st.integers(0, 255), st.lists(st.integers(0, 255), max_size=5))
def test_bytes_are_octets_from_0_to_255(level, data):
    # ROS 2's byte is an octet; rosbags writes it as int8, which must not show through
    status = STORE.codec("diagnostic_msgs/msg/DiagnosticStatus")
    assert status.decode(status.encode({"level": level}))["level"] == level
    array = STORE.codec("std_msgs/msg/ByteMultiArray")
    assert array.decode(array.encode({"data": data}))["data"] == data
    with pytest.raises(MessageError, match="out of range for byte"):
        status.encode({"level": 256})
