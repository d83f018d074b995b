"""ROS 2's own test interfaces (Debian's ros2-test-interface-files: test_msgs' .msg, .srv and
.action files) in the type store: every one loads, every message round-trips with its .msg
defaults, byte-identical to rosbags' serialization; wstrings; service and action types with the
hashes ROS 2 gives them."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.ros2 import TypeStore
from rasm.ros2.types import WSTRING_TYPE

TEST_INTERFACES = Path("/usr/share/test_interface_files")
pytestmark = pytest.mark.skipif(
    not TEST_INTERFACES.is_dir(),
    reason="Debian's ros2-test-interface-files is not installed (scripts/test.sh installs it)",
)


@pytest.fixture(scope="module")
def store() -> TypeStore:
    made = TypeStore()
    made.add_interface_dir(TEST_INTERFACES, "test_msgs")
    return made


def _messages(store: TypeStore) -> list[str]:
    return [t for t in store.types if t.startswith("test_msgs/") and t != WSTRING_TYPE]


def test_every_test_interface_file_loads(store):
    files = sorted(TEST_INTERFACES.glob("*/*.*"))
    files = [f for f in files if f.suffix in (".msg", ".srv", ".action")]
    assert len(files) == 16  # 12 messages, 3 services, 1 action
    for path in files:
        kind = path.suffix[1:]
        assert f"test_msgs/{kind}/{path.stem}" in store, path
    assert "test_msgs/srv/BasicTypes_Request" in store
    assert "test_msgs/action/Fibonacci_SendGoal_Request" in store
    assert "test_msgs/action/Fibonacci_FeedbackMessage" in store


def test_every_message_round_trips_with_its_defaults_byte_identical_to_rosbags(store):
    for typename in _messages(store):
        codec = store.codec(typename)
        data = codec.encode({})
        decoded = codec.decode(data)
        assert decoded == codec.zero(), typename
        assert codec.encode(decoded) == data, typename
        # rosbags' own serializer writes the same bytes for the message it reads back
        rosbags = store.rosbags
        assert bytes(rosbags.serialize_cdr(rosbags.deserialize_cdr(data, typename),
                                           typename)) == data, typename


def test_unset_fields_take_the_msg_defaults_not_zero(store):
    codec = store.codec("test_msgs/msg/Defaults")
    sent = codec.decode(codec.encode({"int32_value": 7}))
    assert sent == {  # Defaults.msg's values, as ROS sets them
        "bool_value": True, "byte_value": 50, "char_value": 100, "float32_value": 1.125,
        "float64_value": 1.125, "int8_value": -50, "uint8_value": 200, "int16_value": -1000,
        "uint16_value": 2000, "int32_value": 7, "uint32_value": 60000,
        "int64_value": -40000000, "uint64_value": 50000000,
    }
    arrays = store.codec("test_msgs/msg/Arrays").decode(store.codec("test_msgs/msg/Arrays")
                                                         .encode({}))
    assert arrays["string_values_default"] == ["", "max value", "min value"]
    assert arrays["uint64_values_default"] == [0, 1, 18446744073709551615]
    assert arrays["int8_values"] == [0, 0, 0]  # no default: zero
    assert arrays["defaults_values"][2]["uint8_value"] == 200  # nested messages too


def test_a_wstring_is_utf16_code_units_after_their_count(store):
    codec = store.codec("test_msgs/msg/WStrings")
    assert codec.zero()["wstring_value_default3"] == "ハローワールド"
    data = codec.encode({"wstring_value": "a😀", "wstring_value_default1": "",
                         "wstring_value_default2": "", "wstring_value_default3": ""})
    # header, then a uint32 count of UTF-16 units (3: 'a' and a surrogate pair), the units
    assert data[4:14] == b"\x03\x00\x00\x00" + "a😀".encode("utf-16-le")
    assert codec.decode(data)["wstring_value"] == "a😀"


@given(text=st.text(st.characters(exclude_characters="\x00", exclude_categories=["Cs"]),
                    max_size=40))
def test_any_text_survives_a_wstring(store, text):
    codec = store.codec("test_msgs/msg/WStrings")
    message = {"wstring_value": text, "unbounded_sequence_of_wstrings": [text, text]}
    decoded = codec.decode(codec.encode(message))
    assert decoded["wstring_value"] == text
    assert decoded["unbounded_sequence_of_wstrings"] == [text, text]


def test_a_service_hash_is_the_one_ros_2_generates(tmp_path):
    """The RIHS01 hashes a ROS 2 (Jazzy) build generated for a service of an empty request and
    a float64[] response: the request, the response, the event and the service itself."""
    (tmp_path / "srv").mkdir()
    (tmp_path / "srv" / "AddTwoInts.srv").write_text("\n---\nfloat64[] position")
    store = TypeStore()
    store.add_interface_dir(tmp_path, "custom_interfaces")
    hashes = {
        "": "fc05a7ba20817a84adf4571aa8cd42cbe038fc71e7e610062f3d01e956c7da32",
        "_Request": "a2c1a898905dc84c2476ed5990bcf1b7ee419fe70fca34b012d35f1f1d1f3bed",
        "_Response": "9450d1440f98019e60d9ed727f74d1e8135c0636e37633fa648ad26fa2d05b08",
        "_Event": "5c2d996b49751d75a2550836d54597dbbb02ad482c533920da4c3b5128b8ad1d",
    }
    for suffix, digest in hashes.items():
        assert store.type_hash(f"custom_interfaces/srv/AddTwoInts{suffix}") == f"RIHS01_{digest}"
    assert store.type_hash("service_msgs/msg/ServiceEventInfo") == (
        "RIHS01_41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45"
    )


def test_message_hashes_are_rosbags_ones(store):
    for typename in store.types:
        if typename.startswith(("std_msgs", "geometry_msgs", "sensor_msgs", "nav_msgs")):
            assert store.type_hash(typename) == store.rosbags.hash_rihs01(typename), typename


def test_a_bad_default_is_reported_at_its_line(tmp_path):
    from rasm.errors import SourceError

    (tmp_path / "msg").mkdir()
    (tmp_path / "msg" / "Bad.msg").write_text("# a comment\nint32 fine 3\nint32[2] pair [1]\n")
    with pytest.raises(SourceError) as caught:
        TypeStore().add_interface_dir(tmp_path, "bad_msgs")
    assert caught.value.location.line == 3
    assert "2 values expected, 1 given" in str(caught.value)
