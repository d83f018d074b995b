"""``zenoh://HOST:PORT`` joins a ROS graph as an rmw_zenoh node does: through a real Zenoh router
configured as ``rmw_zenohd``, with peers configured as rmw_zenoh's default node session."""

from __future__ import annotations

import json

from rasm.ros2.zenoh import SESSION_CONFIG_ENV, ZenohTransport
from rasm.testing.servers import free_port
from tests.ros2.conftest import wait_until

STRING = "std_msgs/msg/String"


def test_two_rasm_processes_behind_a_router_exchange_data(transports, zenoh_router):
    """The managed and the managing side (each a peer of the router) reach each other."""
    url = f"zenoh://127.0.0.1:{zenoh_router}"
    managed = transports(ZenohTransport(url, types={"/temperature": STRING}, node_name="managed"))
    managing = transports(ZenohTransport(url, types={"/temperature": STRING},
                                         node_name="managing"))
    got = []
    managing.subscribe("/temperature", got.append)
    managed.connect()
    managing.connect()
    wait_until(lambda: (managed.publish("/temperature", {"data": "37.5"}), got)[1],
               what="a message from the other rasm process")
    assert got[0].payload == {"data": "37.5"}


def test_an_rmw_zenoh_node_behind_the_router_reaches_rasm_both_ways(
    peers, transports, zenoh_router
):
    """A node with rmw_zenoh's default session (peer, router at HOST:PORT, tcp/localhost:0,
    gossip with greater-zid) publishes to rasm and receives rasm's messages."""
    router = f"tcp/127.0.0.1:{zenoh_router}"
    common = {"middleware": "zenoh", "listen": "tcp/127.0.0.1:0", "connect": [router],
              "rmw": True, "msg": []}
    talker = peers({**common, "role": "pub", "repeat": True,
                    "topics": [{"topic": "/chatter", "type": STRING,
                                "messages": [{"data": "from ros"}]}]})
    listener = peers({**common, "role": "sub",
                      "topics": [{"topic": "/answer", "type": STRING, "messages": []}]})
    transport = transports(ZenohTransport(f"zenoh://127.0.0.1:{zenoh_router}",
                                          types={"/chatter": STRING, "/answer": STRING}))
    got = []
    transport.subscribe("/chatter", got.append)
    transport.connect()
    listener.wait_ready()
    wait_until(lambda: got, what="the rmw_zenoh node's message")
    assert got[0].payload == {"data": "from ros"}
    wait_until(lambda: (transport.publish("/answer", {"data": "from rasm"}),
                        listener.messages("/answer"))[1], what="rasm's message at the node")
    assert listener.messages("/answer")[0]["data"] == {"data": "from rasm"}
    talker.stop()


def test_zenoh_session_config_uri_replaces_the_defaults(
    peers, transports, zenoh_router, tmp_path, monkeypatch
):
    """As for rmw_zenoh: the file's listen endpoint is where rasm listens, so a peer that knows
    only that endpoint (no router) connects straight to rasm."""
    own = free_port()
    config = tmp_path / "session.json5"
    config.write_text(json.dumps({
        "mode": "peer", "listen": {"endpoints": [f"tcp/127.0.0.1:{own}"]},
        "scouting": {"multicast": {"enabled": False}},
    }))
    monkeypatch.setenv(SESSION_CONFIG_ENV, str(config))
    transport = transports(ZenohTransport(f"zenoh://127.0.0.1:{zenoh_router}",
                                          types={"/answer": STRING}))
    transport.connect()
    listener = peers({"middleware": "zenoh", "role": "sub", "listen": "tcp/127.0.0.1:0",
                      "connect": [f"tcp/127.0.0.1:{own}"], "msg": [],
                      "topics": [{"topic": "/answer", "type": STRING, "messages": []}]})
    listener.wait_ready()
    wait_until(lambda: (transport.publish("/answer", {"data": "direct"}),
                        listener.messages("/answer"))[1], what="rasm's message at the peer")
