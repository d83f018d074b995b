"""Helpers of the comm tests."""

from __future__ import annotations

import queue

from rasm.comm import Message


class Inbox:
    """Messages of one subscription, awaited with a timeout (no sleeps)."""

    def __init__(self) -> None:
        self.queue: queue.Queue[Message] = queue.Queue()

    def __call__(self, message: Message) -> None:
        self.queue.put(message)

    def get(self, timeout: float = 10.0) -> Message:
        return self.queue.get(timeout=timeout)

    def take(self, n: int, timeout: float = 10.0) -> list[Message]:
        return [self.get(timeout) for _ in range(n)]

    def empty(self) -> bool:
        return self.queue.empty()
