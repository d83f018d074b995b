"""Bus payloads, as an attacker would send them: whatever bytes arrive, the decoder either
refuses them as malformed or returns a payload rasm could have sent itself; the effector gate
never raises and never passes an action it cannot verify."""

from __future__ import annotations

import json
import math
import queue

import paho.mqtt.client as paho
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from paho.mqtt.enums import CallbackAPIVersion

from rasm.comm import (
    BoundSigner,
    MalformedPayload,
    Message,
    MqttTransport,
    SignedEffector,
    verify,
)
from rasm.comm.envelope import check_payload, decode, encode
from rasm.testing.servers import start_mosquitto

KEY = b"k" * 32
WAIT = 10.0  # a bound on every wait, never a sleep

# pieces of JSON text that have broken decoders: nesting, numbers past every limit, escapes of
# lone surrogates, constants JSON does not have, duplicate keys, control characters
_PIECES = [
    "{", "}", "[", "]", ",", ":", '"', '"a"', '"uid"', '"timestamp"', '"signature"', "1",
    "-0", "1e308", "1e309", "-1e400", "9223372036854775807", "9223372036854775808",
    "1" * 400, "0.1", "NaN", "Infinity", "-Infinity", "true", "null", '"\\ud800"',
    '"\\udc00\\ud800"', '"\\ud83d\\ude00"', '"\\u0000"', '"\x1b"', '"\\"', " ", "\n",
    "[" * 70, "]" * 70, '{"a":' * 70, "}" * 70,
]
JSON_TEXT = st.one_of(
    st.lists(st.sampled_from(_PIECES), max_size=12).map("".join),
    st.lists(st.sampled_from(_PIECES), max_size=6).map(lambda p: '{"a": ' + "".join(p) + "}"),
)


def _all_text(value: object) -> bool:
    if isinstance(value, dict):
        return all(_all_text(k) and _all_text(v) for k, v in value.items())
    if isinstance(value, list):
        return all(_all_text(v) for v in value)
    if isinstance(value, str):
        return value.encode("utf-8", "surrogatepass").decode("utf-8", "replace") == value
    if isinstance(value, float):
        return math.isfinite(value)
    return True


@settings(max_examples=400, derandomize=True)
@given(JSON_TEXT)
def test_whatever_arrives_is_refused_or_is_a_payload_rasm_could_send(text: str) -> None:
    try:
        payload, _, _ = decode(text.encode("utf-8", "surrogatepass"))
    except MalformedPayload:
        return
    assert isinstance(payload, dict)
    assert _all_text(payload)
    check_payload(payload)  # the same rules as for publishing
    again, _, _ = decode(encode(payload, uid="u", timestamp=0.0, max_bytes=1 << 30))
    assert again == payload


VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=6),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner,
                                                                max_size=3),
    max_leaves=8,
)
PAYLOADS = st.one_of(
    VALUES,  # not even a dict
    st.dictionaries(st.sampled_from(["signature", "mode", "seq", "plan"]), VALUES, max_size=4),
)


@settings(max_examples=300, derandomize=True)
@given(payload=PAYLOADS, signed=st.booleans(), tamper=st.booleans())
def test_the_effector_gate_never_raises_and_passes_only_verified_actions(
    payload: object, signed: bool, tamper: bool
) -> None:
    applied: list[dict] = []
    gate = SignedEffector(KEY, applied.append, topic="robot/heater")
    if signed and isinstance(payload, dict):
        try:  # signed and bound to this gate's incarnation, as the checker sends it
            payload = BoundSigner(KEY).sign(payload, topic="robot/heater", epochs=[gate.epoch])
        except Exception:  # not JSON (NaN, an odd key): such a payload cannot be signed
            signed = False
        if tamper and isinstance(payload, dict):
            payload = {**payload, "mode": "tampered"}
    genuine = isinstance(payload, dict) and verify(payload, KEY) and "binding" in payload
    outcome = gate.handle(payload)
    assert outcome is genuine
    assert len(applied) == int(genuine)
    assert gate.handle(payload) is False  # never twice: a replay is refused


@pytest.fixture(scope="module")
def receiver(tmp_path_factory: pytest.TempPathFactory):
    """A transport subscribed to robot/#, and a plain paho client to send it anything (one
    client for everything sent: MQTT keeps one client's messages in order)."""
    broker = start_mosquitto(tmp_path_factory.mktemp("mosquitto"))
    inbox: queue.Queue[Message] = queue.Queue()
    transport = MqttTransport(broker.url)
    transport.subscribe("robot/#", inbox.put)
    transport.connect()
    raw = paho.Client(CallbackAPIVersion.VERSION2, client_id="hostile")
    raw.connect(broker.host, broker.port)
    raw.loop_start()
    yield transport, raw, inbox
    raw.disconnect()
    raw.loop_stop()
    transport.close()
    broker.stop()


@settings(
    max_examples=40, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(JSON_TEXT)
def test_hostile_json_over_a_real_broker_is_delivered_clean_or_counted(receiver, text) -> None:
    transport, raw, inbox = receiver
    malformed = transport.stats.malformed
    raw.publish("robot/raw", text.encode("utf-8", "surrogatepass"), qos=1).wait_for_publish(WAIT)
    raw.publish("robot/sentinel", b'{"sentinel": true}', qos=1).wait_for_publish(WAIT)
    first = inbox.get(timeout=WAIT)
    if first.topic == "robot/raw":
        assert _all_text(first.payload)
        check_payload(first.payload)
        assert transport.stats.malformed == malformed
        first = inbox.get(timeout=WAIT)
    else:
        assert transport.stats.malformed == malformed + 1
    assert first.payload == {"sentinel": True}


def test_a_lone_surrogate_is_refused_both_ways() -> None:
    with pytest.raises(MalformedPayload, match="lone surrogate"):
        decode(b'{"mode": "\\ud800"}')
    with pytest.raises(Exception, match="lone surrogate"):
        encode({"mode": "\ud800"}, uid="u", timestamp=0.0)
    assert decode(json.dumps({"mode": "\U0001f600"}).encode())[0] == {"mode": "\U0001f600"}
