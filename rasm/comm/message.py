"""What a subscriber receives (:class:`Message`) and what a transport counts (its stats)."""

from __future__ import annotations

import threading
from typing import Any, NamedTuple

__all__ = ["Message", "TransportStats"]


class Message(NamedTuple):
    """One received message.

    ``payload`` is exactly the dict the sender published: the envelope fields are taken out of it
    and given here as ``uid`` (unique per message) and ``timestamp`` (the sender's wall clock,
    seconds since the epoch). Both are ``None`` when a foreign publisher did not send them.
    Treat ``payload`` as read-only: on the local bus every subscriber sees the same dict.
    """

    topic: str
    payload: dict[str, Any]
    uid: str | None = None
    timestamp: float | None = None


class TransportStats:
    """Thread-safe counters of one transport.

    - ``published``: messages the transport accepted for sending.
    - ``delivered``: callback calls that returned normally.
    - ``malformed``: received payloads rejected (not JSON, not an object, binary, non-finite or
      huge numbers, too large); each is logged, none is fatal.
    - ``dropped``: messages lost inside rasm: a full subscriber queue (the oldest goes), a full
      dispatch queue, a QoS 0 publish while the broker is unreachable.
    - ``errors``: callback calls that raised (logged; the transport carries on).
    - ``reconnects``: connections re-established after a loss.
    """

    FIELDS = ("published", "delivered", "malformed", "dropped", "errors", "reconnects")

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.published = 0
        self.delivered = 0
        self.malformed = 0
        self.dropped = 0
        self.errors = 0
        self.reconnects = 0

    def incr(self, field: str, n: int = 1) -> None:
        """Add ``n`` to the counter ``field`` (used by layers built on a transport, too)."""
        with self._lock:
            setattr(self, field, getattr(self, field) + n)

    def add_delivery(self, delivered: int, errors: int, published: int = 0) -> None:
        """Count one message's outcome (its callback calls) under one lock."""
        with self._lock:
            self.published += published
            self.delivered += delivered
            self.errors += errors

    def as_dict(self) -> dict[str, int]:
        """A consistent snapshot of every counter."""
        with self._lock:
            return {name: getattr(self, name) for name in self.FIELDS}

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={v}" for k, v in self.as_dict().items())
        return f"TransportStats({inner})"
