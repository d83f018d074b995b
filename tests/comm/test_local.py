"""LocalTransport: synchronous, thread-safe, MQTT topic semantics, errors contained."""

from __future__ import annotations

import logging
import threading

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.comm import CommError, LocalTransport, Message
from rasm.comm.topics import topic_matches

from .strategies import PAYLOADS, TOPICS, patterns


def test_publish_delivers_to_exact_and_wildcard_subscribers_before_returning(local):
    got: list[tuple[str, Message]] = []
    local.subscribe("robot/pose", lambda m: got.append(("exact", m)))
    local.subscribe("robot/+", lambda m: got.append(("plus", m)))
    local.subscribe("robot/#", lambda m: got.append(("hash", m)))
    local.subscribe("other/#", lambda m: got.append(("other", m)))
    local.publish("robot/pose", {"x": 1.5})
    assert [kind for kind, _ in got] == ["exact", "plus", "hash"]
    message = got[0][1]
    assert (message.topic, message.payload) == ("robot/pose", {"x": 1.5})
    assert local.stats.published == 1 and local.stats.delivered == 3


def test_each_message_carries_a_unique_uid_and_a_wall_clock_timestamp(local):
    import time

    got: list[Message] = []
    local.subscribe("t", got.append)
    before = time.time()
    for i in range(100):
        local.publish("t", {"i": i})
    assert len({m.uid for m in got}) == 100
    assert all(before <= m.timestamp <= time.time() for m in got)


def test_cancel_stops_delivery_and_is_idempotent(local):
    got: list[Message] = []
    sub = local.subscribe("a/#", got.append)
    local.publish("a/b", {"n": 1})
    sub.cancel()
    sub.cancel()
    local.publish("a/b", {"n": 2})
    assert [m.payload["n"] for m in got] == [1]
    assert not sub.active and local.subscriptions == 0


def test_a_raising_callback_is_logged_and_counted_and_others_still_receive(local, caplog):
    got: list[Message] = []

    def broken(message: Message) -> None:
        raise ValueError("boom")

    local.subscribe("a", broken)
    local.subscribe("a", got.append)
    with caplog.at_level(logging.ERROR, logger="rasm.comm"):
        local.publish("a", {})
        local.publish("a", {})
    assert len(got) == 2
    assert local.stats.errors == 2 and local.stats.delivered == 2
    assert "boom" in caplog.text


def test_a_callback_may_publish_again(local):
    got: list[Message] = []
    local.subscribe("monitor", lambda m: local.publish("analyse", {"from": m.topic}))
    local.subscribe("analyse", got.append)
    local.publish("monitor", {})
    assert got[0].payload == {"from": "monitor"}


def test_publishing_before_connect_or_after_close_is_an_error():
    transport = LocalTransport()
    with pytest.raises(CommError, match="connect"):
        transport.publish("a", {})
    transport.connect()
    sub = transport.subscribe("a", lambda m: None)
    transport.close()
    assert not sub.active
    with pytest.raises(CommError, match="closed"):
        transport.publish("a", {})
    with pytest.raises(CommError, match="closed"):
        transport.subscribe("a", lambda m: None)


def test_bad_topics_patterns_and_payloads_are_refused(local):
    with pytest.raises(CommError):
        local.publish("a/+", {})
    with pytest.raises(CommError):
        local.subscribe("a/#/b", lambda m: None)
    with pytest.raises(CommError, match="reserved"):
        local.publish("a", {"uid": "mine"})
    with pytest.raises(CommError, match="not callable"):
        local.subscribe("a", "nope")  # type: ignore[arg-type]
    assert local.stats.published == 0


def test_strict_mode_makes_the_json_round_trip():
    transport = LocalTransport(strict=True)
    transport.connect()
    got: list[Message] = []
    transport.subscribe("a", got.append)
    payload = {"xs": (1, 2)}
    transport.publish("a", payload)
    assert got[0].payload == {"xs": [1, 2]}  # a tuple comes back as a list, as over MQTT
    assert got[0].payload is not payload


@settings(max_examples=100)
@given(st.lists(patterns(), min_size=1, max_size=6), st.lists(TOPICS, min_size=1, max_size=6))
def test_routing_equals_topic_matching(pattern_list, topics):
    transport = LocalTransport()
    transport.connect()
    got: list[tuple[int, str]] = []
    for i, pattern in enumerate(pattern_list):
        transport.subscribe(pattern, lambda m, i=i: got.append((i, m.topic)))
    for topic in topics:
        transport.publish(topic, {})
    expected = [
        (i, topic)
        for topic in topics
        for i, pattern in enumerate(pattern_list)
        if topic_matches(pattern, topic)
    ]
    assert sorted(got) == sorted(expected)


@settings(max_examples=100)
@given(PAYLOADS)
def test_strict_mode_round_trips_any_json_payload(payload):
    transport = LocalTransport(strict=True)
    transport.connect()
    got: list[Message] = []
    transport.subscribe("p", got.append)
    transport.publish("p", payload)
    assert got[0].payload == payload


def test_concurrent_publishers_and_subscription_changes_lose_nothing(local):
    counts: dict[int, int] = {}
    lock = threading.Lock()

    def count(message: Message) -> None:
        with lock:
            counts[message.payload["w"]] = counts.get(message.payload["w"], 0) + 1

    local.subscribe("load/+", count)
    start = threading.Barrier(5)

    def publisher(w: int) -> None:
        start.wait()
        for _ in range(2000):
            local.publish(f"load/{w}", {"w": w})

    def churn() -> None:
        start.wait()
        for _ in range(500):  # other subscriptions come and go meanwhile
            local.subscribe("load/#", lambda m: None).cancel()

    threads = [threading.Thread(target=publisher, args=(w,)) for w in range(4)]
    threads.append(threading.Thread(target=churn))
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert counts == {0: 2000, 1: 2000, 2: 2000, 3: 2000}
    assert local.stats.published == 8000
