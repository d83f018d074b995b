"""Communication Manager: the transport, connected and closed with the block's modes."""

from __future__ import annotations

from typing import Any

from rasm.comm import Endpoints, Publisher, Subscriber, Subscription, Transport
from rasm.comm.transport import Callback
from rasm.platform.block import Block

__all__ = ["CommunicationManager"]


class CommunicationManager(Block):
    """Communication Manager (cm): publishers and subscribers on one transport.

    The operations (``create_publisher``, ``create_subscriber``, ``publish_message``,
    ``get_queue_message``) are :class:`rasm.comm.Endpoints`'s; this block adds the
    operation modes: the transport is connected in ``initialization`` and closed on
    termination, and nothing is published unless the block is ``initialized``.
    """

    chart_name = "communication_manager"
    short_name = "cm"

    def __init__(self, transport: Transport, **kw: Any) -> None:
        self.transport = transport
        self.endpoints = Endpoints(transport)
        super().__init__(**kw)

    def on_initialization(self) -> None:
        self.transport.connect()

    def on_termination(self) -> None:
        self.endpoints.close()
        self.transport.close()

    def create_publisher(self, topic: str, *, qos: int | None = None) -> Publisher:
        return self.endpoints.create_publisher(topic, qos=qos)

    def create_subscriber(
        self, topic: str, *, maxsize: int = 1000, qos: int | None = None
    ) -> Subscriber:
        return self.endpoints.create_subscriber(topic, maxsize=maxsize, qos=qos)

    def publish_message(self, topic: str, payload: dict[str, Any]) -> None:
        self.require_mode("initialized")
        self.endpoints.publish_message(topic, payload)

    def subscribe(self, pattern: str, callback: Callback) -> Subscription:
        """Call ``callback(message)`` for every message on ``pattern`` (transport thread)."""
        return self.endpoints.subscribe(pattern, callback)
