"""The Communication Manager's operations on top of any :class:`Transport`.

``create_publisher`` / ``publish_message`` and ``create_subscriber`` / ``get_queue_message``:
a building block publishes on fixed topics and reads what it subscribed to from a bounded queue,
at its own pace, on its own thread. ``publish_message(topic, payload)`` publishes on any topic
and ``subscribe(pattern, callback)`` hands each message to a callback on the transport's thread,
for the blocks that route many topics (Telegraf, the effectors). This is the one implementation:
the platform's Communication Manager block adds only its operation modes to it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rasm.comm.message import Message
from rasm.comm.queues import DropOldestQueue
from rasm.comm.topics import validate_topic
from rasm.comm.transport import Subscription, Transport

__all__ = ["Endpoints", "Publisher", "Subscriber"]


class Publisher:
    """Publishes on one topic (made by :meth:`Endpoints.create_publisher`)."""

    def __init__(self, transport: Transport, topic: str, qos: int | None = None) -> None:
        self.topic = validate_topic(topic)
        self.qos = qos
        self._transport = transport

    def publish_message(self, payload: dict[str, Any]) -> None:
        """Send ``payload`` (a JSON-able dict) on this publisher's topic."""
        self._transport.publish(self.topic, payload, qos=self.qos)

    def __repr__(self) -> str:
        return f"<Publisher {self.topic!r}>"


class Subscriber:
    """A bounded queue of the messages matching one pattern.

    When the queue is full the oldest message is dropped (fresh data matters more in a control
    loop) and counted in :attr:`dropped` and in the transport's ``stats.dropped``.
    """

    def __init__(
        self, transport: Transport, pattern: str, *, maxsize: int = 1000, qos: int | None = None
    ) -> None:
        self.pattern = pattern
        self._transport = transport
        self._queue: DropOldestQueue[Message] = DropOldestQueue(maxsize)
        self._subscription: Subscription = transport.subscribe(pattern, self._put, qos=qos)

    def _put(self, message: Message) -> None:
        if not self._queue.put(message):
            self._transport.stats.incr("dropped")

    def get_queue_message(self, timeout: float | None = None) -> Message | None:
        """The oldest queued message, waiting for one if needed (without polling).

        Returns ``None`` if ``timeout`` seconds pass first, or once the subscriber is closed and
        its queue is empty. ``timeout=None`` waits as long as it takes.
        """
        return self._queue.get(timeout)

    @property
    def dropped(self) -> int:
        """Messages dropped because the queue was full."""
        return self._queue.dropped

    @property
    def maxsize(self) -> int:
        return self._queue.maxsize

    def __len__(self) -> int:
        return len(self._queue)

    def close(self) -> None:
        """Unsubscribe and wake any waiting :meth:`get_queue_message`; idempotent."""
        self._subscription.cancel()
        self._queue.close()

    def __repr__(self) -> str:
        return f"<Subscriber {self.pattern!r} queued={len(self)} dropped={self.dropped}>"


class Endpoints:
    """The Communication Manager's operations: publishers and queued subscribers over one
    transport (the Communication Manager block, :mod:`rasm.platform.communication_manager`,
    adds its operation modes).

    It does not own the transport's life cycle: connect it before and close it after (closing
    them closes their subscribers only).
    """

    def __init__(self, transport: Transport) -> None:
        self.transport = transport
        self._subscribers: list[Subscriber] = []
        self._subscriptions: list[Subscription] = []

    def publish_message(
        self, topic: str, payload: dict[str, Any], *, qos: int | None = None
    ) -> None:
        """Send ``payload`` (a JSON-able dict) on ``topic`` (a topic name without wildcards)."""
        self.transport.publish(topic, payload, qos=qos)

    def subscribe(
        self, pattern: str, callback: Callable[[Message], Any], *, qos: int | None = None
    ) -> Subscription:
        """Call ``callback(message)`` for every message matching ``pattern``, on the transport's
        thread; cancel the returned subscription to stop (:meth:`close` cancels it too)."""
        subscription = self.transport.subscribe(pattern, callback, qos=qos)
        self._subscriptions.append(subscription)
        return subscription

    def create_publisher(self, topic: str, *, qos: int | None = None) -> Publisher:
        """A :class:`Publisher` for ``topic`` (a topic name without wildcards)."""
        return Publisher(self.transport, topic, qos)

    def create_subscriber(
        self, topic: str, *, maxsize: int = 1000, qos: int | None = None
    ) -> Subscriber:
        """A :class:`Subscriber` queueing at most ``maxsize`` messages matching ``topic``."""
        subscriber = Subscriber(self.transport, topic, maxsize=maxsize, qos=qos)
        self._subscribers.append(subscriber)
        return subscriber

    def close(self) -> None:
        """Close every subscriber and cancel every subscription made here."""
        for subscriber in self._subscribers:
            subscriber.close()
        self._subscribers.clear()
        for subscription in self._subscriptions:
            subscription.cancel()
        self._subscriptions.clear()
