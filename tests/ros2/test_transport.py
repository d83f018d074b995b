"""What both ROS 2 transports share: the keep-last inbox, declared topics, URLs (no network)."""

from __future__ import annotations

from collections import defaultdict

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.comm import CommError, open_transport
from rasm.comm.url import credentials_from_env
from rasm.ros2 import QosProfile, RosError
from rasm.ros2.transport import KeepLastInbox, validate_ros_topic
from rasm.ros2.zenoh import ZenohTransport, parse_zenoh_url, qos_text

_puts = st.lists(st.tuples(st.sampled_from("abc"), st.integers(1, 4)), max_size=60)


@given(_puts, st.integers(1, 30))
def test_the_inbox_keeps_the_last_depth_items_of_each_key_in_order(puts, limit):
    inbox = KeepLastInbox(limit)
    sent = defaultdict(list)
    for number, (key, depth) in enumerate(puts):
        inbox.put(key, (key, number), depth)
        sent[key].append(number)
    assert len(inbox) <= limit
    out = []
    while (item := inbox.get(timeout=0)) is not None:
        out.append(item)
    got = defaultdict(list)
    for key, number in out:
        got[key].append(number)
    for key, numbers in got.items():
        assert numbers == sorted(numbers)  # first in, first out per key
        assert numbers == sent[key][-len(numbers):]  # the newest survive
        assert len(numbers) <= max(d for k, d in puts if k == key)
    assert inbox.dropped == len(puts) - len(out)


@given(_puts, st.integers(1, 30), st.integers(0, 60))
def test_the_inbox_drained_at_once_gives_what_get_gives_one_by_one(puts, limit, cut):
    one, drained = KeepLastInbox(limit), KeepLastInbox(limit)
    out_one, out_drained = [], []
    for number, (key, depth) in enumerate(puts):  # taken part way through, then at the end
        for inbox in (one, drained):
            inbox.put(key, (key, number), depth)
        if number == cut:
            while (item := one.get(timeout=0)) is not None:
                out_one.append(item)
            out_drained += drained.get_all(timeout=0)
    while (item := one.get(timeout=0)) is not None:
        out_one.append(item)
    out_drained += drained.get_all(timeout=0)
    assert out_drained == out_one
    assert drained.get_all(timeout=0) == [] and len(drained) == 0
    assert drained.dropped == one.dropped


def test_a_closed_inbox_still_gives_what_it_holds_then_nothing():
    inbox = KeepLastInbox(10)
    inbox.put("a", 1, None)
    inbox.put("b", 2, None)
    inbox.close()
    assert inbox.get_all() == [1, 2]
    assert inbox.get_all() == []  # closed and empty: no wait


def test_keep_all_is_bounded_by_the_inbox_limit():
    inbox = KeepLastInbox(3)
    for i in range(5):
        inbox.put("k", i, None)
    assert [inbox.get(0), inbox.get(0), inbox.get(0), inbox.get(0)] == [2, 3, 4, None]
    inbox.close()
    assert inbox.put("k", 9, None) is False


def test_ros_topic_names():
    assert validate_ros_topic("/robot1/scan") == "/robot1/scan"
    for bad in ("odom", "/", "/a//b", "/a/", "/1st", "/a b", "/odom/#"):
        with pytest.raises(CommError):
            validate_ros_topic(bad)


def test_topics_are_declared_once_with_one_type():
    transport = ZenohTransport("zenoh://127.0.0.1:7447", types={"/odom": "nav_msgs/Odometry"})
    assert transport.topics["/odom"].typename == "nav_msgs/msg/Odometry"
    assert transport.declare("/odom", "nav_msgs/msg/Odometry") is transport.topics["/odom"]
    with pytest.raises(CommError, match="already declared as nav_msgs/msg/Odometry"):
        transport.declare("/odom", "std_msgs/msg/String")
    with pytest.raises(CommError, match="unknown message type 'nav_msgs/msg/Odom'"):
        transport.declare("/x", "nav_msgs/msg/Odom")
    with pytest.raises(CommError, match="QoS or fields given for '/scan'"):
        ZenohTransport("zenoh://h:1", qos={"/scan": {"depth": 3}})
    with pytest.raises(RosError, match="depth must be a positive integer"):
        transport.declare("/y", "std_msgs/msg/Bool", qos={"depth": 0})
    with pytest.raises(RosError, match="unknown QoS setting 'deph'"):
        transport.declare("/y", "std_msgs/msg/Bool", qos={"deph": 3})


def test_zenoh_urls():
    assert parse_zenoh_url("zenoh://127.0.0.1:7448") == ("127.0.0.1", 7448, {})
    assert parse_zenoh_url("zenoh://localhost") == ("localhost", 7447, {})
    assert parse_zenoh_url("zenoh://[::1]:7447?domain=9") == ("::1", 7447, {"domain": 9})
    assert parse_zenoh_url("zenoh://h:1?max_payload=2048") == ("h", 1, {"max_payload": 2048})
    transport = open_transport("zenoh://127.0.0.1:7449?domain=2")
    assert (type(transport), transport.port, transport.domain) == (ZenohTransport, 7449, 2)
    for bad in ("zenoh://", "zenoh://h:1/path", "zenoh://h:1?domain=1&x=2", "zenoh://u:p@h:1",
                "zenoh://h:1?domain=-1", "zenoh://h:1?max_payload=-5"):
        with pytest.raises(CommError, match="zenoh://"):
            parse_zenoh_url(bad)
    with pytest.raises(CommError, match="dds://"):
        open_transport("ros2://x")


def test_mqtt_credentials_are_not_given_to_ros_transports():
    env = {"RASM_MQTT_USERNAME": "u", "RASM_MQTT_PASSWORD": "p"}
    assert credentials_from_env("zenoh://127.0.0.1:7447", env) == {}
    assert credentials_from_env("dds://", env) == {}
    assert credentials_from_env("mqtt://127.0.0.1:1883", env) == {"username": "u",
                                                                "password": "p"}


def test_the_qos_text_of_liveliness_tokens_is_rmw_zenohs():
    transport = ZenohTransport("zenoh://h:1", types={
        "/a": "std_msgs/msg/Bool", "/b": "std_msgs/msg/Bool", "/c": "std_msgs/msg/Bool",
    }, qos={"/b": QosProfile(depth=42), "/c": {"reliability": "best_effort",
                                                 "durability": "transient_local",
                                                 "history": "keep_all"}})
    assert qos_text(transport.topics["/a"]) == "::,10:,:,:,,"
    assert qos_text(transport.topics["/b"]) == "::,:,:,:,,"  # 42 is rmw_zenoh's default depth
    assert qos_text(transport.topics["/c"]) == "2:1:2,10:,:,:,,"


def test_a_topics_qos_cannot_change_once_in_use(transports, dds_domain):
    from rasm.ros2 import DdsTransport

    transport = transports(DdsTransport(f"dds://?domain={dds_domain}",
                                        types={"/odom": "nav_msgs/msg/Odometry"}))
    transport.declare("/odom", "nav_msgs/msg/Odometry", qos={"depth": 3})  # not used yet: fine
    transport.subscribe("/odom", lambda m: None)
    transport.connect()
    with pytest.raises(CommError, match="its QoS cannot change now"):
        transport.declare("/odom", "nav_msgs/msg/Odometry", qos={"depth": 4})
    assert transport.topics["/odom"].qos.depth == 3


def test_a_zenoh_session_that_cannot_listen_says_so_not_that_no_router_answered():
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        t = open_transport(f"zenoh://127.0.0.1:{port}", listen=[f"tcp/127.0.0.1:{port}"])
        with pytest.raises(CommError, match=f"could not listen on tcp/127.0.0.1:{port}") as err:
            t.connect()
    assert "router" not in str(err.value)
