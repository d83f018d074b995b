"""A transport's own messages on their way back to it, delivered in the order they were sent.

A transport subscribed to a topic it also publishes on gets its own messages back from the
network. A run on the simulated clock must not move its clock while one of them is still on the
way (a reading would be judged as never sent), nor take them in another order than the
in-process bus would (the network may bring two topics' messages back crossed). So, while
counting, each message that leaves for a topic of its own subscriptions is noted in order; one
that comes back waits for those sent before it, and a caller can wait until none is left.
Messages from elsewhere on the topics a run must have to itself are counted too: nobody can wait
for them.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Iterable

from rasm.comm.message import Message

__all__ = ["OwnDeliveries"]


class OwnDeliveries:
    """The own messages sent and not yet delivered, in the order they were sent; and the
    messages from elsewhere on the ``exclusive`` topics."""

    def __init__(self, exclusive: Iterable[str] = ()) -> None:
        self.exclusive = frozenset(exclusive)
        self._changed = threading.Condition(threading.Lock())
        self._waiting: dict[str, str] = {}  # uid -> topic: sent, not yet handed out
        self._order: deque[str] = deque()  # the same uids, in the order they were sent
        self._back: dict[str, Message] = {}  # came back before one sent earlier
        self._handed = 0  # handed out for delivery, callbacks not yet returned
        self._strangers: dict[str, int] = {}  # messages from elsewhere, by topic

    def sent(self, uid: str, topic: str) -> None:
        """The message ``uid`` is about to leave for ``topic``."""
        with self._changed:
            self._waiting[uid] = topic
            self._order.append(uid)

    def take(self, message: Message, *, own: bool) -> list[Message] | None:
        """``message`` came back: the own messages to deliver now, in the order they were sent
        (empty while one sent earlier is still away); None if it is not one waited for (sent
        elsewhere, ``own`` False, or sent when no subscription here matched): deliver it as
        usual. Call :meth:`delivered` with what this returns once its callbacks have run."""
        with self._changed:
            if message.uid not in self._waiting or message.uid in self._back:
                if not own and message.topic in self.exclusive:
                    self._strangers[message.topic] = self._strangers.get(message.topic, 0) + 1
                return None
            self._back[message.uid] = message
            ready = []
            while self._order and self._order[0] in self._back:
                uid = self._order.popleft()
                ready.append(self._back.pop(uid))
                del self._waiting[uid]
            self._handed += len(ready)
            return ready

    def delivered(self, messages: list[Message]) -> None:
        """The callbacks of ``messages`` (from :meth:`take`) have returned."""
        with self._changed:
            self._handed -= len(messages)
            if not self._waiting and not self._handed:
                self._changed.notify_all()

    def wait(self, timeout: float) -> dict[str, int]:
        """Wait until every message sent is delivered (at most ``timeout`` s); how many are
        still missing then, by topic (empty: all delivered)."""
        with self._changed:
            self._changed.wait_for(lambda: not self._waiting and not self._handed, timeout)
            missing: dict[str, int] = {}
            for topic in self._waiting.values():
                missing[topic] = missing.get(topic, 0) + 1
            return missing

    def strangers(self) -> dict[str, int]:
        """How many messages from elsewhere came on the exclusive topics, by topic."""
        with self._changed:
            return dict(self._strangers)
