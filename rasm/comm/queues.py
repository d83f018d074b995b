"""A bounded FIFO that drops its oldest item when full; receivers block on a condition."""

from __future__ import annotations

import threading
from collections import deque
from typing import Generic, TypeVar

__all__ = ["DropOldestQueue"]

T = TypeVar("T")


class DropOldestQueue(Generic[T]):
    """Bounded, thread-safe queue: :meth:`put` never blocks; when full the oldest item goes.

    Fresh data is worth more than old data in a control loop, so overflow sacrifices the oldest
    message and counts it in :attr:`dropped`. :meth:`get` blocks on a condition variable (no
    polling) until an item arrives, the timeout expires or the queue is closed.
    """

    def __init__(self, maxsize: int) -> None:
        if maxsize < 1:
            raise ValueError(f"maxsize must be at least 1, got {maxsize}")
        self.maxsize = maxsize
        self.dropped = 0
        self._items: deque[T] = deque()
        self._cond = threading.Condition(threading.Lock())
        self._closed = False

    def put(self, item: T) -> bool:
        """Append ``item``; returns False if an old item was dropped to make room (or closed)."""
        with self._cond:
            if self._closed:
                return False
            kept = True
            if len(self._items) >= self.maxsize:
                self._items.popleft()
                self.dropped += 1
                kept = False
            self._items.append(item)
            self._cond.notify()
            return kept

    def get(self, timeout: float | None = None) -> T | None:
        """The oldest item; ``None`` if ``timeout`` expires or the queue is closed and empty."""
        with self._cond:
            if not self._items and not self._closed:
                self._cond.wait_for(lambda: self._items or self._closed, timeout)
            return self._items.popleft() if self._items else None

    def close(self) -> None:
        """Wake every waiting :meth:`get`; items already queued can still be taken."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        return self._closed

    def __len__(self) -> int:
        return len(self._items)
