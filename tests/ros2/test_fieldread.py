"""Fields read straight out of CDR bytes (rasm.ros2.fieldread) give what decoding the whole
message gives, and refuse exactly the bytes the whole decoding refuses."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rosbags.typesys import get_types_from_msg

from rasm.ros2 import FieldPathError, MalformedMessage, TypeStore, read_field
from rasm.ros2.fieldread import MISSING, field_reader, projection, serves
from tests.ros2.samples import SAMPLES, app_store

# every alignment case: 1-byte fields before 8-byte ones, strings before fixed blocks, bounded
# strings, fixed and bounded arrays of strings, sequences of messages holding sequences
ODD = """\
int8 a
float64 b
string<=5 label
uint16[3] c
string[2] names
bool flag
int64[<=3] counts
std_msgs/Header[] headers
uint8 d
float32[] e
"""
STORE = app_store()
STORE.register(get_types_from_msg(ODD, "rasm_test/msg/Odd"))
TYPES = sorted({t for t, _ in SAMPLES.values()} | {
    "rasm_test/msg/Odd", "sensor_msgs/msg/JointState", "sensor_msgs/msg/Imu",
    "diagnostic_msgs/msg/DiagnosticArray", "std_msgs/msg/Empty", "nav_msgs/msg/Path",
})

_INTS = {
    "int8": (-(2**7), 2**7 - 1), "int16": (-(2**15), 2**15 - 1), "int32": (-(2**31), 2**31 - 1),
    "int64": (-(2**63), 2**63 - 1), "uint8": (0, 255), "byte": (0, 255), "char": (0, 255),
    "uint16": (0, 2**16 - 1), "uint32": (0, 2**32 - 1), "uint64": (0, 2**64 - 1),
}


def _element(store: TypeStore, ftype) -> st.SearchStrategy:
    if ftype.is_message:
        return message_of(store, ftype.base)
    if ftype.base == "bool":
        return st.booleans()
    if ftype.base in ("float32", "float64"):
        return st.floats(width=32 if ftype.base == "float32" else 64)
    if ftype.base == "string":
        text = st.text(st.characters(blacklist_characters="\x00", codec="utf-8"))
        return text.filter(lambda s: len(s) <= ftype.string_bound) if ftype.string_bound \
            else text
    return st.integers(*_INTS[ftype.base])


def message_of(store: TypeStore, typename: str) -> st.SearchStrategy:
    """Any message of ``typename`` as a dict (sequences short)."""
    fields = {}
    for name, ftype in store.fields(typename).items():
        element = _element(store, ftype)
        if ftype.array == "fixed":
            fields[name] = st.lists(element, min_size=ftype.length, max_size=ftype.length)
        elif ftype.array == "sequence":
            fields[name] = st.lists(element, max_size=min(ftype.length or 4, 4))
        else:
            fields[name] = element
    return st.fixed_dictionaries(fields)


def paths_of(store: TypeStore, typename: str, prefix: str = "") -> list[str]:
    """Every path the reader serves in ``typename`` (indexes 0, 1 and 5 of sequences)."""
    out = []
    for name, ftype in store.fields(typename).items():
        path = prefix + name
        if ftype.is_message and ftype.array is None:
            out += paths_of(store, ftype.base, path + ".")
        elif ftype.is_message:
            continue
        elif ftype.array is None:
            out.append(path)
        else:
            out.append(path)
            if ftype.base != "string":
                indexes = range(ftype.length) if ftype.array == "fixed" else (0, 1, 5)
                out += [f"{path}[{i}]" for i in indexes][:3]
    return out


def wanted(message: dict[str, Any], path: str) -> Any:
    try:
        return read_field(message, path)
    except FieldPathError:
        return MISSING


def same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return a == b and type(a) is type(b)


@st.composite
def message_and_paths(draw):
    typename = draw(st.sampled_from(TYPES))
    message = draw(message_of(STORE, typename))
    served = paths_of(STORE, typename)
    paths = draw(st.lists(st.sampled_from(served), unique=True, max_size=6)) if served else []
    return typename, message, paths


@pytest.mark.slow
@settings(max_examples=400, deadline=None)
@given(message_and_paths())
def test_the_fields_read_are_the_decoded_messages(case):
    typename, message, paths = case
    codec = STORE.codec(typename)
    data = codec.encode(message)
    assert serves(STORE, typename, paths)
    read = field_reader(STORE, typename, paths)
    decoded = codec.decode(data)
    got = read(data)
    assert all(same(g, wanted(decoded, p)) for g, p in zip(got, paths, strict=True)), (got, paths)


@pytest.mark.slow
@settings(max_examples=600, deadline=None)
@given(message_and_paths(), st.data())
def test_bytes_are_refused_exactly_when_decoding_refuses_them(case, data):
    typename, message, paths = case
    codec = STORE.codec(typename)
    encoded = bytearray(codec.encode(message))
    # a few bytes changed and the end cut or extended: lengths, terminators, UTF-8 broken
    for _ in range(data.draw(st.integers(0, 3))):
        where = data.draw(st.integers(4, max(4, len(encoded) - 1)))
        if where < len(encoded):
            encoded[where] = data.draw(st.integers(0, 255))
    end = data.draw(st.integers(0, len(encoded) + 8))
    hostile = bytes(encoded[:end]) + bytes(max(0, end - len(encoded)))
    read = field_reader(STORE, typename, paths)
    try:
        decoded = codec.decode(hostile)
    except MalformedMessage:
        try:
            read(hostile)
        except MalformedMessage:
            return
        raise AssertionError("the field reader took bytes the decoder refuses") from None
    got = read(hostile)
    assert all(same(g, wanted(decoded, p)) for g, p in zip(got, paths, strict=True))


def test_paths_into_arrays_of_messages_or_whole_sub_messages_are_read_from_the_message():
    path = STORE.codec("nav_msgs/msg/Path")
    data = path.encode({"poses": [{"pose": {"position": {"x": 2.5}}}]})
    assert not serves(STORE, "nav_msgs/msg/Path", ["poses[0].pose.position.x"])
    assert field_reader(STORE, "nav_msgs/msg/Path", ["poses[0].pose.position.x", "poses[1]"])(
        data) == [2.5, MISSING]
    odom = STORE.codec("nav_msgs/msg/Odometry").encode(SAMPLES["/odom"][1])
    assert not serves(STORE, "nav_msgs/msg/Odometry", ["pose.pose.position"])
    assert field_reader(STORE, "nav_msgs/msg/Odometry", ["pose.pose.position"])(odom) == [
        {"x": 1.5, "y": -2.25, "z": 0.0}]
    assert serves(STORE, "nav_msgs/msg/Odometry", ["twist.twist.linear.x", "header.stamp.sec"])


def all_paths(store: TypeStore, typename: str, prefix: str = "") -> list[str]:
    """Paths of every kind: leaves, whole arrays and sub-messages, elements of arrays of
    messages and fields inside them."""
    out = []
    for name, ftype in store.fields(typename).items():
        path = prefix + name
        out.append(path)
        if ftype.is_message and ftype.array is None:
            out += all_paths(store, ftype.base, path + ".")
        elif ftype.is_message:
            out += [f"{path}[0]"] + all_paths(store, ftype.base, f"{path}[0].")[:3]
        elif ftype.array:
            out.append(f"{path}[1]")
    return out


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(st.data())
def test_a_projection_holds_what_its_paths_read(data):
    typename = data.draw(st.sampled_from([t for t in TYPES if STORE.fields(t)]))
    message = data.draw(message_of(STORE, typename))
    paths = data.draw(st.lists(st.sampled_from(all_paths(STORE, typename)), max_size=5))
    encoded = STORE.codec(typename).encode(message)
    whole = STORE.codec(typename).decode(encoded)
    part = projection(STORE, typename, paths)(encoded)
    for path in paths:
        assert same(wanted(part, path), wanted(whole, path)), (path, part)


def test_a_path_the_type_does_not_have_is_refused_when_the_reader_is_made():
    with pytest.raises(FieldPathError, match="twist.twist.linear.w"):
        field_reader(STORE, "nav_msgs/msg/Odometry", ["twist.twist.linear.w"])
