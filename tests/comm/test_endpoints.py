"""The Communication Manager's operations: create_publisher/publish_message,
create_subscriber/get_queue_message."""

from __future__ import annotations

import threading
import time

import pytest

from rasm.comm import CommError, Endpoints


def test_a_subscriber_queues_what_a_publisher_sends(local):
    cm = Endpoints(local)
    subscriber = cm.create_subscriber("robot/+")
    publisher = cm.create_publisher("robot/pose")
    publisher.publish_message({"x": 1})
    publisher.publish_message({"x": 2})
    first = subscriber.get_queue_message(timeout=1)
    second = subscriber.get_queue_message(timeout=1)
    assert (first.topic, first.payload, second.payload) == ("robot/pose", {"x": 1}, {"x": 2})
    assert len(subscriber) == 0


def test_overflow_drops_the_oldest_and_counts_it(local):
    cm = Endpoints(local)
    subscriber = cm.create_subscriber("t", maxsize=3)
    publisher = cm.create_publisher("t")
    for i in range(5):
        publisher.publish_message({"i": i})
    assert subscriber.dropped == 2 and local.stats.dropped == 2
    assert [subscriber.get_queue_message(timeout=1).payload["i"] for _ in range(3)] == [2, 3, 4]


def test_get_queue_message_returns_none_when_the_timeout_expires(local):
    subscriber = Endpoints(local).create_subscriber("quiet")
    assert subscriber.get_queue_message(timeout=0.01) is None


def test_a_blocked_reader_wakes_when_a_message_arrives(local):
    cm = Endpoints(local)
    subscriber = cm.create_subscriber("wake")
    publisher = cm.create_publisher("wake")
    waiting = threading.Event()
    result = []

    def reader() -> None:
        waiting.set()
        result.append(subscriber.get_queue_message())  # no timeout: blocks until a message

    thread = threading.Thread(target=reader)
    thread.start()
    assert waiting.wait(5)
    publisher.publish_message({"go": True})
    thread.join(5)
    assert not thread.is_alive()
    assert result[0].payload == {"go": True}


def test_closing_wakes_a_blocked_reader_with_none(local):
    cm = Endpoints(local)
    subscriber = cm.create_subscriber("never")
    result = []
    thread = threading.Thread(target=lambda: result.append(subscriber.get_queue_message()))
    thread.start()
    cm.close()
    thread.join(5)
    assert not thread.is_alive() and result == [None]
    assert local.subscriptions == 0


def test_a_publisher_needs_a_topic_name_not_a_pattern(local):
    with pytest.raises(CommError, match="wildcard"):
        Endpoints(local).create_publisher("robot/#")


def test_maxsize_must_be_positive(local):
    with pytest.raises(ValueError, match="maxsize"):
        Endpoints(local).create_subscriber("t", maxsize=0)


def test_publish_message_sends_on_any_topic_to_callbacks_and_queues(local):
    cm = Endpoints(local)
    seen = []
    arrived = threading.Event()

    def callback(message):
        seen.append((message.topic, message.payload))
        arrived.set()

    cm.subscribe("robot/+/cmd", callback)
    queued = cm.create_subscriber("robot/#")
    cm.publish_message("robot/wheels/cmd", {"v": 0.2})
    assert arrived.wait(5)
    assert seen == [("robot/wheels/cmd", {"v": 0.2})]
    assert queued.get_queue_message(timeout=5).payload == {"v": 0.2}


def test_closing_the_manager_cancels_its_callback_subscriptions(local):
    cm = Endpoints(local)
    seen = []
    subscription = cm.subscribe("t", seen.append)
    assert subscription.active and local.subscriptions == 1
    cm.close()
    assert not subscription.active and local.subscriptions == 0
    cm.publish_message("t", {"late": True})
    assert seen == []


def test_publish_message_needs_a_topic_name_not_a_pattern(local):
    with pytest.raises(CommError, match="wildcard"):
        Endpoints(local).publish_message("robot/+", {"x": 1})


def test_the_operations_work_over_a_real_broker(shared_broker, mqtt_factory):
    cm = Endpoints(mqtt_factory(shared_broker.url))
    arrived = threading.Event()
    seen = []
    cm.subscribe("cm/+", lambda message: (seen.append(message.payload), arrived.set()))
    queued = cm.create_subscriber("cm/#")
    deadline = time.monotonic() + 10
    while not arrived.is_set() and time.monotonic() < deadline:  # until the subscription is live
        cm.publish_message("cm/x", {"n": 1})
        arrived.wait(0.2)
    assert seen and seen[0] == {"n": 1}
    assert queued.get_queue_message(timeout=5).payload == {"n": 1}
    cm.close()
