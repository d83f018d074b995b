"""A transport counts its own messages until they are back (what a simulated run waits for),
on a real mosquitto on loopback."""

from __future__ import annotations

import threading
from collections import Counter

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.comm import CommError, LocalTransport, Message
from rasm.comm.own_deliveries import OwnDeliveries

WAIT = 10.0  # generous bound on every wait: a loaded CI machine, never a sleep


def test_the_wait_returns_once_every_own_message_has_reached_its_callbacks(mqtt):
    bus = mqtt()
    received: list[Message] = []
    bus.subscribe("sim/#", received.append)
    bus.count_own_deliveries()
    for n in range(300):
        bus.publish(f"sim/{'ab'[n % 2]}", {"n": n})
    bus.wait_own_deliveries(WAIT)
    # nothing is read after the wait: it returned with all 300 delivered
    assert sorted(m.payload["n"] for m in received) == list(range(300))


TOPICS = st.sampled_from(["sim/a", "sim/b", "other/c"])


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(topics=st.lists(TOPICS, max_size=40))
def test_after_the_wait_each_subscribed_topic_has_had_every_message_sent_on_it(
    shared_broker, mqtt_factory, topics
):
    bus = mqtt_factory(shared_broker.url)
    received: Counter[str] = Counter()
    bus.subscribe("sim/+", lambda m: received.update([m.topic]))
    bus.count_own_deliveries()
    for topic in topics:
        bus.publish(topic, {"x": 1})  # other/c has no subscription here: nothing waits for it
    bus.wait_own_deliveries(WAIT)
    assert received == Counter(t for t in topics if t.startswith("sim/"))
    bus.close()


def test_a_message_lost_on_the_way_fails_the_wait_naming_its_topic(broker, mqtt):
    bus = mqtt()
    bus.subscribe("sim/temperature", lambda m: None)
    bus.count_own_deliveries()
    broker.stop()
    bus.publish("sim/temperature", {"value": 37.0})  # QoS 0 without a broker: dropped
    with pytest.raises(CommError, match=r"did not come back within 0.5 s \(1 on 'sim/temperature'"):
        bus.wait_own_deliveries(0.5)


def test_a_message_another_process_published_on_an_own_topic_fails_the_wait(mqtt):
    bus, other = mqtt(), mqtt()
    received: list[Message] = []
    all_three = threading.Event()

    def receive(message: Message) -> None:
        received.append(message)
        if len(received) == 3:
            all_three.set()

    bus.subscribe("sim/+", receive)
    bus.count_own_deliveries(exclusive=["sim/temperature"])
    bus.publish("sim/temperature", {"value": 37.0})
    other.publish("sim/presence", {"online": True})  # not exclusive: not counted
    other.publish("sim/temperature", {"value": 99.0})
    assert all_three.wait(WAIT)
    with pytest.raises(CommError, match=r"another process published on topics this process "
                                        r"needs to itself \(1 on 'sim/temperature'\)"):
        bus.wait_own_deliveries(WAIT)


def test_a_transport_that_cannot_tell_its_own_messages_refuses_to_count_them():
    with pytest.raises(CommError, match="cannot tell its own messages"):
        LocalTransport().count_own_deliveries()


@given(data=st.data(), sent=st.lists(TOPICS, min_size=1, max_size=30))
def test_own_messages_are_handed_out_in_the_order_sent_whatever_order_they_come_back(
    data, sent
):
    own = OwnDeliveries(exclusive={"sim/a"})
    messages = [Message(topic, {"n": n}, f"own.{n}") for n, topic in enumerate(sent)]
    for message in messages:
        own.sent(message.uid, message.topic)
    back = data.draw(st.permutations(messages))
    lost = data.draw(st.sampled_from([None, *messages]))  # one may never come back
    handed: list[Message] = []
    for message in back:
        if message is lost:
            continue
        ready = own.take(message, own=True)
        assert ready is not None
        handed += ready
        own.delivered(ready)
    # a message from elsewhere is delivered as usual, and counted on an exclusive topic
    assert own.take(Message("sim/a", {}, "elsewhere.1"), own=False) is None
    assert own.take(Message("sim/b", {}, "elsewhere.2"), own=False) is None
    assert own.strangers() == {"sim/a": 1}
    if lost is None:
        assert handed == messages and own.wait(0) == {}
    else:  # what was sent after the lost one waits for it, and the wait names its topic
        assert handed == messages[: messages.index(lost)]
        assert own.wait(0)[lost.topic] >= 1
