"""Counting a transport's own messages on their way back to it.

A transport subscribed to a topic it also publishes on gets its own messages back from the
network. A run on the simulated clock must not move its clock while one of them is still on
the way (a reading would be judged as never sent), so it counts them: one more on a topic when
one leaves, one less when it has been delivered, and it waits for nought.
"""

from __future__ import annotations

import threading

__all__ = ["OwnDeliveries"]


class OwnDeliveries:
    """Per topic, how many own messages have left and not yet been delivered back."""

    def __init__(self) -> None:
        self._changed = threading.Condition(threading.Lock())
        self._waiting: dict[str, int] = {}

    def sent(self, topic: str) -> None:
        with self._changed:
            self._waiting[topic] = self._waiting.get(topic, 0) + 1

    def delivered(self, topic: str) -> None:
        """One came back. One sent before counting began is not counted (nothing waits)."""
        with self._changed:
            left = self._waiting.get(topic, 0) - 1
            if left < 0:
                return
            if left:
                self._waiting[topic] = left
            else:
                del self._waiting[topic]
                if not self._waiting:
                    self._changed.notify_all()

    @property
    def in_flight(self) -> int:
        """How many have left and are not delivered yet."""
        with self._changed:
            return sum(self._waiting.values())

    def wait(self, timeout: float) -> dict[str, int]:
        """Wait until none is on the way (at most ``timeout`` s); what is still missing then,
        by topic (empty: all delivered)."""
        with self._changed:
            self._changed.wait_for(lambda: not self._waiting, timeout)
            return dict(self._waiting)
