"""ROS 2 over Zenoh, as rmw_zenoh speaks it (the format of current ROS 2 releases).

- A topic is the key expression ``<domain>/<topic without its leading slash>/<DDS type
  name>/<RIHS01 type hash>``, e.g. ``0/chatter/std_msgs::msg::dds_::String_/RIHS01_df66...``.
- The payload is the message's CDR, with its 4-byte header.
- Each message carries a 33-byte attachment: sequence number (int64), source time stamp (int64,
  ns since the epoch) and the publisher's GID (a length byte, 16, then 16 bytes), little
  endian: what ``zenoh.ext.z_serialize`` makes of ``(Int64, Int64, bytes)``.
- The graph is made of liveliness tokens, ``@ros2_lv/<domain>/<session id>/<node id>/<entity
  id>/<NN|MP|MS>/<enclave>/<namespace>/<node>[/<topic>/<type>/<hash>/<qos>]`` with ``/`` in
  names written ``%``: one for rasm's node and one per publisher and subscription, so
  ``ros2 node list`` and ``ros2 topic list`` on the Zenoh network see them.

The session is configured as rmw_zenoh's default node session: a Zenoh peer that connects to
the router at ``HOST:PORT`` (``rmw_zenohd`` listens on 7447), listens on an ephemeral loopback
port, has multicast scouting off and learns of the other nodes by the router's gossip, then
connects to them directly (to a peer only when its own zid is the greater, so the other one
connects to rasm). ``ZENOH_SESSION_CONFIG_URI`` names a file that replaces those defaults, as it
does for rmw_zenoh.

Received messages wait in Zenoh's own channel of each subscription, which is the topic's
history: a ring of ``depth`` for keep-last (the oldest goes), a queue of ``max_pending`` for
keep-all (full, it holds the publisher back, as a reliable keep-all one waits in ROS). One
thread per subscribed topic takes them in batches: Zenoh's threads never run Python, which at
sensor rates costs more than the decoding does. A message a publisher sent that a subscription
never got (a sequence number skipped) is counted in ``stats.dropped``.
"""

from __future__ import annotations

import atexit
import itertools
import json
import logging
import os
import struct
import threading
import time
from collections.abc import Sequence
from typing import Any
from urllib.parse import urlsplit
from weakref import WeakSet

import xxhash
import zenoh
import zenoh.ext

from rasm.errors import CommError
from rasm.ros2.transport import (
    RosTopic,
    RosTransport,
    merge_settings,
    node_of,
    oversize,
    url_settings,
)
from rasm.ros2.types import ros_type_name
from rasm.times import format_seconds

__all__ = ["ZenohTransport", "parse_zenoh_url", "topic_key", "liveliness_key", "attachment"]

_log = logging.getLogger("rasm.ros2.zenoh")

ACCEPTED_FORM = (
    "'zenoh://HOST:PORT' or 'zenoh://HOST:PORT?domain=N', optionally with &max_payload=BYTES"
)
DEFAULT_PORT = 7447  # where rmw_zenoh's router listens

_ATTACHMENT = struct.Struct("<qqB16s")  # sequence number, source time (ns), GID length, GID
_GID_SIZE = 16
_BATCH = 1000  # messages a receiving thread takes from its channel at once, at most
_FRAMING = 64 * 1024  # room for a message's key expression, attachment and headers

# rmw_zenoh writes each QoS policy into the token only where it differs from its defaults:
# reliable, volatile, keep last 42 (its default depth), infinite deadline, lifespan and lease.
_RELIABILITY = {"reliable": "", "best_effort": "2"}
_DURABILITY = {"volatile": "", "transient_local": "1"}
_HISTORY = {"keep_last": "", "keep_all": "2"}
_DEFAULT_DEPTH = 42

#: The variable naming a Zenoh configuration file that replaces rmw_zenoh's session defaults.
SESSION_CONFIG_ENV = "ZENOH_SESSION_CONFIG_URI"
_LOOPBACK_LISTEN = "tcp/127.0.0.1:0"
#: rmw_zenoh's default node session (DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5): a peer with
#: multicast scouting off that finds the other nodes through the router's gossip and then
#: connects to them directly (to a peer only when its own zid is the greater). One difference:
#: rasm gossips to peers as well as routers, since its URL may name a peer (a robot's own
#: session) rather than a router, and the others then learn of rasm's endpoint only from it.
RMW_ZENOH_SESSION: dict[str, Any] = {
    "mode": "peer",
    "scouting/multicast/enabled": False,
    "scouting/gossip/enabled": True,
    "scouting/gossip/multihop": False,
    "scouting/gossip/target": {"router": ["router", "peer"], "peer": ["router", "peer"]},
    "scouting/gossip/autoconnect": {"router": [], "peer": ["router", "peer"]},
    "scouting/gossip/autoconnect_strategy": {
        "peer": {"to_router": "always", "to_peer": "greater-zid"}
    },
    "timestamping/enabled": True,  # transient_local's publication cache needs it
}


def parse_zenoh_url(url: str) -> tuple[str, int, dict[str, int]]:
    """``(host, port, settings)`` of a ``zenoh://`` URL, the settings those its query names
    (``domain``, ``max_payload``); :class:`CommError` for anything else."""
    def bad(why: str) -> CommError:
        return CommError(f"bad transport URL {url!r}: {why}; expected {ACCEPTED_FORM}")

    parts = urlsplit(url.strip()) if isinstance(url, str) else None
    if parts is None or parts.scheme != "zenoh":
        raise bad("not a zenoh:// URL")
    if parts.username is not None or parts.password is not None:
        raise bad("credentials do not belong in the URL")
    if parts.path not in ("", "/") or parts.fragment:
        raise bad("a Zenoh URL has no path or fragment")
    try:
        port = parts.port
    except ValueError as exc:
        raise bad(str(exc)) from None
    if not parts.hostname:
        raise bad("no host")
    settings = url_settings(parts.query, url, bad)
    return parts.hostname, port if port is not None else DEFAULT_PORT, settings


def topic_key(domain: int, topic: str, dds_name: str, type_hash: str) -> str:
    """rmw_zenoh's key expression of a topic, as ``0/chatter/<type>/RIHS01_...``."""
    return f"{domain}/{topic.strip('/')}/{dds_name}/{type_hash}"


def _mangle(name: str) -> str:
    return name.replace("/", "%")


def qos_text(topic: RosTopic) -> str:
    """The QoS part of a liveliness token, as rmw_zenoh writes it (``::,10:,:,:,,``)."""
    qos = topic.qos
    depth = "" if qos.depth == _DEFAULT_DEPTH else str(qos.depth)
    return (
        f"{_RELIABILITY[qos.reliability]}:{_DURABILITY[qos.durability]}:"
        f"{_HISTORY[qos.history]},{depth}:,:,:,,"
    )


def liveliness_key(
    domain: int, session_id: str, node_id: int, entity_id: int, kind: str,
    namespace: str, node: str, topic: RosTopic | None = None,
) -> str:
    """The liveliness token of a node (``kind`` NN) or of a publisher (MP) or subscription (MS)."""
    key = (
        f"@ros2_lv/{domain}/{session_id}/{node_id}/{entity_id}/{kind}/%/{_mangle(namespace)}/"
        f"{_mangle(node)}"
    )
    if topic is not None:
        key += (
            f"/{_mangle(topic.name)}/{topic.codec.dds_name}/{topic.codec.type_hash}/"
            f"{qos_text(topic)}"
        )
    return key


def attachment(sequence: int, timestamp_ns: int, gid: bytes) -> bytes:
    """The 33-byte rmw_zenoh attachment of one message."""
    return _ATTACHMENT.pack(sequence, timestamp_ns, _GID_SIZE, gid)


def _gid(key: str) -> bytes:
    """An entity's GID as rmw_zenoh makes it: the XXH3-128 of its liveliness token's key, low
    64 bits then high 64 bits, little endian; so a message's GID names the token of the
    publisher that sent it."""
    digest = xxhash.xxh3_128_intdigest(key.encode())
    return (digest & (2**64 - 1)).to_bytes(8, "little") + (digest >> 64).to_bytes(8, "little")


def _demangle(name: str) -> str:
    return name.replace("%", "/")


class _Graph:
    """The ROS graph as the liveliness tokens on the Zenoh network tell it: the nodes in it
    and, by GID, each publisher's node and topic. Fed by one thread of the transport's."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._nodes: dict[str, int] = {}  # node -> its NN tokens alive
        self._publishers: dict[bytes, tuple[str, str]] = {}  # gid -> (node, topic)
        self._tokens: dict[str, tuple[str, str, bytes | None]] = {}  # key -> (kind, node, gid)

    def put(self, key: str) -> None:
        parts = key.split("/")
        if len(parts) < 9 or parts[0] != "@ros2_lv" or key in self._tokens:
            return
        kind, node = parts[5], node_of(_demangle(parts[7]), parts[8])
        gid = None
        with self._lock:
            if kind == "NN":
                self._nodes[node] = self._nodes.get(node, 0) + 1
            elif kind == "MP" and len(parts) >= 10:
                gid = _gid(key)
                self._publishers[gid] = (node, _demangle(parts[9]))
            if len(self._tokens) < 100_000:  # a bounded memory of the graph
                self._tokens[key] = (kind, node, gid)

    def delete(self, key: str) -> None:
        with self._lock:
            found = self._tokens.pop(key, None)
            if found is None:
                return
            kind, node, gid = found
            if kind == "NN":
                left = self._nodes.get(node, 0) - 1
                if left > 0:
                    self._nodes[node] = left
                else:
                    self._nodes.pop(node, None)
            elif gid is not None:
                self._publishers.pop(gid, None)

    def alive(self, node: str) -> bool:
        with self._lock:
            return node in self._nodes

    def publisher(self, gid: bytes) -> tuple[str, str] | None:
        """The node and topic of the publisher with ``gid``, while its token is alive."""
        with self._lock:
            return self._publishers.get(gid)


# the transports open in this process: closed at exit if their owner did not, as a receiving
# thread still waiting in Zenoh when the interpreter ends aborts the process
_OPEN: WeakSet[ZenohTransport] = WeakSet()


@atexit.register
def _close_open_transports() -> None:
    for transport in list(_OPEN):
        transport.close()


class _Publisher:
    """One topic's Zenoh publisher, its liveliness token, GID and sequence numbers."""

    def __init__(self, publisher: Any, token: Any, gid: bytes) -> None:
        self.publisher = publisher
        self.token = token
        self.gid = gid
        self.sequence = itertools.count(1)

    def undeclare(self) -> None:
        for entity in (self.token, self.publisher):
            try:
                entity.undeclare()
            except zenoh.ZError:
                pass  # the session is already closed: nothing is left to undeclare


class ZenohTransport(RosTransport):
    """ROS 2 topics over Zenoh with rmw_zenoh's conventions (see the module docstring).

    ``url`` is ``zenoh://HOST:PORT[?domain=N]``: the Zenoh router or peer to connect to.
    ``listen`` replaces the ephemeral loopback endpoint this session listens on
    (``["tcp/127.0.0.1:7448"]``); listening on the URL's own ``tcp/HOST:PORT`` makes this
    session the meeting point the others connect to (as rmw_zenoh's router is), connecting
    to nothing itself. ``config_file`` (else the file ``ZENOH_SESSION_CONFIG_URI`` names)
    replaces rmw_zenoh's defaults: the session is configured as the file says, with the URL's
    endpoint added to its connect endpoints and ``listen`` to its listen endpoints.
    ``connect()`` fails with :class:`CommError` if nothing answers at ``HOST:PORT`` within
    ``connect_timeout`` seconds. The other keywords are
    :class:`~rasm.ros2.transport.RosTransport`'s. Its own messages come back to its own
    subscriptions with their publisher's gid and sequence number, so it knows them.
    """

    tells_own_messages = True
    uses_inbox = False  # Zenoh's channel per subscription holds what waits (module docstring)

    def __init__(
        self,
        url: str,
        *,
        listen: Sequence[str] = (),
        config_file: str | None = None,
        connect_timeout: float = 5.0,
        domain: int | None = None,
        max_payload: int | None = None,
        **options: Any,
    ) -> None:
        self.host, self.port, from_url = parse_zenoh_url(url)
        settings = {"domain": domain, "max_payload": max_payload}
        super().__init__(**merge_settings(url, from_url, settings), **options)
        self.url = url
        self.listen = list(listen)
        self.config_file = config_file
        self.connect_timeout = connect_timeout
        self._session: Any = None
        self._session_id = ""
        self._node_token: Any = None
        self._entity_ids = itertools.count(1)  # 0 is the node's
        self._publishers: dict[str, _Publisher] = {}
        self._own_gids: set[str] = set()  # this session's publishers, as in a message's uid
        # topic -> (subscriber, liveliness token, the thread receiving its messages)
        self._subscribers: dict[str, tuple[Any, Any, threading.Thread]] = {}
        self._receiving = threading.local()  # .topic: set on a receiving thread
        self._graph = _Graph()
        self._graph_subscriber: Any = None
        self._graph_thread: threading.Thread | None = None

    # -- the wire -------------------------------------------------------------------------------
    def _open_wire(self) -> None:
        config_file = self.config_file or os.environ.get(SESSION_CONFIG_ENV) or None
        host = f"[{self.host}]" if ":" in self.host else self.host
        endpoint = f"tcp/{host}:{self.port}"
        meeting_point = endpoint in self.listen  # others connect to it; it connects to nothing
        if config_file:
            # the file replaces rmw_zenoh's defaults, as ZENOH_SESSION_CONFIG_URI does for
            # rmw_zenoh; the URL's router and the listen= endpoints are added to its own
            try:
                config = zenoh.Config.from_file(config_file)
            except (zenoh.ZError, OSError) as exc:
                raise CommError(
                    f"{config_file}: not a usable Zenoh configuration: {exc}"
                ) from None
            connect = _endpoints(config, "connect/endpoints")
            listen = _endpoints(config, "listen/endpoints")
            settings: dict[str, Any] = {
                "connect/endpoints": [e for e in connect if e != endpoint]
                + ([] if meeting_point else [endpoint]),
                "listen/endpoints": listen + [e for e in self.listen if e not in listen],
            }
        else:
            config = zenoh.Config()
            settings = {
                **RMW_ZENOH_SESSION,
                "connect/endpoints": [] if meeting_point else [endpoint],
                # an ephemeral loopback port, as rmw_zenoh's tcp/localhost:0: a node that the
                # router's gossip tells about rasm connects to it (greater-zid decides who)
                "listen/endpoints": self.listen or [_LOOPBACK_LISTEN],
            }
        settings.update({
            "connect/timeout_ms": int(self.connect_timeout * 1000),
            "connect/exit_on_failure": True,
            # a message over this arriving in fragments is dropped before it is reassembled
            # (its publisher's next sequence number tells the gap); those that come whole, as
            # through shared memory on one machine, are measured in _take
            "transport/link/rx/max_message_size": self.max_payload + _FRAMING,
        })
        try:
            for key, value in settings.items():
                config.insert_json5(key, json.dumps(value))
            self._session = zenoh.open(config)
        except zenoh.ZError as exc:
            if "listener" in str(exc):  # the session's own listen address, not the peer
                raise CommError(
                    f"could not listen on {', '.join(settings['listen/endpoints'])}: {exc}"
                ) from None
            raise CommError(
                f"could not reach a Zenoh router or peer at {self.host}:{self.port} within "
                f"{format_seconds(self.connect_timeout)} s ({exc}); is one running there? (ROS 2: "
                "ros2 run rmw_zenoh_cpp rmw_zenohd)"
            ) from None
        self._session_id = str(self._session.zid())
        self._node_token = self._declare_token(0, "NN")
        self._follow_graph()
        _OPEN.add(self)

    def _follow_graph(self) -> None:
        """Follow the liveliness tokens of this domain (the ones already there included), on a
        thread of rasm's: Zenoh's own threads never run Python."""
        channel = zenoh.handlers.FifoChannel(self.max_pending)
        self._graph_subscriber = self._session.liveliness().declare_subscriber(
            f"@ros2_lv/{self.domain}/**", channel, history=True
        )
        self._graph_thread = threading.Thread(
            target=self._watch_graph, args=(self._graph_subscriber.handler,),
            name="rasm-zenoh-graph", daemon=True,
        )
        self._graph_thread.start()

    def _watch_graph(self, channel: Any) -> None:
        while (batch := _take_batch(channel)) is not None:
            for sample in batch:
                try:
                    key = str(sample.key_expr)
                    if sample.kind == zenoh.SampleKind.PUT:
                        self._graph.put(key)
                    else:
                        self._graph.delete(key)
                except Exception:
                    _log.exception("error reading the ROS graph's liveliness tokens")

    @property
    def session(self) -> Any:
        """The open Zenoh session (None before ``connect()`` and after ``close()``)."""
        return self._session

    def node_alive(self, node: str) -> bool:
        """Whether ROS node ``node`` has a liveliness token on the network now."""
        return self._graph.alive(node)

    def _close_wire(self) -> None:
        _OPEN.discard(self)
        for publisher in self._publishers.values():
            publisher.undeclare()
        for name in list(self._subscribers):
            self._undeclare_subscriber(name)
        self._publishers.clear()
        if self._graph_subscriber is not None:
            try:
                self._graph_subscriber.undeclare()
            except zenoh.ZError:
                pass
        session, self._session = self._session, None
        if session is not None:
            try:
                self._node_token.undeclare()
            finally:
                session.close()
        if self._graph_thread is not None:
            self._graph_thread.join(timeout=5.0)

    def _declare_token(self, entity_id: int, kind: str, topic: RosTopic | None = None) -> Any:
        key = liveliness_key(
            self.domain, self._session_id, 0, entity_id, kind, self.namespace, self.node_name,
            topic,
        )
        return self._session.liveliness().declare_token(key)

    def _key(self, topic: RosTopic) -> str:
        return topic_key(self.domain, topic.name, topic.codec.dds_name, topic.codec.type_hash)

    def _wire_publisher(self, topic: RosTopic) -> _Publisher:
        found = self._publishers.get(topic.name)
        if found is not None and found.token is not None:
            return found
        qos = topic.qos
        reliable = qos.reliability == "reliable"
        reliability = zenoh.Reliability.RELIABLE if reliable else zenoh.Reliability.BEST_EFFORT
        options: dict[str, Any] = {
            "reliability": reliability,
            # as rmw_zenoh: only a reliable keep-all publisher waits for a slow network
            "congestion_control": zenoh.CongestionControl.BLOCK
            if reliable and qos.keeps_all else zenoh.CongestionControl.DROP,
        }
        if qos.durability == "transient_local":
            # late subscribers get the last `depth` messages from the publisher's cache
            publisher = zenoh.ext.declare_advanced_publisher(
                self._session, self._key(topic),
                cache=zenoh.ext.CacheConfig(max_samples=qos.depth),
                publisher_detection=True, **options,
            )
        else:
            publisher = self._session.declare_publisher(self._key(topic), **options)
        entity_id = next(self._entity_ids)
        token_key = liveliness_key(
            self.domain, self._session_id, 0, entity_id, "MP", self.namespace, self.node_name,
            topic,
        )
        made = _Publisher(publisher, self._session.liveliness().declare_token(token_key),
                          _gid(token_key))
        self._publishers[topic.name] = made
        self._own_gids.add(made.gid.hex())
        return made

    def _wire_send(self, topic: RosTopic, data: bytes) -> None:
        publisher = self._publishers.get(topic.name) or self._wire_publisher(topic)
        sequence = next(publisher.sequence)
        extra = attachment(sequence, time.time_ns(), publisher.gid)
        # the uid it comes back under (_sender): noted before it leaves, as it may be back first
        self._own_sent(f"{publisher.gid.hex()}.{sequence}", topic.name)
        try:
            publisher.publisher.put(data, attachment=extra)
        except zenoh.ZError as exc:
            raise CommError(f"{self.url}: could not publish on {topic.name}: {exc}") from None

    def _wire_matched(self, topic: RosTopic, publisher: _Publisher) -> bool:
        status = getattr(publisher.publisher, "matching_status", None)
        if status is not None:
            return bool(status.matching)
        # a transient_local (advanced) publisher has no matching status: ask the ROS graph
        # whether some subscription of this topic has a liveliness token
        key = f"@ros2_lv/{self.domain}/*/*/*/MS/*/*/*/{_mangle(topic.name)}/**"
        replies = self._session.liveliness().get(key, timeout=self.connect_timeout)
        return any(reply.ok is not None for reply in replies)

    def _in_use(self, topic: str) -> bool:
        return topic in self._publishers

    def _sent_here(self, uid: str | None) -> bool:
        # a uid is its publisher's gid and the message's sequence number (_sender)
        return uid is not None and uid.rpartition(".")[0] in self._own_gids

    def _wire_subscribe(self, topic: RosTopic) -> None:
        if topic.name in self._subscribers:
            return
        # any type and hash: a message with the wrong ones is counted, not silently missed
        key = f"{self.domain}/{topic.name.strip('/')}/*/*"
        qos = topic.qos
        channel = (zenoh.handlers.FifoChannel(self.max_pending) if qos.keeps_all
                   else zenoh.handlers.RingChannel(qos.depth))
        if qos.durability == "transient_local":
            subscriber = zenoh.ext.declare_advanced_subscriber(
                self._session, key, channel,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True),
                subscriber_detection=True,
            )
        else:
            subscriber = self._session.declare_subscriber(key, channel)
        token = self._declare_token(next(self._entity_ids), "MS", topic)
        receiver = threading.Thread(
            target=self._receive, args=(topic, subscriber.handler),
            name=f"rasm-zenoh-{topic.name}", daemon=True,
        )
        self._subscribers[topic.name] = (subscriber, token, receiver)
        receiver.start()

    def _wire_unsubscribe(self, topic: RosTopic) -> None:
        self._undeclare_subscriber(topic.name)

    def _undeclare_subscriber(self, name: str) -> None:
        entry = self._subscribers.pop(name, None)
        if entry is None:
            return
        subscriber, token, receiver = entry
        for entity in (token, subscriber):
            try:
                entity.undeclare()
            except zenoh.ZError:
                pass  # the session is already closed
        # its channel is closed now: the receiver ends after the batch in hand (not awaited
        # from a callback, which holds the delivery another receiver may be waiting for)
        if not getattr(self._receiving, "topic", None):
            receiver.join(timeout=5.0)

    def _receive(self, topic: RosTopic, channel: Any) -> None:
        """Take ``topic``'s messages from its channel and deliver them, until it closes."""
        # the subscription's key ends in /*/*: a sample of the right type and hash has this key
        expected_key = self._key(topic)
        self._receiving.topic = topic.name
        gaps = _SequenceGaps()
        while (batch := _take_batch(channel)) is not None:
            for sample in batch:
                try:
                    if sample.kind != zenoh.SampleKind.PUT:
                        continue
                    key = str(sample.key_expr)
                    if key == expected_key or self._right_type(topic, key):
                        self._take(topic, sample, gaps)
                except Exception:
                    _log.exception("error receiving a message on %s", topic.name)

    def _take(self, topic: RosTopic, sample: Any, gaps: _SequenceGaps) -> None:
        """Deliver one sample of the right type and size, counting what its publisher sent
        before it that never came."""
        uid = stamp = None
        sender = _sender(sample.attachment)
        node = self._restricted.get(topic.name)
        if node is not None:
            known = self._graph.publisher(sender[0]) if sender is not None else None
            if known != (node, topic.name):
                if sender is None:
                    who = "a publisher that sends no GID"
                elif known is None:
                    who = "a publisher with no liveliness token in the graph"
                else:
                    who = f"{known[0]} (on {known[1]})"
                self._foreign(topic, who)
                return
        if sender is not None:
            gid, sequence, stamp = sender
            missed = gaps.missed(gid, sequence)
            if missed:
                self.stats.incr("dropped", missed)
            uid = f"{gid.hex()}.{sequence}"
        size = len(sample.payload)  # Zenoh's own buffer: measured before it is copied or decoded
        if size > self.max_payload:
            self._reject(topic.name, *oversize(size, self.max_payload))
            return
        self._dispatch(topic, sample.payload.to_bytes(), uid, stamp)

    def _right_type(self, topic: RosTopic, key: str) -> bool:
        """Whether ``key`` names the topic's type and type hash; a wrong one is rejected."""
        type_part, hash_part = key.rsplit("/", 2)[-2:]
        expected_hash = topic.codec.type_hash
        if type_part != topic.codec.dds_name:
            self._reject_type(topic, type_part)
            return False
        if hash_part != expected_hash:
            self._reject(
                topic.name, "wrong_hash",
                f"type hash {hash_part[:80]} is not {expected_hash}, this type store's "
                f"{topic.typename} ({self.store.distro}); the publisher's definition differs",
            )
            return False
        return True

    def _reject_type(self, topic: RosTopic, type_part: str) -> None:
        ros_name = ros_type_name(type_part)
        if ros_name is None or ros_name not in self.store:
            self._reject(
                topic.name, "unknown_type",
                f"its type {type_part[:80]!r} is not in the type store (declared type: "
                f"{topic.typename})",
            )
        else:
            self._reject(
                topic.name, "type_conflict",
                f"published as {ros_name}, but declared as {topic.typename}",
            )


def _endpoints(config: Any, key: str) -> list[str]:
    """A configuration's endpoint list (a plain list; the per-mode form gives its peer list)."""
    try:
        found = json.loads(config.get_json(key))
    except (zenoh.ZError, ValueError):
        return []
    if isinstance(found, dict):
        found = found.get("peer", [])
    return [str(e) for e in found] if isinstance(found, list) else []


def _take_batch(channel: Any) -> list[Any] | None:
    """What waits in ``channel`` (at most :data:`_BATCH`), once something does; None once it
    is closed (the subscription was undeclared)."""
    try:
        batch = [channel.recv()]
        while len(batch) < _BATCH and (sample := channel.try_recv()) is not None:
            batch.append(sample)
    except zenoh.ZError:
        return None
    return batch


class _SequenceGaps:
    """The last sequence number of each publisher (by GID) a subscription got."""

    LIMIT = 10_000  # publishers remembered: a bounded memory of who sent what

    def __init__(self) -> None:
        self.last: dict[bytes, int] = {}

    def missed(self, gid: bytes, sequence: int) -> int:
        """How many numbers publisher ``gid`` skipped before ``sequence``: its messages that
        never came (none for a publisher seen first, or one that started counting again)."""
        previous = self.last.get(gid)
        if previous is not None or len(self.last) < self.LIMIT:
            self.last[gid] = sequence
        return sequence - previous - 1 if previous is not None and sequence > previous + 1 else 0


def _sender(extra: Any) -> tuple[bytes, int, float] | None:
    """``(publisher GID, sequence number, source time in s)`` from an rmw_zenoh attachment;
    None without one."""
    if extra is None:
        return None
    data = extra.to_bytes()
    if len(data) != _ATTACHMENT.size:
        return None
    sequence, stamp, size, gid = _ATTACHMENT.unpack(data)
    if size != _GID_SIZE:
        return None
    return gid, sequence, stamp / 1e9
