"""The Storage Manager's interface: knowledge pushed to non-volatile memory and restored from it.

The RoboSAPIENS design names two operations: ``registerKnowledgeUpdate`` (prepare data for
pushing) and ``updatePersistency`` (push it). Here the first only buffers, so it is cheap enough
to run on every registration (:meth:`Storage.buffer` skips its checks for values a knowledge base
already accepted); the second writes what was buffered, as one batch. Engines (SQLite, Redis)
subclass :class:`Storage`.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod

from rasm.errors import KnowledgeError
from rasm.knowledge.base import KnowledgeBase, Sample, Subscription


class Storage(ABC):
    """Persistence of a :class:`KnowledgeBase`. Use as a context manager or call :meth:`close`."""

    def __init__(self) -> None:
        self._attach_lock = threading.Lock()
        self._kb: KnowledgeBase | None = None
        self._subscription: Subscription | None = None

    @abstractmethod
    def register_knowledge_update(self, key: str, sample: Sample) -> None:
        """Buffer one sample of ``key`` for the next :meth:`update_persistency`."""

    @abstractmethod
    def update_persistency(self) -> int:
        """Write everything buffered; return how many samples were written."""

    @abstractmethod
    def restore(self, kb: KnowledgeBase, *, strict: bool = False) -> int:
        """Load the stored declarations and samples into ``kb``; return how many samples.

        Stored samples that no longer fit ``kb``'s declarations are skipped with a warning, or
        refused with :class:`KnowledgeError` if ``strict``.
        """

    @abstractmethod
    def buffer(self, key: str, sample: Sample) -> None:
        """Buffer a sample a knowledge base already accepted: checked against its declaration,
        not older than the key's last. The cheap path, taken for every value stored."""

    def buffer_all(self, samples: list[tuple[str, Sample]]) -> None:
        """:meth:`buffer` each ``(key, sample)`` pair, in order (a knowledge base's batch)."""
        for key, sample in samples:
            self.buffer(key, sample)

    @property
    def location(self) -> str:
        """Where it writes (a file, a server), for messages."""
        return repr(self)

    @property
    def pending(self) -> int:
        """Samples buffered and not written yet (what a failed last write loses)."""
        return 0

    @abstractmethod
    def _close(self) -> None:
        """Release the engine's resources (called once, after the last flush)."""

    @property
    def knowledge(self) -> KnowledgeBase | None:
        """The knowledge base this storage is attached to, if any."""
        return self._kb

    def attach(self, kb: KnowledgeBase) -> None:
        """Buffer every registration of ``kb`` from now on (and persist its declarations)."""
        with self._attach_lock:
            if self._kb is kb:
                return
            if self._kb is not None:
                raise KnowledgeError("this storage is already attached to another knowledge base")
            self._kb = kb
            self._subscription = kb.subscribe_batches(self.buffer_all)

    def detach(self) -> None:
        """Stop buffering the attached knowledge base's registrations."""
        with self._attach_lock:
            if self._subscription is not None:
                self._subscription.cancel()
            self._subscription = None
            self._kb = None

    def close(self) -> None:
        """Write what is buffered, detach, release the engine. Calling it again does nothing."""
        try:
            if not self.closed:
                self.update_persistency()
        finally:
            self.detach()
            self._close()

    @property
    @abstractmethod
    def closed(self) -> bool:
        """True once :meth:`close` ran."""

    def __enter__(self) -> Storage:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
