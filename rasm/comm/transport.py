"""The :class:`Transport` interface every message bus implements, and its subscription handle."""

from __future__ import annotations

import logging
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable
from typing import Any

from rasm.comm.message import Message, TransportStats
from rasm.comm.own_deliveries import OwnDeliveries
from rasm.comm.topics import TopicIndex, validate_pattern
from rasm.errors import CommError
from rasm.times import format_seconds

__all__ = ["Transport", "Subscription", "Callback"]

_log = logging.getLogger("rasm.comm")

Callback = Callable[[Message], None]


class Subscription:
    """A live subscription; :meth:`cancel` ends it (idempotent)."""

    def __init__(self, transport: Transport, pattern: str, callback: Callback, qos: int) -> None:
        self.pattern = pattern
        self.callback = callback
        self.qos = qos
        self._transport = transport
        self._active = True

    @property
    def active(self) -> bool:
        """False once cancelled or once its transport is closed."""
        return self._active

    def cancel(self) -> None:
        """Stop receiving. A callback already running on another thread may still finish."""
        if self._active:
            self._active = False
            self._transport._remove(self)

    def __repr__(self) -> str:
        state = "active" if self._active else "cancelled"
        return f"<Subscription {self.pattern!r} qos={self.qos} {state}>"


def check_qos(qos: int) -> int:
    if qos not in (0, 1, 2):
        raise CommError(f"QoS must be 0, 1 or 2, got {qos!r}")
    return qos


class Transport(ABC):
    """A publish/subscribe message bus with MQTT topic semantics.

    Life cycle: :meth:`connect`, then any number of :meth:`publish` and :meth:`subscribe` calls
    (subscribing before connecting is allowed), then :meth:`close`. Also a context manager.

    Payloads are JSON-able dicts (see :mod:`rasm.comm.envelope`); subscribers receive a
    :class:`Message`. Patterns may use ``+`` and ``#`` on every transport. Callbacks run on the
    transport's delivery thread (the publisher's thread for :class:`LocalTransport`, one
    dispatcher thread per :class:`MqttTransport`): keep them short and hand long work to a
    queue (:class:`~rasm.comm.endpoints.Subscriber` does exactly that). A callback that raises is
    logged and counted in ``stats.errors``; the transport carries on.

    ``qos=None`` (the default) means the QoS configured for the topic, else 0.
    """

    #: The URL this transport was opened with (``local`` or ``mqtt://host:port``).
    url: str

    #: Whether the transport knows its own messages when they come back over the network, so
    #: that :meth:`count_own_deliveries` and :meth:`wait_own_deliveries` work.
    tells_own_messages: bool = False

    def __init__(self) -> None:
        self.stats = TransportStats()
        self._index: TopicIndex[Subscription] = TopicIndex()
        self._sub_lock = threading.Lock()
        self._state = "new"  # new -> open -> closed
        self._own: OwnDeliveries | None = None  # counting own messages (count_own_deliveries)

    # -- the interface --------------------------------------------------------------------------
    @abstractmethod
    def connect(self) -> None:
        """Open the transport; raises :class:`CommError` if that is impossible."""

    @abstractmethod
    def close(self) -> None:
        """Release everything; idempotent. Subscriptions end; publishing afterwards raises."""

    @abstractmethod
    def publish(self, topic: str, payload: dict[str, Any], *, qos: int | None = None) -> None:
        """Send ``payload`` on ``topic`` (a topic name, no wildcards)."""

    def subscribe(
        self, pattern: str, callback: Callback, *, qos: int | None = None
    ) -> Subscription:
        """Call ``callback(message)`` for every message whose topic matches ``pattern``."""
        validate_pattern(pattern)
        if not callable(callback):
            raise CommError(f"callback for {pattern!r} is not callable: {callback!r}")
        if self._state == "closed":
            raise CommError(f"cannot subscribe to {pattern!r}: the transport {self.url} is closed")
        sub = Subscription(self, pattern, callback, check_qos(self._qos_for(pattern, qos)))
        with self._sub_lock:
            before = self._index.get(pattern)
            self._index.add(pattern, sub)
        # The broker holds one subscription per pattern, at the highest QoS asked for.
        if not before or sub.qos > max(s.qos for s in before):
            try:
                self._pattern_added(pattern, sub.qos)
            except BaseException:
                sub.cancel()
                raise
        return sub

    # -- own messages coming back -----------------------------------------------------------------
    def count_own_deliveries(self, exclusive: Iterable[str] = ()) -> None:
        """From now on count every message this transport publishes on a topic it is itself
        subscribed to, until the network has brought it back and its callbacks have returned;
        and every message another process publishes on an ``exclusive`` topic (one this
        process must have to itself).

        A run on the simulated clock waits for them (:meth:`wait_own_deliveries`) before its
        clock moves on. :class:`CommError` if this transport cannot tell its own messages.
        """
        if not self.tells_own_messages:
            raise CommError(
                f"{self.url}: this transport cannot tell its own messages when they come back, "
                "so nothing can wait for their delivery"
            )
        if self._own is None:
            self._own = OwnDeliveries(exclusive)

    def wait_own_deliveries(self, timeout: float) -> None:
        """Return once every own message counted has been delivered here (callbacks returned).

        A message that has not come back after ``timeout`` seconds (lost by the network, or
        dropped by a full queue) raises :class:`CommError` naming its topic: the caller would
        otherwise carry on as if it had never been sent. So does a message another process
        published on an exclusive topic: nothing could say when it would come.
        """
        own = self._own
        if own is None:
            return
        missing = own.wait(timeout)
        strangers = own.strangers()
        if strangers:
            raise CommError(
                f"{self.url}: another process published on topics this process needs to "
                f"itself ({_per_topic(strangers)}); a run on the simulated clock can wait only "
                "for its own messages, so its managed system's topics must be its own (a broker "
                "of its own)"
            )
        if missing:
            raise CommError(
                f"{self.url}: messages this process published did not come back within "
                f"{format_seconds(timeout)} s ({_per_topic(missing)}); a run on the simulated "
                "clock moves its clock only once every one of them is delivered"
            )

    def _own_sent(self, uid: str, topic: str) -> None:
        """Called by :meth:`publish` before message ``uid`` leaves: noted if counting and some
        subscription of this transport matches ``topic``."""
        own = self._own
        if own is not None and any(sub._active for sub in self._index.match(topic)):
            own.sent(uid, topic)

    def _sent_here(self, uid: str | None) -> bool:
        """Whether the message of ``uid`` left this transport (a transport that sets
        ``tells_own_messages`` knows)."""
        return False

    def _deliver_received(self, message: Message) -> None:
        """Deliver a message that came from the network (on the transport's delivery thread)
        and count it; own messages waited for go in the order they were sent."""
        own = self._own
        ready = own.take(message, own=self._sent_here(message.uid)) if own is not None else None
        if ready is None:
            ok, failed = self._deliver(message)
            self.stats.add_delivery(ok, failed)
            return
        try:
            for each in ready:
                ok, failed = self._deliver(each)
                self.stats.add_delivery(ok, failed)
        finally:
            own.delivered(ready)

    @property
    def subscriptions(self) -> int:
        """How many subscriptions are active."""
        return len(self._index)

    # -- hooks for concrete transports ----------------------------------------------------------
    def _qos_for(self, topic: str, qos: int | None) -> int:
        return 0 if qos is None else qos

    def _pattern_added(self, pattern: str, qos: int) -> None:
        """Called when a pattern gets its first subscription, or one with a higher QoS."""
        return None

    def _pattern_removed(self, pattern: str) -> None:
        """Called when a pattern loses its last subscription."""
        return None

    def _remove(self, sub: Subscription) -> None:
        with self._sub_lock:
            removed = self._index.remove(sub.pattern, sub)
            last = removed and self._index.count(sub.pattern) == 0
        if last and self._state == "open":
            self._pattern_removed(sub.pattern)

    def _cancel_all(self) -> None:
        with self._sub_lock:
            subs = self._index.items()
            self._index = TopicIndex()
        for sub in subs:
            sub._active = False

    def _deliver(self, message: Message) -> tuple[int, int]:
        """Run every matching callback; ``(calls that returned, calls that raised)``.

        The caller adds them to the stats together with its own counts (one lock per message).
        """
        ok = failed = 0
        for sub in self._index.match(message.topic):
            if not sub._active:
                continue
            try:
                sub.callback(message)
                ok += 1
            except Exception:
                failed += 1
                _log.exception(
                    "callback %r for %r raised on a message on %r (the transport carries on)",
                    sub.callback, sub.pattern, message.topic,
                )
        return ok, failed

    def _require_open(self, what: str) -> None:
        if self._state != "open":
            hint = "call connect() first" if self._state == "new" else "it was closed"
            raise CommError(f"cannot {what}: the transport {self.url} is not open ({hint})")

    def __enter__(self) -> Transport:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.url} {self._state}>"


def _per_topic(counts: dict[str, int]) -> str:
    """``3 on 'a/b', 1 on 'c'``: the first five topics of ``counts``, sorted."""
    return ", ".join(f"{n} on {topic!r}" for topic, n in sorted(counts.items())[:5])
