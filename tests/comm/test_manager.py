"""The seed's operations: create_publisher/publish_message, create_subscriber/get_queue_message."""

from __future__ import annotations

import threading

import pytest

from rasm.comm import CommError, CommunicationManager


def test_a_subscriber_queues_what_a_publisher_sends(local):
    cm = CommunicationManager(local)
    subscriber = cm.create_subscriber("robot/+")
    publisher = cm.create_publisher("robot/pose")
    publisher.publish_message({"x": 1})
    publisher.publish_message({"x": 2})
    first = subscriber.get_queue_message(timeout=1)
    second = subscriber.get_queue_message(timeout=1)
    assert (first.topic, first.payload, second.payload) == ("robot/pose", {"x": 1}, {"x": 2})
    assert len(subscriber) == 0


def test_overflow_drops_the_oldest_and_counts_it(local):
    cm = CommunicationManager(local)
    subscriber = cm.create_subscriber("t", maxsize=3)
    publisher = cm.create_publisher("t")
    for i in range(5):
        publisher.publish_message({"i": i})
    assert subscriber.dropped == 2 and local.stats.dropped == 2
    assert [subscriber.get_queue_message(timeout=1).payload["i"] for _ in range(3)] == [2, 3, 4]


def test_get_queue_message_returns_none_when_the_timeout_expires(local):
    subscriber = CommunicationManager(local).create_subscriber("quiet")
    assert subscriber.get_queue_message(timeout=0.01) is None


def test_a_blocked_reader_wakes_when_a_message_arrives(local):
    cm = CommunicationManager(local)
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
    cm = CommunicationManager(local)
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
        CommunicationManager(local).create_publisher("robot/#")


def test_maxsize_must_be_positive(local):
    with pytest.raises(ValueError, match="maxsize"):
        CommunicationManager(local).create_subscriber("t", maxsize=0)
