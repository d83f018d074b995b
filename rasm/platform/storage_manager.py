"""Storage Manager: knowledge updates batched and persisted."""

from __future__ import annotations

import logging
from typing import Any

from rasm.knowledge.base import Sample
from rasm.knowledge.storage import Storage
from rasm.losses import WriteFailure, WriteGuard
from rasm.platform.block import Block

__all__ = ["LIVE_FLUSH_PERIOD", "SIMULATED_FLUSH_PERIOD", "StorageManager"]

LIVE_FLUSH_PERIOD = 1.0
"""Seconds between a live run's first unpersisted update and its flush: what a crash may lose."""

SIMULATED_FLUSH_PERIOD = 10.0
"""The same on the simulated clock. Ten simulated seconds pass in milliseconds, and the next
simulated run starts its file afresh: flushing every simulated second cost a simulated hour 3,600
transactions that no crash needs (the trace file still has every record)."""

_log = logging.getLogger("rasm.platform")


class StorageManager(Block):
    """Storage Manager (stom): batches knowledge updates and persists them (SQLite, WAL).

    Every update is buffered by the storage; only the first one while the chart is ``idle``
    steps it (to ``dirty``), and the chart persists the batch ``flush_period`` seconds later.

    A write that fails (a full disk, a read-only file system) never stops the loop: it is
    logged once with the file, later ones are counted (:attr:`failure`), the samples wait in
    the storage's buffer (bounded: the newest ``keep`` of each key) and the chart retries after
    the next ``flush_period``. What the last write at the end of the run cannot persist is
    counted as lost.
    """

    chart_name = "storage_manager"
    short_name = "stom"

    def __init__(
        self, storage: Storage | None, *, flush_period: float = LIVE_FLUSH_PERIOD, **kw: Any
    ) -> None:
        self.storage = storage
        self.persisted = 0
        self.guard = WriteGuard(
            "knowledge store", storage.location if storage is not None else "(none)",
            unit="samples", logger=_log,
        )
        self._idle = False  # the chart is in `idle`: the next update is the first of a batch
        super().__init__(context={"flush_period": flush_period}, **kw)

    def register_knowledge_update(self, key: str, sample: Sample) -> None:
        self.register_knowledge_updates([(key, sample)])

    def register_knowledge_updates(self, samples: list[tuple[str, Sample]]) -> None:
        """Buffer the ``(key, sample)`` pairs of one registration (the knowledge base checked
        them); the first of a batch steps the chart to ``dirty``."""
        if self.storage is None or not samples:
            return
        self.storage.buffer_all(samples)
        if self._idle:
            self._idle = False
            self.send("update_registered")

    def on_enter_idle(self) -> None:
        self._idle = True

    def on_fault(self, reason: str | None) -> None:
        self._idle = False

    @property
    def failure(self) -> WriteFailure | None:
        """The writes that failed (None: none did)."""
        return self.guard.failure

    def on_enter_persisting(self) -> None:
        try:
            self.persisted += self.update_persistency()
        except Exception as exc:  # a full disk must not stop the loop; the chart retries
            self.guard.fail(
                "committing", exc, time=self.clock.time,
                consequence="the run goes on; the samples wait in memory and are written when "
                "the store takes writes again (the run summary counts the failures)",
            )
            self.post("persist_failed")
            return
        self.guard.succeeded()
        self.post("persisted")

    def update_persistency(self) -> int:
        return 0 if self.storage is None else int(self.storage.update_persistency() or 0)

    def on_termination(self) -> None:
        self._idle = False
        if self.storage is None:
            return
        try:
            self.storage.close()  # the last write, then the file is released whatever happens
        except Exception as exc:
            self.guard.fail(
                "committing", exc, lost=self.storage.pending, time=self.clock.time,
                consequence="the samples not written yet are lost",
            )
