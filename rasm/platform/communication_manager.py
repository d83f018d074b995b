"""Communication Manager: the transport, connected and closed with the block's modes."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rasm.platform.block import Block

__all__ = ["CommunicationManager"]


class CommunicationManager(Block):
    """Communication Manager (cm): publishers and subscribers on one transport (seed §5.5.1).

    The seed's operations (``create_publisher``, ``create_subscriber``, ``publish_message``,
    ``get_queue_message``) come from :class:`rasm.comm.CommunicationManager`; this block adds the
    operation modes: the transport is connected in ``initialization`` and closed on termination,
    and nothing is published unless the block is ``initialized``.
    """

    __slots__ = ("transport", "endpoints")  # slots, as Block's (read for every reading)

    chart_name = "communication_manager"
    short_name = "cm"

    def __init__(self, transport: Any, **kw: Any) -> None:
        from rasm.comm import CommunicationManager as Endpoints

        self.transport = transport
        self.endpoints = Endpoints(transport)
        super().__init__(**kw)

    def on_initialization(self) -> None:
        self.transport.connect()

    def on_termination(self) -> None:
        self.transport.close()

    def create_publisher(self, topic: str, **kw: Any) -> Any:
        return self.endpoints.create_publisher(topic, **kw)

    def create_subscriber(self, topic: str, **kw: Any) -> Any:
        return self.endpoints.create_subscriber(topic, **kw)

    def publish_message(self, topic: str, payload: dict[str, Any]) -> None:
        if self._mode != "initialized":  # tested inline: every probe reading passes here
            self.require_mode("initialized")
        self.transport.publish(topic, payload)

    def subscribe(self, pattern: str, callback: Callable[[Any], Any]) -> Any:
        """Call ``callback(message)`` for every message on ``pattern`` (transport thread)."""
        return self.transport.subscribe(pattern, callback)
