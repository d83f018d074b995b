"""The JSON envelope: valid payloads round-trip exactly; anything else is refused or counted."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.comm import CommError, MalformedPayload
from rasm.comm.envelope import check_payload, decode, encode

from .strategies import PAYLOADS


@pytest.mark.slow
@settings(max_examples=300)
@given(PAYLOADS)
def test_any_json_payload_round_trips_exactly(payload):
    data = encode(payload, uid="u-1", timestamp=12.5)
    back, uid, timestamp = decode(data)
    assert back == payload
    assert (uid, timestamp) == ("u-1", 12.5)


def test_wire_form_is_the_payload_with_uid_and_timestamp_first():
    data = encode({"velocity": 0.3}, uid="abc", timestamp=1.0)
    assert json.loads(data) == {"uid": "abc", "timestamp": 1.0, "velocity": 0.3}
    assert list(json.loads(data)) == ["uid", "timestamp", "velocity"]


@settings(max_examples=500)
@given(st.binary(max_size=64) | st.text(max_size=64).map(str.encode))
def test_any_bytes_either_decode_to_an_object_or_raise_malformed(data):
    try:
        payload, _, _ = decode(data)
    except MalformedPayload:
        return
    assert isinstance(payload, dict)


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"not json", "not JSON"),
        (b"[1, 2]", "list"),
        (b'"text"', "str"),
        (b"\xff\xfe\x00binary", "binary"),
        (b'{"x": NaN}', "non-finite"),
        (b'{"x": Infinity}', "non-finite"),
        (b'{"x": 1e999}', "out of range"),
        (b'{"x": 123456789012345678901234567890}', "64 bits"),
        (b'{"x": 9223372036854775808}', "64 bits"),
        (b'{"x": ' + b"9" * 100_000 + b"}", "64 bits"),
        (b"[" * 100_000 + b"]" * 100_000, "nested"),
        (b"{}" + b" " * (1 << 20), "limit"),
    ],
)
def test_malformed_payloads_raise_malformed_with_a_reason(data, reason):
    with pytest.raises(MalformedPayload) as info:
        decode(data)
    assert reason in str(info.value)


def test_int64_bounds_are_accepted():
    back, _, _ = decode(b'{"lo": -9223372036854775808, "hi": 9223372036854775807}')
    assert back == {"lo": -(2**63), "hi": 2**63 - 1}


def test_a_foreign_message_without_envelope_gives_none_uid_and_timestamp():
    assert decode(b'{"value": true}') == ({"value": True}, None, None)


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        ([1], "must be a dict"),
        ({"uid": 1}, "reserved"),
        ({"timestamp": 1}, "reserved"),
        ({"x": math.nan}, "finite"),
        ({"x": [math.inf]}, "finite"),
        ({"x": 2**64}, "64 bits"),
        ({"x": {1: "a"}}, "not a string"),
        ({"x": {1, 2}}, "set is not JSON"),
        ({"x": b"bytes"}, "bytes is not JSON"),
    ],
)
def test_unpublishable_payloads_are_refused_naming_the_problem(payload, reason):
    with pytest.raises(CommError) as info:
        check_payload(payload)
    assert reason in str(info.value)


def test_an_oversized_payload_is_refused_at_encoding():
    with pytest.raises(CommError, match="limit"):
        encode({"blob": "x" * 2000}, uid="u", timestamp=0.0, max_bytes=1000)
