"""What the Zenoh and DDS transports share.

A ROS 2 transport is a :class:`~rasm.comm.transport.Transport` whose topics are ROS topic names
(``/odom``) and whose payloads are ROS messages as plain dicts. Each topic has one message type
and one QoS profile, declared before use (:meth:`RosTransport.declare`, or ``types=`` and
``qos=`` at construction). rasm's MQTT-style patterns apply to ROS names level by level:
``/odom`` is the levels ``""`` and ``odom``, so ``/robot1/+`` matches ``/robot1/odom`` and ``#``
matches every declared topic. A pattern subscribes to the declared topics it matches, including
topics declared later.

Received messages wait, per topic at most the QoS depth (keep-last: the oldest goes first),
until a thread of rasm's takes them, decodes them and runs the callbacks; so a slow callback
never stalls the middleware's own threads. Where they wait is the subclass's choice: Zenoh's own
channel per subscription, with one receiving thread each (:mod:`rasm.ros2.zenoh`), or this
module's inbox with one dispatcher thread per transport (:mod:`rasm.ros2.dds`). Either way the
callbacks of one transport run one at a time. Bad input from the wire (bytes that do not
decode, a wrong type hash, a type the store does not know, a topic published with another type,
a message over ``max_payload`` bytes) is never delivered and never fatal: it is counted in
``stats.malformed`` and in :attr:`RosTransport.rejected` by reason, and logged once per topic
and reason.
"""

from __future__ import annotations

import itertools
import logging
import os
import re
import threading
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar
from urllib.parse import parse_qs

from rasm.comm.envelope import MAX_PAYLOAD
from rasm.comm.message import Message
from rasm.comm.topics import topic_matches
from rasm.comm.transport import Transport
from rasm.errors import CommError
from rasm.ros2.codec import MessageCodec
from rasm.ros2.errors import MalformedMessage, MessageError, RosError
from rasm.ros2.fieldread import projection
from rasm.ros2.qos import DEFAULT_QOS, QosProfile
from rasm.ros2.types import TypeStore, default_store

__all__ = [
    "REJECTIONS",
    "RosTopic",
    "RosTransport",
    "check_max_payload",
    "domain_from_env",
    "node_of",
    "oversize",
    "validate_node_name",
    "validate_ros_topic",
]

_log = logging.getLogger("rasm.ros2")

#: Why a received message was not delivered (the keys of :attr:`RosTransport.rejected`).
REJECTIONS = (
    "malformed", "wrong_hash", "unknown_type", "type_conflict", "foreign_publisher", "oversize",
)

_NAME_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
MAX_DOMAIN = 232  # the highest ROS domain id DDS can map to UDP ports


def validate_ros_topic(name: str) -> str:
    """Return ``name`` if it is an absolute ROS topic name (``/odom``, ``/robot1/scan``)."""
    if not isinstance(name, str) or not name.startswith("/") or name == "/":
        raise CommError(
            f"{name!r} is not an absolute ROS topic name: write it with its leading slash, "
            "as in /odom"
        )
    for token in name[1:].split("/"):
        if not _NAME_TOKEN.fullmatch(token):
            raise CommError(
                f"ROS topic name {name!r}: {token!r} is not a valid name token (letters, digits "
                "and '_', not starting with a digit; no empty level)"
            )
    return name


def validate_node_name(node: str) -> str:
    """Return ``node`` if it is a fully qualified ROS node name (``/name``, ``/ns/name``)."""
    if not isinstance(node, str) or not node.startswith("/") or not all(
        _NAME_TOKEN.fullmatch(token) for token in node[1:].split("/")
    ):
        raise CommError(
            f"{node!r} is not a fully qualified ROS node name (/name or /namespace/name)"
        )
    return node


def node_of(namespace: str, name: str) -> str:
    """A node's fully qualified name from its namespace and name."""
    return f"{namespace.rstrip('/')}/{name}"


def check_domain(domain: Any, where: str = "ROS domain id") -> int:
    """``domain`` as an int in 0..232, else :class:`CommError`."""
    text = str(domain).strip()
    if not text.isdigit() or int(text) > MAX_DOMAIN:
        raise CommError(f"{where} must be an integer from 0 to {MAX_DOMAIN}, got {domain!r}")
    return int(text)


def check_max_payload(value: Any, where: str = "max_payload") -> int:
    """``value`` as a positive number of bytes, else :class:`CommError`."""
    text = str(value).strip()
    if isinstance(value, bool) or not text.isdigit() or int(text) < 1:
        raise CommError(f"{where} must be a positive whole number of bytes, got {value!r}")
    return int(text)


# what a ROS 2 transport URL's query may set, and how each value is checked
_URL_SETTINGS: dict[str, Callable[[Any, str], int]] = {
    "domain": check_domain, "max_payload": check_max_payload,
}


def url_settings(query: str, url: str, bad: Callable[[str], CommError]) -> dict[str, int]:
    """The settings a ROS 2 transport URL's query gives (``domain=N``, ``max_payload=BYTES``,
    each at most once): only those it names. ``bad(why)`` makes the error for a bad query."""
    found = parse_qs(query, keep_blank_values=True)
    unknown = sorted(set(found) - set(_URL_SETTINGS))
    if unknown:
        raise bad(f"unknown query parameter {unknown[0]!r} (the parameters are domain=N and "
                  "max_payload=BYTES)")
    if any(len(values) != 1 for values in found.values()):
        raise bad("each query parameter is given once")
    return {
        key: _URL_SETTINGS[key](values[0], f"{key}= in {url!r}") for key, values in found.items()
    }


def merge_settings(url: str, from_url: Mapping[str, int], given: Mapping[str, Any]) -> dict:
    """The keyword settings ``given`` (None: not given) with those of ``url``'s query; a
    keyword that contradicts the URL raises :class:`CommError`."""
    merged = {key: value for key, value in given.items() if value is not None}
    for key, value in from_url.items():
        if merged.get(key, value) != value:
            raise CommError(f"{url}: {key}={merged[key]} contradicts the URL's {key}={value}")
        merged[key] = value
    return merged


def oversize(size: int, limit: int) -> tuple[str, str]:
    """The rejection of a received message of ``size`` bytes over ``limit``: never decoded."""
    return "oversize", (
        f"{size} bytes, over the {limit}-byte limit (max_payload), not decoded"
    )


def domain_from_env(environ: Mapping[str, str] | None = None) -> int:
    """The ROS domain id from ``ROS_DOMAIN_ID`` (as ROS 2 reads it), else 0."""
    env = os.environ if environ is None else environ
    value = env.get("ROS_DOMAIN_ID", "").strip()
    return check_domain(value, "ROS_DOMAIN_ID") if value else 0


@dataclass(frozen=True)
class RosTopic:
    """A declared topic: its ROS name, its message type (as a codec), its QoS and how its
    messages are decoded (the whole message, or only the fields declared)."""

    name: str
    codec: MessageCodec
    qos: QosProfile
    decode: Callable[[bytes], dict[str, Any]]

    @property
    def typename(self) -> str:
        return self.codec.typename


T = TypeVar("T")


class KeepLastInbox(Generic[T]):
    """Received items waiting for the dispatcher, in arrival order.

    Per key at most ``depth`` items wait (``None``: no per-key limit); a new item beyond that
    replaces the key's oldest, which is how a ROS keep-last history behaves. In all at most
    ``limit`` items wait; beyond that the oldest of all goes. :meth:`put` never blocks.
    """

    def __init__(self, limit: int) -> None:
        if limit < 1:
            raise ValueError(f"limit must be at least 1, got {limit}")
        self.limit = limit
        self.dropped = 0
        self._queues: dict[Any, deque[T]] = {}
        # one key per waiting item, in arrival order: whose oldest item is served next
        self._order: deque[Any] = deque()
        self._cond = threading.Condition(threading.Lock())
        self._getters = 0  # waiting in get() or get_all(): what put() must wake
        self._closed = False

    def put(self, key: Any, item: T, depth: int | None) -> bool:
        """Queue ``item`` under ``key``; False if an older item was dropped for it (or closed)."""
        with self._cond:
            if self._closed:
                return False
            queue = self._queues.get(key)
            if queue is None:
                queue = self._queues[key] = deque()
            if depth is not None and len(queue) >= depth:
                queue.popleft()  # the key keeps its place in the order: one out, one in
                queue.append(item)
                self.dropped += 1
                return False
            kept = True
            if len(self._order) >= self.limit:
                self._queues[self._order.popleft()].popleft()
                self.dropped += 1
                kept = False
            queue.append(item)
            self._order.append(key)
            if self._getters:  # at high rates the getter is mostly busy: no one to wake
                self._cond.notify()
            return kept

    def get(self, timeout: float | None = None) -> T | None:
        """The next item; ``None`` once closed and empty, or when ``timeout`` expires."""
        with self._cond:
            self._wait(timeout)
            if not self._order:
                return None
            return self._queues[self._order.popleft()].popleft()

    def get_all(self, timeout: float | None = None) -> list[T]:
        """Every waiting item, in the order :meth:`get` would give them, once there is one;
        empty once closed and empty, or when ``timeout`` expires. One lock for all of them."""
        with self._cond:
            self._wait(timeout)
            items = [self._queues[key].popleft() for key in self._order]
            self._order.clear()
            return items

    def _wait(self, timeout: float | None) -> None:
        """Wait (holding the lock) until an item is there, the inbox closes or ``timeout``."""
        if self._order or self._closed:
            return
        self._getters += 1
        try:
            self._cond.wait_for(lambda: self._order or self._closed, timeout)
        finally:
            self._getters -= 1

    def close(self) -> None:
        """Wake every waiting :meth:`get`; items already queued can still be taken."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def __len__(self) -> int:
        return len(self._order)


# what waits in the inbox: the topic, the CDR bytes, the sender's message id and time stamp
_Received = tuple[RosTopic, bytes, "str | None", "float | None"]


class RosTransport(Transport):
    """Base class of :class:`~rasm.ros2.zenoh.ZenohTransport` and
    :class:`~rasm.ros2.dds.DdsTransport`: declared topics, the inbox, the dispatcher, the
    counting of bad input. Subclasses move bytes; they implement the ``_wire_*`` hooks.

    ``types`` maps ROS topic names to message types (``{"/odom": "nav_msgs/msg/Odometry"}``),
    ``qos`` topic names to a :class:`QosProfile` or a mapping of its settings, ``fields`` topic
    names to the field paths their subscribers read (see :meth:`declare`). ``store`` is the
    :class:`TypeStore` (default: ROS 2 Jazzy's standard interfaces). ``domain`` defaults to
    ``ROS_DOMAIN_ID``, else 0. ``node_name`` and ``namespace`` name the ROS node rasm appears
    as. The integer ``qos=`` of :meth:`publish` and :meth:`subscribe` (MQTT's) is accepted and
    ignored: a ROS topic's QoS is its profile.
    """

    def __init__(
        self,
        *,
        types: Mapping[str, str] | None = None,
        qos: Mapping[str, QosProfile | Mapping[str, Any]] | None = None,
        fields: Mapping[str, Sequence[str]] | None = None,
        store: TypeStore | None = None,
        domain: int | None = None,
        node_name: str = "rasm",
        namespace: str = "/",
        max_pending: int = 10_000,
        max_payload: int | None = None,
    ) -> None:
        super().__init__()
        self.store = store if store is not None else default_store()
        self.max_payload = MAX_PAYLOAD if max_payload is None else check_max_payload(max_payload)
        self.domain = domain_from_env() if domain is None else check_domain(domain)
        if not _NAME_TOKEN.fullmatch(node_name or ""):
            raise CommError(f"{node_name!r} is not a valid ROS node name")
        if namespace != "/":
            validate_ros_topic(namespace)
        self.node_name = node_name
        self.namespace = namespace
        self._topics: dict[str, RosTopic] = {}
        self._restricted: dict[str, str] = {}  # topic -> the only node whose messages count
        self._wired: set[str] = set()  # topics with a subscription on the wire
        self._rejected = dict.fromkeys(REJECTIONS, 0)
        self._reported: set[tuple[str, str]] = set()  # (topic, reason) already logged
        self._reject_lock = threading.Lock()
        self.max_pending = max_pending
        self._inbox: KeepLastInbox[_Received] = KeepLastInbox(max_pending)
        self._delivery_lock = threading.Lock()  # the callbacks run one at a time
        self._uids = itertools.count(1)
        self._dispatcher: threading.Thread | None = None
        profiles = dict(qos or {})
        projections = dict(fields or {})
        for topic, typename in (types or {}).items():
            self.declare(topic, typename, qos=profiles.pop(topic, None),
                         fields=projections.pop(topic, None))
        if profiles or projections:
            raise CommError(
                f"QoS or fields given for {sorted({*profiles, *projections})[0]!r}, which has "
                "no type in types="
            )

    # -- topics ---------------------------------------------------------------------------------
    def declare(
        self,
        topic: str,
        typename: str,
        *,
        qos: QosProfile | Mapping[str, Any] | None = None,
        fields: Sequence[str] | None = None,
    ) -> RosTopic:
        """Give ``topic`` its message type (and QoS; default reliable, keep last 10).

        With ``fields`` (field paths), a received message is decoded only as far as those
        paths need: subscribers get a dict holding just them, nested as in the whole message
        (:func:`rasm.ros2.fieldread.projection`), which costs a fraction of decoding it all.

        Declaring a topic again with the same type changes nothing; with another type it
        raises :class:`CommError`: a ROS topic has one type. Subscriptions whose pattern
        matches the topic start receiving it.
        """
        validate_ros_topic(topic)
        profile = qos if isinstance(qos, QosProfile) else (
            QosProfile.from_mapping(qos) if qos is not None else DEFAULT_QOS
        )
        try:
            codec = self.store.codec(typename)
        except RosError as exc:
            raise CommError(f"cannot declare {topic}: {exc}") from None
        known = self._topics.get(topic)
        if known is not None:
            if known.typename != codec.typename:
                raise CommError(
                    f"{topic} is already declared as {known.typename}; a ROS topic has one type "
                    f"(not also {codec.typename})"
                )
            if qos is None or known.qos == profile:
                return known
            if known.name in self._wired or self._in_use(known.name):
                raise CommError(
                    f"{topic} is already in use with {known.qos}; its QoS cannot change now "
                    "(declare it with its QoS before subscribing or publishing)"
                )
        try:
            decode = codec.decode if fields is None else projection(
                self.store, codec.typename, fields
            )
        except RosError as exc:
            raise CommError(f"cannot declare {topic}: {exc}") from None
        declared = self._topics[topic] = RosTopic(topic, codec, profile, decode)
        if self._state == "open" and self._wanted(topic) and topic not in self._wired:
            self._wire_subscribe(declared)
            self._wired.add(topic)
        return declared

    def restrict(self, topic: str, node: str) -> None:
        """Deliver only the messages of ``topic`` that ROS node ``node`` (``/name`` or
        ``/namespace/name``) publishes while it is in the graph; every other publisher's are
        refused as ``foreign_publisher`` (counted, logged once). Zenoh: the message's GID must
        be that of one of the node's publishers of the topic, by their liveliness tokens; DDS:
        its writer must be one the node's participant announces on ``ros_discovery_info``.
        Without SROS2 this tells publishers apart, it does not authenticate them: whoever
        joins the graph may take the node's name (docs/threats.md)."""
        validate_node_name(node)
        self._restricted[topic] = node

    def node_alive(self, node: str) -> bool:
        """Whether ROS node ``node`` is in the graph now."""
        raise NotImplementedError

    def _foreign(self, topic: RosTopic, who: str) -> None:
        """Refuse one message of a restricted topic that its declared node did not send."""
        self._reject(
            topic.name, "foreign_publisher",
            f"published by {who}, not by {self._restricted[topic.name]} (its declared publisher)",
        )

    @property
    def topics(self) -> dict[str, RosTopic]:
        """The declared topics by name (a copy)."""
        return dict(self._topics)

    def advertise(self, topic: str) -> None:
        """Create the publisher of a declared topic now (before the first message), so that
        ROS tools list it; :meth:`publish` otherwise creates it on first use."""
        self._require_open(f"advertise {topic!r}")
        self._wire_publisher(self._declared(topic, "advertise"))

    def has_subscribers(self, topic: str) -> bool:
        """True if some subscriber on the network matches this transport's publisher of
        ``topic`` (created if need be): what a sender waits for before its first message."""
        self._require_open(f"look for subscribers of {topic!r}")
        declared = self._declared(topic, "look for subscribers of")
        return self._wire_matched(declared, self._wire_publisher(declared))

    @property
    def rejected(self) -> dict[str, int]:
        """Received messages not delivered, by reason (see :data:`REJECTIONS`)."""
        with self._reject_lock:
            return dict(self._rejected)

    def _declared(self, topic: str, what: str) -> RosTopic:
        found = self._topics.get(topic)
        if found is None:
            validate_ros_topic(topic)
            raise CommError(
                f"cannot {what} {topic}: it has no declared message type; declare it first "
                f"(transport.declare({topic!r}, 'pkg/msg/Type') or types={{{topic!r}: ...}})"
            )
        return found

    def _in_use(self, topic: str) -> bool:
        """True if the middleware already has a publisher for ``topic`` (subclasses know)."""
        return False

    def _wanted(self, topic: str) -> bool:
        """True if some active subscription's pattern matches ``topic``."""
        return any(sub.active for sub in self._index.match(topic))

    # -- the Transport interface ----------------------------------------------------------------
    def connect(self) -> None:
        """Join the middleware; :class:`CommError` when that is impossible."""
        if self._state == "open":
            return
        if self._state == "closed":
            raise CommError(f"{self.url}: a closed transport cannot reconnect; make a new one")
        self._open_wire()
        self._state = "open"
        if self.uses_inbox:
            self._dispatcher = threading.Thread(
                target=self._dispatch_loop, name=f"rasm-ros2-{self.url}", daemon=True
            )
            self._dispatcher.start()
        try:
            for topic in list(self._topics.values()):
                if self._wanted(topic.name):
                    self._wire_subscribe(topic)
                    self._wired.add(topic.name)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Leave the middleware and stop the dispatcher; idempotent."""
        if self._state == "closed":
            return
        was_open = self._state == "open"
        self._state = "closed"
        self._cancel_all()
        self._wired.clear()
        if was_open:
            self._close_wire()
        self._inbox.close()
        dispatcher = self._dispatcher
        if dispatcher is not None and dispatcher is not threading.current_thread():
            dispatcher.join(timeout=5.0)

    def publish(self, topic: str, payload: Mapping[str, Any], *, qos: int | None = None) -> None:
        """Encode ``payload`` as the topic's message type and send it (unset fields are zero).

        A payload that does not fit the type raises :class:`MessageError` naming the field.
        """
        if self._state != "open":
            self._require_open(f"publish on {topic!r}")
        declared = self._declared(topic, "publish on")
        try:
            data = declared.codec.encode(payload)
        except MessageError as exc:
            raise MessageError(f"publishing on {topic}: {exc}") from None
        size = self._wire_size(data)
        if size > self.max_payload:  # its receivers would refuse it: not sent
            raise MessageError(
                f"publishing on {topic}: the {declared.typename} is {size} bytes, over the "
                f"{self.max_payload}-byte limit (max_payload)"
            )
        self._wire_send(declared, data)
        self.stats.incr("published")

    def _pattern_added(self, pattern: str, qos: int) -> None:
        if self._state != "open":
            return  # connect() subscribes to what is wanted by then
        for topic in list(self._topics.values()):
            if topic.name not in self._wired and topic_matches(pattern, topic.name):
                self._wire_subscribe(topic)
                self._wired.add(topic.name)

    def _pattern_removed(self, pattern: str) -> None:
        for name in list(self._wired):
            if topic_matches(pattern, name) and not self._wanted(name):
                self._wired.discard(name)
                self._wire_unsubscribe(self._topics[name])

    # -- what subclasses call -------------------------------------------------------------------
    #: Whether received messages wait in this module's inbox for the transport's dispatcher
    #: (the subclass calls :meth:`_received`); False: the subclass's own threads take them
    #: from where the middleware keeps them and call :meth:`_dispatch`.
    uses_inbox = True

    def _received(
        self, topic: RosTopic, data: bytes, uid: str | None, timestamp: float | None
    ) -> None:
        """Hand one received message to the dispatcher (any thread; never blocks)."""
        depth = None if topic.qos.keeps_all else topic.qos.depth
        if not self._inbox.put(topic.name, (topic, data, uid, timestamp), depth):
            self.stats.incr("dropped")

    def _reject(self, topic: str, reason: str, detail: str) -> None:
        """Count one message that is not delivered; log the first per topic and reason."""
        self.stats.incr("malformed")
        with self._reject_lock:
            self._rejected[reason] += 1
            first = (topic, reason) not in self._reported
            if first and len(self._reported) < 10_000:  # a bounded memory of what was said
                self._reported.add((topic, reason))
        if first:
            _log.warning(
                "%s: ignored a message on %s (%s): %s; further ones on %s are only counted "
                "(transport.rejected[%r])", self.url, topic, reason.replace("_", " "), detail,
                topic, reason,
            )

    # -- hooks ----------------------------------------------------------------------------------
    def _open_wire(self) -> None:
        raise NotImplementedError

    def _close_wire(self) -> None:
        raise NotImplementedError

    def _wire_subscribe(self, topic: RosTopic) -> None:
        raise NotImplementedError

    def _wire_unsubscribe(self, topic: RosTopic) -> None:
        raise NotImplementedError

    def _wire_publisher(self, topic: RosTopic) -> Any:
        raise NotImplementedError

    def _wire_send(self, topic: RosTopic, data: bytes) -> None:
        """Send ``data``; a subclass that sets ``tells_own_messages`` calls
        ``self._own_sent(uid, topic.name)`` just before, with the uid it arrives under."""
        raise NotImplementedError

    def _wire_matched(self, topic: RosTopic, publisher: Any) -> bool:
        raise NotImplementedError

    def _wire_size(self, data: bytes) -> int:
        """The size of ``data`` on the wire, as receivers measure it against ``max_payload``."""
        return len(data)

    # -- the dispatcher -------------------------------------------------------------------------
    def _dispatch_loop(self) -> None:
        # what arrived while the last ones were delivered is taken at once: at high rates one
        # wake-up and one lock for many messages, not one each
        while items := self._inbox.get_all():
            for item in items:
                self._dispatch(*item)

    def _dispatch(
        self, topic: RosTopic, data: bytes, uid: str | None, timestamp: float | None
    ) -> None:
        """Decode one received message and run its callbacks (on whichever thread of rasm's
        took it from the wire: one at a time)."""
        try:
            payload = topic.decode(data)
        except MalformedMessage as exc:
            self._reject(topic.name, "malformed", str(exc))
            return
        with self._delivery_lock:
            try:
                self._deliver_received(Message(topic.name, payload, uid, timestamp))
            except Exception:  # _deliver catches callback errors; a last line of defence
                _log.exception("error dispatching a message on %s", topic.name)
