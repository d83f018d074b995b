"""The MQTT transport (paho-mqtt 2.x), for ``--transport mqtt://host:port``.

Threads: paho's network thread only moves bytes (it hands each received message to a bounded
inbox and returns); one dispatcher thread per transport decodes messages and runs callbacks. So a
callback that publishes does so from the dispatcher, never from inside paho's network callback,
and a slow callback delays other callbacks but never the socket (publishing from inside paho's
callbacks makes a hop slower as the message rate grows). Sockets get TCP_NODELAY so
small messages are not held back by Nagle's algorithm.
"""

from __future__ import annotations

import itertools
import logging
import secrets
import socket
import ssl
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion, MQTTErrorCode

from rasm.comm.envelope import MAX_PAYLOAD, MalformedPayload, check_payload, decode, encode
from rasm.comm.message import Message
from rasm.comm.queues import DropOldestQueue
from rasm.comm.topics import TopicIndex, validate_pattern, validate_topic
from rasm.comm.transport import Transport, check_qos
from rasm.comm.url import parse_mqtt_url
from rasm.errors import CommError
from rasm.times import format_seconds

__all__ = ["MqttTransport", "Will"]

_log = logging.getLogger("rasm.comm.mqtt")


@dataclass(frozen=True)
class Will:
    """The last will: published by the broker if this client vanishes without closing.

    The payload travels in the usual envelope (``uid`` and ``timestamp`` from connection time).
    Typical use is presence: ``Will("presence/planner", {"online": False}, retain=True)``.
    """

    topic: str
    payload: dict[str, Any] = field(default_factory=dict)
    qos: int = 1
    retain: bool = False

    def __post_init__(self) -> None:
        validate_topic(self.topic)
        check_qos(self.qos)
        check_payload(self.payload)


# CONNACK refusals that a retry cannot cure (MQTT 3.1.1 return codes 4 and 5, as paho names them)
_AUTH_REFUSALS = frozenset({"Not authorized", "Bad user name or password"})


class MqttTransport(Transport):
    """Publish/subscribe over an MQTT broker with JSON envelopes, per-topic QoS and reconnects.

    ``url`` is ``mqtt://host:port`` (``mqtts://`` turns TLS on). ``client_id`` defaults to a
    random ``rasm-...`` id (clean session). ``tls`` is ``True`` (system trust store) or an
    :class:`ssl.SSLContext`. ``qos_by_topic`` maps patterns to QoS: a publish without ``qos=``
    uses the first pattern matching its topic (exact names before wildcards), else 0. ``will``
    is a :class:`Will`.

    After a lost connection paho reconnects by itself (delays growing from
    ``reconnect_delay[0]`` to ``reconnect_delay[1]`` seconds) and every subscription is renewed.
    While disconnected, QoS 0 publishes are dropped and counted in ``stats.dropped``; QoS 1 and 2
    publishes wait in paho's queue (at most ``max_pending``) and go out after reconnecting.
    ``on_connection_change(connected)`` is told, on paho's network thread, when the transport
    becomes ready (connected and subscriptions confirmed) and when it loses the connection.
    Its own messages carry their uids, so it knows them when the broker brings them back.
    """

    tells_own_messages = True

    def __init__(
        self,
        url: str,
        *,
        client_id: str | None = None,
        username: str | None = None,
        password: str | None = None,
        tls: bool | ssl.SSLContext | None = None,
        qos_by_topic: Mapping[str, int] | None = None,
        will: Will | None = None,
        keepalive: int = 10,
        connect_timeout: float = 5.0,
        reconnect_delay: tuple[float, float] = (0.1, 2.0),
        max_payload: int = MAX_PAYLOAD,
        max_pending: int = 10_000,
        on_connection_change: Callable[[bool], None] | None = None,
    ) -> None:
        super().__init__()
        self.host, self.port, url_tls = parse_mqtt_url(url)
        self.url = url
        self.client_id = client_id or f"rasm-{secrets.token_hex(6)}"
        self.tls = tls if tls is not None else url_tls
        self.will = will
        self.keepalive = keepalive
        self.connect_timeout = connect_timeout
        self.max_payload = max_payload
        self.on_connection_change = on_connection_change
        self._username, self._password = username, password
        self._reconnect_delay = reconnect_delay
        self._max_pending = max_pending
        self._qos_table: dict[str, int] = {}
        self._qos_index: TopicIndex[tuple[str, int]] = TopicIndex()
        for pattern, qos in (qos_by_topic or {}).items():
            validate_pattern(pattern)
            entry = (pattern, check_qos(qos))
            self._qos_table[pattern] = entry[1]
            self._qos_index.add(pattern, entry)
        # uid = random per-transport prefix + counter: unique across processes, cheap per message
        self._uid_prefix = f"{secrets.token_hex(6)}."
        self._uids = itertools.count(1)
        self._client: mqtt.Client | None = None
        self._inbox: DropOldestQueue[tuple[str, bytes]] = DropOldestQueue(max_pending)
        self._dispatcher = threading.Thread(
            target=self._dispatch_loop, name=f"rasm-comm-{self.client_id}", daemon=True
        )
        self._ready = threading.Event()
        # set with _ready, or when the broker refuses this client's credentials: connect() then
        # fails at once (retrying cannot help) instead of waiting out connect_timeout
        self._settled = threading.Event()
        self._auth_refused: str | None = None
        self._acks_lock = threading.Lock()
        self._acks: dict[int, threading.Event] = {}
        self._resub_mid: int | None = None
        self._last_publish: mqtt.MQTTMessageInfo | None = None
        self._disconnected = threading.Event()
        self._connections = 0
        self._last_failure = "no answer"

    # -- the Transport interface ----------------------------------------------------------------
    def connect(self) -> None:
        """Connect and wait until ready (at most ``connect_timeout`` s), else :class:`CommError`."""
        if self._state == "open":
            return
        if self._state != "new":
            raise CommError(f"{self.url}: a closed MqttTransport cannot reconnect; make a new one")
        client = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=self.client_id,
            clean_session=True,
            protocol=mqtt.MQTTv311,
        )
        if self._username is not None:
            client.username_pw_set(self._username, self._password)
        if self.tls:
            context = self.tls if isinstance(self.tls, ssl.SSLContext) else None
            client.tls_set_context(context or ssl.create_default_context())
        if self.will is not None:
            data = encode(
                self.will.payload, uid=self._next_uid(), timestamp=time.time(),
                max_bytes=self.max_payload,
            )
            client.will_set(self.will.topic, data, qos=self.will.qos, retain=self.will.retain)
        client.reconnect_delay_set(*self._reconnect_delay)  # type: ignore[arg-type]
        client.max_queued_messages_set(self._max_pending)
        client.on_socket_open = self._on_socket_open
        client.on_connect = self._on_connect
        client.on_connect_fail = self._on_connect_fail
        client.on_disconnect = self._on_disconnect
        client.on_subscribe = self._on_subscribe
        client.on_message = self._on_message
        self._client = client
        self._state = "connecting"
        self._dispatcher.start()
        try:
            client.connect_async(self.host, self.port, self.keepalive)
            client.loop_start()
        except (OSError, ValueError) as exc:
            self._shutdown()
            raise CommError(f"cannot connect to {self.url}: {exc}") from exc
        self._settled.wait(self.connect_timeout)
        if self._auth_refused is not None:
            self._shutdown()
            who = f"user {self._username!r}" if self._username is not None else "no user name"
            raise CommError(
                f"the MQTT broker at {self.url} refused the connection: {self._auth_refused} "
                f"({who}; `rasm run` and `rasm monitor` take the credentials from "
                "RASM_MQTT_USERNAME and RASM_MQTT_PASSWORD)"
            )
        if not self._ready.is_set():
            self._shutdown()
            raise CommError(
                f"could not connect to the MQTT broker at {self.url} within "
                f"{format_seconds(self.connect_timeout)} s ({self._last_failure}); is a broker "
                "running there? "
                f"(try: mosquitto -p {self.port})"
            )
        self._state = "open"

    def close(self) -> None:
        """Flush, disconnect cleanly (so the broker does not send the will), stop both threads.

        Messages already published are written out first (QoS 1/2: acknowledged), waiting at
        most ``connect_timeout`` seconds in all.
        """
        if self._state == "closed":
            return
        self._shutdown()

    def publish(self, topic: str, payload: dict[str, Any], *, qos: int | None = None) -> None:
        """Send ``payload`` in the envelope; returns once paho has it (does not wait for acks)."""
        if self._state != "open":
            self._require_open(f"publish on {topic!r}")
        validate_topic(topic)
        q = check_qos(self._qos_for(topic, qos))
        uid = self._next_uid()
        data = encode(payload, uid=uid, timestamp=time.time(), max_bytes=self.max_payload)
        assert self._client is not None
        self._own_sent(uid, topic)  # before it leaves: it may be back before publish() returns
        info = self._client.publish(topic, data, qos=q)
        rc = info.rc
        self._last_publish = info  # close() waits for it: packets leave in order
        if rc == MQTTErrorCode.MQTT_ERR_SUCCESS or (rc == MQTTErrorCode.MQTT_ERR_NO_CONN and q):
            self.stats.incr("published")  # QoS>0 without connection: queued by paho, sent later
        else:
            self.stats.incr("dropped")
            _log.debug("dropped a message on %r: %s", topic, mqtt.error_string(rc))

    # -- connection state -----------------------------------------------------------------------
    @property
    def connected(self) -> bool:
        """True while connected with every subscription confirmed by the broker."""
        return self._ready.is_set()

    def wait_connected(self, timeout: float | None = None) -> bool:
        """Block until :attr:`connected` (or ``timeout`` s); returns :attr:`connected`."""
        return self._ready.wait(timeout)

    # -- internals ------------------------------------------------------------------------------
    def _next_uid(self) -> str:
        return self._uid_prefix + str(next(self._uids))

    def _sent_here(self, uid: str | None) -> bool:
        return uid is not None and uid.startswith(self._uid_prefix)

    def _qos_for(self, topic: str, qos: int | None) -> int:
        if qos is not None:
            return qos
        if topic in self._qos_table:
            return self._qos_table[topic]
        found = self._qos_index.match(topic)
        return found[0][1] if found else 0

    def _on_network_thread(self) -> bool:
        # paho keeps its loop thread in a private attribute; there is no public accessor.
        client = self._client
        return client is not None and threading.current_thread() is client._thread

    def _pattern_added(self, pattern: str, qos: int) -> None:
        client = self._client
        # Not "ready" is not enough to skip: between CONNACK and the SUBACK of the renewal the
        # renewal list may already have been taken without this pattern. Only while there is no
        # connection at all is it safe to leave it to the next _on_connect.
        if client is None or not client.is_connected():
            return
        with self._acks_lock:
            rc, mid = client.subscribe(pattern, qos)
            if rc != MQTTErrorCode.MQTT_ERR_SUCCESS or mid is None:
                return  # the connection just dropped: renewed with the others on reconnect
            done = self._acks[mid] = threading.Event()
        # Wait for the SUBACK so that whatever is published after subscribe() returns arrives.
        # Never on the network thread: it is the one that would process the SUBACK.
        if not self._on_network_thread() and not done.wait(self.connect_timeout):
            if self._ready.is_set():
                raise CommError(
                    f"{self.url}: the broker did not confirm the subscription to {pattern!r} "
                    f"within {format_seconds(self.connect_timeout)} s"
                )

    def _pattern_removed(self, pattern: str) -> None:
        if self._client is not None and self._client.is_connected():
            self._client.unsubscribe(pattern)

    def _shutdown(self) -> None:
        self._state = "closed"
        self._cancel_all()
        client = self._client
        if client is not None:
            # paho's loop_stop() does not flush: without these waits the last messages and the
            # DISCONNECT itself could be lost, and the broker would then publish the will.
            waits = client.is_connected() and not self._on_network_thread()
            deadline = time.monotonic() + self.connect_timeout
            if waits and self._last_publish is not None:
                try:
                    self._last_publish.wait_for_publish(self.connect_timeout)
                except (ValueError, RuntimeError):
                    pass  # it was never queued (counted as dropped when published)
            client.disconnect()
            if waits:
                self._disconnected.wait(max(0.0, deadline - time.monotonic()))
            client.loop_stop()
        self._ready.clear()
        self._release_acks()
        self._inbox.close()
        if self._dispatcher.is_alive() and threading.current_thread() is not self._dispatcher:
            self._dispatcher.join(timeout=5.0)

    def _release_acks(self) -> None:
        with self._acks_lock:
            waiting, self._acks = self._acks, {}
            self._resub_mid = None
        for event in waiting.values():
            event.set()

    def _became_ready(self) -> None:
        self._ready.set()
        self._settled.set()
        self._notify(True)

    def _notify(self, connected: bool) -> None:
        if self.on_connection_change is not None:
            try:
                self.on_connection_change(connected)
            except Exception:
                _log.exception("on_connection_change(%s) raised", connected)

    # paho callbacks: they run on paho's network thread and must never raise (an exception there
    # would end the network loop), so each catches everything and logs it.
    def _on_socket_open(self, client: mqtt.Client, userdata: Any, sock: Any) -> None:
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except (OSError, AttributeError):
            pass  # not a TCP socket (e.g. a websocket wrapper): Nagle stays on

    def _on_connect(self, client: mqtt.Client, userdata: Any, flags: Any, reason: Any,
                    properties: Any) -> None:
        try:
            if reason.is_failure:
                self._last_failure = f"broker refused: {reason}"
                if self._state == "connecting" and str(reason) in _AUTH_REFUSALS:
                    self._auth_refused = str(reason)
                    self._settled.set()
                    return
                _log.warning("%s refused the connection: %s", self.url, reason)
                return
            self._connections += 1
            self._disconnected.clear()
            if self._connections > 1:
                self.stats.incr("reconnects")
                _log.info("reconnected to %s", self.url)
            wanted: dict[str, int] = {}
            for sub in self._index.items():
                wanted[sub.pattern] = max(wanted.get(sub.pattern, 0), sub.qos)
            if not wanted:
                self._became_ready()
                return
            with self._acks_lock:
                rc, mid = client.subscribe(list(wanted.items()))
                self._resub_mid = mid if rc == MQTTErrorCode.MQTT_ERR_SUCCESS else None
        except Exception:
            _log.exception("error in the MQTT connect handler")

    def _on_connect_fail(self, client: mqtt.Client, userdata: Any) -> None:
        self._last_failure = "connection refused or unreachable"

    def _on_disconnect(self, client: mqtt.Client, userdata: Any, flags: Any, reason: Any,
                       properties: Any) -> None:
        try:
            was_ready = self._ready.is_set()
            self._ready.clear()
            self._disconnected.set()
            self._release_acks()
            if self._state == "open":
                _log.warning("lost the connection to %s (%s); reconnecting", self.url, reason)
            if was_ready:
                self._notify(False)
        except Exception:
            _log.exception("error in the MQTT disconnect handler")

    def _on_subscribe(self, client: mqtt.Client, userdata: Any, mid: int, reasons: Any,
                      properties: Any) -> None:
        try:
            for code in reasons:
                if getattr(code, "is_failure", False):
                    _log.error("%s refused a subscription: %s", self.url, code)
            with self._acks_lock:
                done = self._acks.pop(mid, None)
                resubscribed = mid == self._resub_mid
                if resubscribed:
                    self._resub_mid = None
            if done is not None:
                done.set()
            if resubscribed:
                self._became_ready()
        except Exception:
            _log.exception("error in the MQTT subscribe handler")

    def _on_message(self, client: mqtt.Client, userdata: Any, msg: mqtt.MQTTMessage) -> None:
        # Only hand over: decoding and callbacks happen on the dispatcher thread.
        try:
            topic = msg.topic
        except UnicodeDecodeError:
            self._count_malformed("?", "topic is not UTF-8")
            return
        if not self._inbox.put((topic, msg.payload)):
            self.stats.incr("dropped")

    def _dispatch_loop(self) -> None:
        while True:
            item = self._inbox.get()
            if item is None:
                return
            topic, data = item
            try:
                payload, uid, timestamp = decode(data, max_bytes=self.max_payload)
            except MalformedPayload as exc:
                self._count_malformed(topic, str(exc))
                continue
            if uid is not None and not isinstance(uid, str):
                uid = str(uid)
            if isinstance(timestamp, int | float) and not isinstance(timestamp, bool):
                timestamp = float(timestamp)
            else:
                timestamp = None
            try:
                self._deliver_received(Message(topic, payload, uid, timestamp))
            except Exception:  # _deliver catches callback errors; this is a last line of defence
                _log.exception("error dispatching a message on %r", topic)

    def _count_malformed(self, topic: str, reason: str) -> None:
        self.stats.incr("malformed")
        n = self.stats.malformed
        # The first few are logged in full; after that a reminder now and then, not a flood.
        if n <= 10 or n % 1000 == 0:
            _log.warning("malformed message #%d on %r ignored: %s", n, topic, reason)
