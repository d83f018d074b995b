"""MqttTransport against a real mosquitto on loopback: envelope, malformed input, QoS,
reconnect after a broker restart, last will."""

from __future__ import annotations

import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

import paho.mqtt.client as paho
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from paho.mqtt.enums import CallbackAPIVersion

from rasm.comm import CommError, Endpoints, Message, MqttTransport
from rasm.comm.envelope import MalformedPayload, decode
from rasm.comm.mqtt import Will
from rasm.testing.servers import free_port

from .strategies import PAYLOADS

ROOT = Path(__file__).resolve().parents[2]
WAIT = 10.0  # generous bound on every wait: a loaded CI machine, never a sleep


class RawClient:
    """A plain paho client, to publish what rasm never would and to observe wire-level QoS."""

    def __init__(self, url_host: str, port: int) -> None:
        self.received: queue.Queue[paho.MQTTMessage] = queue.Queue()
        self.client = paho.Client(CallbackAPIVersion.VERSION2, client_id=f"raw-{port}-{id(self)}")
        self.client.on_message = lambda c, u, msg: self.received.put(msg)
        subscribed = threading.Event()
        self.client.on_subscribe = lambda *args: subscribed.set()
        self._subscribed = subscribed
        self.client.connect(url_host, port)
        self.client.loop_start()

    def subscribe(self, pattern: str, qos: int = 2) -> None:
        self._subscribed.clear()
        self.client.subscribe(pattern, qos)
        assert self._subscribed.wait(WAIT)

    def publish(self, topic: str, data: bytes, qos: int = 0) -> None:
        self.client.publish(topic, data, qos=qos).wait_for_publish(WAIT)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


@pytest.fixture
def raw(broker):
    client = RawClient(broker.host, broker.port)
    yield client
    client.close()


def test_a_message_arrives_with_its_payload_and_envelope(broker, mqtt_factory):
    inbox: queue.Queue[Message] = queue.Queue()
    receiver = mqtt_factory(broker.url)
    receiver.subscribe("robot/+/pose", inbox.put)
    sender = mqtt_factory(broker.url)
    before = time.time()
    sender.publish("robot/r1/pose", {"x": 1.25, "tags": ["a"], "ok": True, "n": None})
    message = inbox.get(timeout=WAIT)
    assert message.topic == "robot/r1/pose"
    assert message.payload == {"x": 1.25, "tags": ["a"], "ok": True, "n": None}
    assert isinstance(message.uid, str) and message.uid
    assert before <= message.timestamp <= time.time()
    assert sender.stats.published == 1 and receiver.stats.delivered == 1


def test_the_wire_carries_uid_and_timestamp_beside_the_payload(broker, mqtt_factory, raw):
    raw.subscribe("wire")
    mqtt_factory(broker.url).publish("wire", {"v": 3})
    import json

    wire = json.loads(raw.received.get(timeout=WAIT).payload)
    assert set(wire) == {"uid", "timestamp", "v"} and wire["v"] == 3


def test_uids_are_unique_across_messages_and_transports(broker, mqtt_factory):
    inbox: queue.Queue[Message] = queue.Queue()
    mqtt_factory(broker.url).subscribe("u/#", inbox.put)
    senders = [mqtt_factory(broker.url) for _ in range(3)]
    for i in range(100):
        senders[i % 3].publish(f"u/{i % 3}", {"i": i})
    uids = {inbox.get(timeout=WAIT).uid for _ in range(100)}
    assert len(uids) == 100


def test_malformed_messages_are_counted_never_fatal(broker, mqtt_factory, raw):
    inbox: queue.Queue[Message] = queue.Queue()
    receiver = mqtt_factory(broker.url)
    receiver.subscribe("in", inbox.put)
    garbage = [
        b"not json", b"[1, 2]", b'"text"', b"\xff\xfe\x00", b"", b'{"x": NaN}',
        b'{"x": 1e999}', b'{"x": 123456789012345678901234567890}', b"[" * 50_000,
        b'{"x": "' + b"y" * (1 << 20) + b'"}',
    ]
    for data in garbage:
        raw.publish("in", data)
    raw.publish("in", b'{"after": "garbage"}')  # a foreign publisher: no envelope
    message = inbox.get(timeout=WAIT)  # same connection, so it arrives after all the garbage
    assert message.payload == {"after": "garbage"}
    assert (message.uid, message.timestamp) == (None, None)
    assert receiver.stats.malformed == len(garbage)
    assert inbox.empty()


@pytest.fixture(scope="module")
def garbage_rig(shared_broker):
    inbox: queue.Queue[Message] = queue.Queue()
    receiver = MqttTransport(shared_broker.url)
    receiver.subscribe("g", inbox.put)
    receiver.connect()
    raw = RawClient(shared_broker.host, shared_broker.port)
    yield receiver, inbox, raw
    raw.close()
    receiver.close()


def _valid(data: bytes) -> bool:
    try:
        decode(data)
    except MalformedPayload:
        return False
    return True


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=48) | st.text(max_size=48).map(str.encode))
def test_any_bytes_from_the_wire_are_delivered_or_counted(garbage_rig, data):
    receiver, inbox, raw = garbage_rig
    malformed = receiver.stats.malformed
    raw.publish("g", data)
    raw.publish("g", b'{"sentinel": true}')
    first = inbox.get(timeout=WAIT)
    if _valid(data):
        assert first.payload == decode(data)[0]
        first = inbox.get(timeout=WAIT)
        assert receiver.stats.malformed == malformed
    else:
        assert receiver.stats.malformed == malformed + 1
    assert first.payload == {"sentinel": True}


@pytest.fixture(scope="module")
def round_trip_rig(shared_broker):
    inbox: queue.Queue[Message] = queue.Queue()
    transport = MqttTransport(shared_broker.url)
    transport.subscribe("rt", inbox.put)
    transport.connect()
    yield transport, inbox
    transport.close()


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(PAYLOADS)
def test_any_json_payload_round_trips_through_the_broker(round_trip_rig, payload):
    transport, inbox = round_trip_rig
    transport.publish("rt", payload)
    assert inbox.get(timeout=WAIT).payload == payload


def test_a_raising_callback_is_counted_and_the_transport_carries_on(broker, mqtt_factory):
    inbox: queue.Queue[Message] = queue.Queue()
    receiver = mqtt_factory(broker.url)

    def broken(message: Message) -> None:
        raise RuntimeError("callback bug")

    receiver.subscribe("e", broken)
    receiver.subscribe("e", inbox.put)
    sender = mqtt_factory(broker.url)
    sender.publish("e", {"n": 1})
    sender.publish("e", {"n": 2})
    assert [inbox.get(timeout=WAIT).payload["n"] for _ in range(2)] == [1, 2]
    assert receiver.stats.errors == 2


def test_a_callback_can_publish_the_next_stage(broker, mqtt_factory):
    inbox: queue.Queue[Message] = queue.Queue()
    stage = mqtt_factory(broker.url)
    stage.subscribe("monitor", lambda m: stage.publish("analyse", {"seen": m.payload["i"]}))
    stage.subscribe("analyse", inbox.put)
    source = mqtt_factory(broker.url)
    for i in range(50):
        source.publish("monitor", {"i": i})
    assert [inbox.get(timeout=WAIT).payload["seen"] for _ in range(50)] == list(range(50))


def test_cancelled_subscriptions_receive_nothing_more(broker, mqtt_factory):
    inbox: queue.Queue[Message] = queue.Queue()
    marker: queue.Queue[Message] = queue.Queue()
    receiver = mqtt_factory(broker.url)
    sub = receiver.subscribe("c/#", inbox.put)
    receiver.subscribe("marker", marker.put)
    sender = mqtt_factory(broker.url)
    sender.publish("c/1", {})
    inbox.get(timeout=WAIT)
    sub.cancel()
    sender.publish("c/1", {})
    sender.publish("marker", {})
    marker.get(timeout=WAIT)
    assert inbox.empty()


def test_qos_by_topic_sets_the_qos_on_the_wire(broker, mqtt_factory, raw):
    raw.subscribe("#", qos=2)
    sender = mqtt_factory(broker.url, qos_by_topic={"alarm/#": 2, "cmd/+": 1, "cmd/stop": 2})
    for topic in ("telemetry/x", "alarm/fire", "cmd/go", "cmd/stop"):
        sender.publish(topic, {})
    sender.publish("alarm/fire", {}, qos=0)  # an explicit qos wins
    seen = [raw.received.get(timeout=WAIT) for _ in range(5)]
    assert sorted((m.topic, m.qos) for m in seen) == sorted(
        [("telemetry/x", 0), ("alarm/fire", 2), ("cmd/go", 1), ("cmd/stop", 2), ("alarm/fire", 0)]
    )


def test_bad_qos_is_refused(broker, mqtt_factory):
    with pytest.raises(CommError, match="QoS"):
        MqttTransport(broker.url, qos_by_topic={"a": 3})
    transport = mqtt_factory(broker.url)
    with pytest.raises(CommError, match="QoS"):
        transport.publish("a", {}, qos=5)


def test_messages_flow_again_after_the_broker_restarts(broker, mqtt_factory):
    events: queue.Queue[tuple[str, bool]] = queue.Queue()
    inbox: queue.Queue[Message] = queue.Queue()
    receiver = mqtt_factory(broker.url, on_connection_change=lambda up: events.put(("rx", up)))
    receiver.subscribe("flow/#", inbox.put)
    sender = mqtt_factory(broker.url, on_connection_change=lambda up: events.put(("tx", up)))
    # told once each on the way up, before connect() returned
    assert {events.get(timeout=WAIT) for _ in range(2)} == {("rx", True), ("tx", True)}
    sender.publish("flow/a", {"n": 1})
    assert inbox.get(timeout=WAIT).payload == {"n": 1}

    broker.stop()
    assert {events.get(timeout=WAIT) for _ in range(2)} == {("rx", False), ("tx", False)}
    assert not receiver.connected
    sender.publish("flow/a", {"n": "lost"})  # QoS 0 while the broker is away: dropped, counted
    assert sender.stats.dropped == 1

    broker.restart()  # same port, empty broker: the receiver must subscribe again by itself
    assert {events.get(timeout=WAIT) for _ in range(2)} == {("rx", True), ("tx", True)}
    sender.publish("flow/b", {"n": 2})
    message = inbox.get(timeout=WAIT)
    assert (message.topic, message.payload) == ("flow/b", {"n": 2})
    assert receiver.stats.reconnects == 1 and sender.stats.reconnects == 1


def test_qos1_messages_published_during_an_outage_arrive_after_reconnect(broker, mqtt_factory):
    events: queue.Queue[bool] = queue.Queue()
    inbox: queue.Queue[Message] = queue.Queue()
    transport = mqtt_factory(broker.url, on_connection_change=events.put)
    transport.subscribe("outage/#", inbox.put, qos=1)
    assert events.get(timeout=WAIT) is True
    broker.stop()
    assert events.get(timeout=WAIT) is False
    for i in range(3):
        transport.publish("outage/x", {"i": i}, qos=1)
    assert transport.stats.dropped == 0
    broker.restart()
    assert events.get(timeout=WAIT) is True
    assert sorted(inbox.get(timeout=WAIT).payload["i"] for _ in range(3)) == [0, 1, 2]


def test_subscriptions_made_while_disconnected_are_sent_on_reconnect(broker, mqtt_factory):
    events: queue.Queue[bool] = queue.Queue()
    inbox: queue.Queue[Message] = queue.Queue()
    receiver = mqtt_factory(broker.url, on_connection_change=events.put)
    assert events.get(timeout=WAIT) is True
    broker.stop()
    assert events.get(timeout=WAIT) is False
    receiver.subscribe("late", inbox.put)
    broker.restart()
    assert events.get(timeout=WAIT) is True
    mqtt_factory(broker.url).publish("late", {"ok": 1})
    assert inbox.get(timeout=WAIT).payload == {"ok": 1}


WILL_CHILD = """
import sys, threading
from rasm.comm import MqttTransport
from rasm.comm.mqtt import Will
transport = MqttTransport(sys.argv[1], will=Will("presence/worker", {"online": False}))
transport.connect()
transport.publish("presence/worker", {"online": True}, qos=1)
print("ready", flush=True)
threading.Event().wait()
"""


def test_the_last_will_is_published_when_a_client_dies(broker, mqtt_factory):
    inbox: queue.Queue[Message] = queue.Queue()
    mqtt_factory(broker.url).subscribe("presence/+", inbox.put, qos=1)
    child = subprocess.Popen(
        [sys.executable, "-c", WILL_CHILD, broker.url], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout.readline().strip() == "ready"
        assert inbox.get(timeout=WAIT).payload == {"online": True}
        child.kill()  # no clean disconnect: the broker must publish the will
        will = inbox.get(timeout=WAIT)
        assert (will.topic, will.payload) == ("presence/worker", {"online": False})
        assert will.uid is not None
    finally:
        child.kill()
        child.wait(WAIT)
        child.stdout.close()


def test_connecting_to_no_broker_fails_clearly_within_the_timeout():
    url = f"mqtt://127.0.0.1:{free_port()}"
    transport = MqttTransport(url, connect_timeout=0.5)
    with pytest.raises(CommError) as info:
        transport.connect()
    assert url in str(info.value) and "broker" in str(info.value)
    with pytest.raises(CommError):
        transport.publish("a", {})


def test_publishing_before_connect_is_an_error(broker):
    with pytest.raises(CommError, match="connect"):
        MqttTransport(broker.url).publish("a", {})


def test_communication_manager_over_mqtt(broker, mqtt_factory):
    cm = Endpoints(mqtt_factory(broker.url))
    subscriber = cm.create_subscriber("k/#", maxsize=10)
    cm.create_publisher("k/speed").publish_message({"v": 0.4})
    message = subscriber.get_queue_message(timeout=WAIT)
    assert (message.topic, message.payload) == ("k/speed", {"v": 0.4})
    cm.close()


def test_close_flushes_what_was_published_just_before(broker, mqtt_factory):
    inbox: queue.Queue[Message] = queue.Queue()
    mqtt_factory(broker.url).subscribe("burst", inbox.put)
    sender = mqtt_factory(broker.url)
    for i in range(500):
        sender.publish("burst", {"i": i})
    sender.close()  # right away: nothing may be left behind in paho's queue
    assert [inbox.get(timeout=WAIT).payload["i"] for _ in range(500)] == list(range(500))


def test_a_clean_close_does_not_send_the_will(broker, mqtt_factory):
    leaving = mqtt_factory(broker.url, will=Will("presence/a", {"online": False}, retain=True))
    leaving.close()
    # A will would have been retained: a new subscriber would get it on subscribing, before the
    # answer to its own marker message.
    inbox: queue.Queue[Message] = queue.Queue()
    observer = mqtt_factory(broker.url)
    observer.subscribe("presence/#", inbox.put)
    observer.publish("presence/marker", {})
    assert inbox.get(timeout=WAIT).topic == "presence/marker"


def test_a_callback_may_close_its_own_transport(broker, mqtt_factory):
    closed = threading.Event()
    transport = mqtt_factory(broker.url)

    def close_me(message: Message) -> None:
        transport.close()
        closed.set()

    transport.subscribe("bye", close_me)
    transport.publish("bye", {})
    assert closed.wait(WAIT)
    with pytest.raises(CommError, match="closed"):
        transport.publish("bye", {})
