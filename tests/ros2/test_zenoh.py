"""ZenohTransport against a foreign Zenoh peer (eclipse-zenoh + rosbags only), on loopback."""

from __future__ import annotations

import logging
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.comm import CommError, open_transport
from rasm.ros2 import TypeStore
from rasm.ros2.zenoh import ZenohTransport, liveliness_key, topic_key
from rasm.testing.servers import free_port
from tests.ros2.conftest import wait_until
from tests.ros2.samples import MSG_FILES, SAMPLES, app_store, expected

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"


def _peer(peers, port, role, topics, **extra):
    peer = peers({"middleware": "zenoh", "role": role, "listen": f"tcp/127.0.0.1:{port}",
                  "msg": MSG_FILES, "topics": topics, **extra})
    peer.wait_for(lambda p: p.events, what="the peer to listen")
    return peer


def test_the_design_doc_key_of_std_msgs_string_is_reproduced():
    store = TypeStore()
    codec = store.codec("std_msgs/msg/String")
    assert codec.type_hash == STRING_HASH
    assert topic_key(0, "/chatter", codec.dds_name, codec.type_hash) == (
        f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )
    assert topic_key(3, "/robot1/scan", "sensor_msgs::msg::dds_::LaserScan_", "RIHS01_x") == (
        "3/robot1/scan/sensor_msgs::msg::dds_::LaserScan_/RIHS01_x"
    )


def test_messages_of_a_foreign_publisher_arrive_as_dicts(peers, transports, zenoh_port):
    store = app_store()
    topics = [{"topic": t, "type": ty, "messages": [m]} for t, (ty, m) in SAMPLES.items()]
    peer = _peer(peers, zenoh_port, "pub", topics)
    transport = transports(ZenohTransport(
        f"zenoh://127.0.0.1:{zenoh_port}", store=store,
        types={t: ty for t, (ty, _) in SAMPLES.items()},
    ))
    got = {}
    transport.subscribe("#", lambda m: got.setdefault(m.topic, m))
    transport.connect()
    peer.wait_ready()
    wait_until(lambda: len(got) == len(SAMPLES), what="one message per topic")
    for topic, (typename, message) in SAMPLES.items():
        assert got[topic].payload == expected(store, typename, message), topic
    assert got["/odom"].payload["pose"]["pose"]["position"]["x"] == 1.5
    assert got["/scan"].payload["ranges"][2] == float("inf")
    assert got["/chatter"].payload == {"data": "héllo wörld ✓"}
    assert got["/spin_plan"].payload["skip_sectors"] == [False, True, False]
    # the attachment: the peer's GID and sequence number, its source time stamp
    assert got["/scan"].uid == f"{bytes(range(16)).hex()}.1"
    assert abs(got["/scan"].timestamp - time.time()) < 60
    assert transport.stats.delivered == len(SAMPLES)
    assert transport.stats.malformed == 0


def test_messages_a_publisher_sent_that_never_arrived_are_counted_as_dropped(
    peers, transports, zenoh_port
):
    chatter = [{"data": f"m{i}"} for i in range(5)]
    # the publisher's sequence numbers skip 3, 4 and 7: three messages sent that never arrived
    peer = _peer(peers, zenoh_port, "pub", [{"topic": "/chatter", "type": "std_msgs/msg/String",
                                             "messages": chatter}], sequences=[1, 2, 5, 6, 8])
    transport = transports(ZenohTransport(f"zenoh://127.0.0.1:{zenoh_port}",
                                          types={"/chatter": "std_msgs/msg/String"}))
    got = []
    transport.subscribe("/chatter", got.append)
    transport.connect()
    peer.wait_ready()
    wait_until(lambda: len(got) == 5, what="the five messages sent")
    assert [m.uid.rsplit(".", 1)[1] for m in got] == ["1", "2", "5", "6", "8"]
    assert transport.stats.dropped == 3


def test_a_topic_declared_with_fields_delivers_only_those(peers, transports, zenoh_port):
    topics = [{"topic": t, "type": SAMPLES[t][0], "messages": [SAMPLES[t][1]]}
              for t in ("/odom", "/scan")]
    peer = _peer(peers, zenoh_port, "pub", topics)
    transport = transports(ZenohTransport(
        f"zenoh://127.0.0.1:{zenoh_port}",
        types={t: SAMPLES[t][0] for t in ("/odom", "/scan")},
        fields={"/odom": ["twist.twist.angular.z", "header.stamp.sec"],
                "/scan": ["ranges[1]"]},
    ))
    got = {}
    transport.subscribe("#", lambda m: got.setdefault(m.topic, m.payload))
    transport.connect()
    peer.wait_ready()
    wait_until(lambda: len(got) == 2, what="one message per topic")
    assert got["/odom"] == {"twist": {"twist": {"angular": {"z": -0.5}}},
                            "header": {"stamp": {"sec": 3}}}
    assert got["/scan"] == {"ranges": [0.5, 1.25, float("inf"), 3.0]}


def test_messages_published_reach_a_foreign_subscriber(peers, transports, zenoh_port):
    store = app_store()
    topics = [{"topic": t, "type": ty} for t, (ty, _) in SAMPLES.items()]
    peer = _peer(peers, zenoh_port, "sub", topics)
    transport = transports(ZenohTransport(
        f"zenoh://127.0.0.1:{zenoh_port}", store=store,
        types={t: ty for t, (ty, _) in SAMPLES.items()},
    ))
    transport.connect()
    peer.wait_ready()
    for topic, (_, message) in SAMPLES.items():
        wait_until(lambda topic=topic: transport.has_subscribers(topic), what=f"a match on {topic}")
        transport.publish(topic, message)
    peer.wait_for(lambda p: len(p.messages()) == len(SAMPLES), what="every message")
    received = {e["topic"]: e for e in peer.messages()}
    for topic, (typename, message) in SAMPLES.items():
        assert received[topic]["data"] == expected(store, typename, message), topic
    chatter = received["/chatter"]
    assert chatter["key"] == f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    attachment = bytes.fromhex(chatter["attachment"])
    sequence, stamp, size, gid = struct.unpack("<qqB16s", attachment)
    assert (len(attachment), sequence, size) == (33, 1, 16)
    assert abs(stamp / 1e9 - time.time()) < 60
    assert transport.stats.published == len(SAMPLES)


def test_the_domain_is_the_first_key_part(peers, transports, zenoh_port, monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    peer = _peer(peers, zenoh_port, "sub", [{"topic": "/flag", "type": "std_msgs/msg/Bool"}],
                 domain=42)
    transport = transports(open_transport(f"zenoh://127.0.0.1:{zenoh_port}",
                                          types={"/flag": "std_msgs/msg/Bool"}))
    assert transport.domain == 42
    transport.connect()
    peer.wait_ready()
    wait_until(lambda: transport.has_subscribers("/flag"), what="a match on /flag")
    transport.publish("/flag", {"data": True})
    peer.wait_for(lambda p: p.messages(), what="the message")
    assert peer.messages()[0]["key"].startswith("42/flag/std_msgs::msg::dds_::Bool_/RIHS01_")


def test_the_node_and_its_topics_are_in_the_ros_graph(peers, transports, zenoh_port):
    peer = _peer(peers, zenoh_port, "graph", [])
    peer.wait_ready()
    transport = ZenohTransport(
        f"zenoh://127.0.0.1:{zenoh_port}", node_name="monitor", namespace="/robot1",
        types={"/odom": "nav_msgs/msg/Odometry", "/cmd_vel": "geometry_msgs/msg/Twist"},
        qos={"/odom": {"reliability": "best_effort", "depth": 5}},
    )
    transport.subscribe("/odom", lambda m: None)
    transport.connect()
    transport.advertise("/cmd_vel")
    zid = transport._session_id
    twist = transport.store.codec("geometry_msgs/msg/Twist")
    odom = transport.store.codec("nav_msgs/msg/Odometry")
    node = f"@ros2_lv/0/{zid}/0/0/NN/%/%robot1/monitor"
    prefix = f"@ros2_lv/0/{zid}/0/"
    publisher = (f"MP/%/%robot1/monitor/%cmd_vel/geometry_msgs::msg::dds_::Twist_/"
                 f"{twist.type_hash}/::,10:,:,:,,")
    subscription = (f"MS/%/%robot1/monitor/%odom/nav_msgs::msg::dds_::Odometry_/"
                    f"{odom.type_hash}/2::,5:,:,:,,")

    def tokens(kind: str) -> list[str]:
        return [e["key"] for e in peer.events if e["event"] == "token" and kind in e["kind"]]

    wait_until(lambda: len(tokens("PUT")) >= 3, what="three liveliness tokens")
    keys = tokens("PUT")
    assert node in keys
    assert any(k.startswith(prefix) and k.endswith(publisher) for k in keys), keys
    assert any(k.startswith(prefix) and k.endswith(subscription) for k in keys), keys
    assert node == liveliness_key(0, zid, 0, 0, "NN", "/robot1", "monitor")
    transport.close()
    wait_until(lambda: len(tokens("DELETE")) >= 3, what="the tokens to go with the node")


def test_wrong_hash_unknown_type_and_other_type_are_counted_not_delivered(
    peers, transports, zenoh_port, caplog
):
    store = TypeStore()
    odom = store.codec("nav_msgs/msg/Odometry")
    string = store.codec("std_msgs/msg/String")
    good = odom.encode({}).hex()
    bad_keys = {
        "wrong_hash": f"0/odom/{odom.dds_name}/RIHS01_{'0' * 64}",
        "unknown_type": f"0/odom/foo_msgs::msg::dds_::Bar_/RIHS01_{'1' * 64}",
        "type_conflict": f"0/odom/{string.dds_name}/{string.type_hash}",
    }
    topics = [{"topic": "/odom", "key": key, "raw": [good] * 3} for key in bad_keys.values()]
    peer = _peer(peers, zenoh_port, "pub", topics)
    transport = transports(ZenohTransport(f"zenoh://127.0.0.1:{zenoh_port}",
                                          types={"/odom": "nav_msgs/msg/Odometry"}))
    delivered = []
    transport.subscribe("/odom", delivered.append)
    with caplog.at_level(logging.WARNING, logger="rasm.ros2"):
        transport.connect()
        peer.wait_ready()
        wait_until(lambda: sum(transport.rejected.values()) == 9, what="nine rejections")
    assert transport.rejected == {"malformed": 0, "wrong_hash": 3, "unknown_type": 3,
                                  "type_conflict": 3, "foreign_publisher": 0, "oversize": 0}
    assert delivered == []
    assert transport.stats.malformed == 9
    warnings = [r.getMessage() for r in caplog.records if r.name == "rasm.ros2"]
    assert len(warnings) == 3  # once per topic and reason
    assert any("RIHS01_000" in w and "/odom" in w for w in warnings)
    assert any("std_msgs/msg/String" in w for w in warnings)


@pytest.mark.slow
@settings(max_examples=4, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(payloads=st.lists(st.binary(max_size=200), min_size=10, max_size=40))
def test_hostile_payloads_never_escape_the_transport(peers, payloads):
    store = TypeStore()
    codec = store.codec("nav_msgs/msg/Odometry")
    port = free_port()  # a port per example: the previous peer may still hold its own
    peer = _peer(peers, port, "pub", [{"topic": "/odom", "type": "nav_msgs/msg/Odometry",
                                       "raw": [p.hex() for p in payloads]}])
    transport = ZenohTransport(f"zenoh://127.0.0.1:{port}", store=store,
                               types={"/odom": "nav_msgs/msg/Odometry"},
                               qos={"/odom": {"history": "keep_all"}})
    delivered = []
    transport.subscribe("/odom", lambda m: delivered.append(m.payload))
    try:
        transport.connect()
        peer.wait_ready()
        wait_until(lambda: len(delivered) + transport.rejected["malformed"] == len(payloads),
                   what="every payload delivered or rejected")
    finally:
        transport.close()
        peer.stop()
    decodable = []
    for data in payloads:
        try:
            decodable.append(codec.decode(data))
        except CommError:
            pass
    assert delivered == decodable
    assert transport.stats.errors == 0


def test_connect_fails_loudly_when_nothing_answers(zenoh_port):
    transport = ZenohTransport(f"zenoh://127.0.0.1:{zenoh_port}", connect_timeout=0.5)
    started = time.monotonic()
    with pytest.raises(CommError, match="rmw_zenohd"):
        transport.connect()
    assert time.monotonic() - started < 5
    with pytest.raises(CommError, match="not open"):
        transport.publish("/x", {})


@pytest.mark.slow
def test_a_process_that_never_closes_its_transport_still_exits_cleanly(zenoh_port):
    # its receiving thread waits in Zenoh all along: left there, the interpreter's end would
    # abort the process
    script = (
        "import threading\n"
        "from rasm.ros2 import ZenohTransport\n"
        f"t = ZenohTransport('zenoh://127.0.0.1:{zenoh_port}', "
        f"listen=['tcp/127.0.0.1:{zenoh_port}'], types={{'/quiet': 'std_msgs/msg/String'}})\n"
        "heard = threading.Event()\n"
        "t.subscribe('/quiet', lambda m: heard.set())\n"
        "t.connect()\n"
        "print(heard.wait(1.0))\n"  # a second without a message
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=60, cwd=Path(__file__).resolve().parents[2])
    assert (done.returncode, done.stdout) == (0, "False\n"), done.stderr
