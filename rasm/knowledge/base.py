"""The Knowledge Manager's store: typed values with a bounded history per key.

Every key holds its last ``history`` samples (time, value) in time order, so a write is an
append and a time-range query is two binary searches. One re-entrant lock guards the store: bus
callbacks, the loop and the storage flusher use it from their threads.
"""

from __future__ import annotations

import logging
import math
import sys
import threading
from bisect import bisect_left, bisect_right
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from itertools import islice
from typing import Any, NamedTuple

from rasm.errors import KnowledgeError
from rasm.knowledge.values import (
    DEFAULT_HISTORY,
    Check,
    Declaration,
    infer_type,
    make_check,
)

_log = logging.getLogger("rasm.knowledge")


# Below every finite time: the first sample of a key may have any finite time, -inf is refused.
_BEFORE_ALL = -sys.float_info.max
_INF = math.inf


class Sample(NamedTuple):
    """One value of a key and the platform-clock time (seconds) it was registered at."""

    time: float
    value: Any


Callback = Callable[[str, Sample], object]
"""Called as ``callback(key, sample)`` after each registration."""

BatchCallback = Callable[[list[tuple[str, Sample]]], object]
"""Called as ``callback(samples)`` with the ``(key, sample)`` pairs of one registration call."""


def _time_of(sample: Sample) -> float:
    return sample.time


class _Series:
    """The samples of one key: its last ``decl.history`` samples, oldest first."""

    def __init__(self, decl: Declaration) -> None:
        self.decl = decl
        self.check: Check = make_check(decl)
        self.capacity = decl.history
        self.samples: deque[Sample] = deque(maxlen=decl.history)

    def __len__(self) -> int:
        return len(self.samples)

    def last(self) -> float:
        """The time of the newest sample (below every finite time when there is none)."""
        return self.samples[-1].time if self.samples else _BEFORE_ALL

    def add(self, value: Any, time: float) -> Sample:
        """Check and store ``value`` at float ``time``; return the sample stored. Raise
        :class:`KnowledgeError` for a refused value or a time before the last sample's (or
        not finite)."""
        value = self.check(value)
        last = self.last()
        if not last <= time < _INF:  # also false for NaN
            raise KnowledgeBase._bad_time(self.decl.key, time, last)
        sample = Sample(time, value)
        self.samples.append(sample)
        return sample

    def latest(self) -> Sample | None:
        return self.samples[-1] if self.samples else None

    def position(self, time: float, after: bool) -> int:
        """Index of the first sample with time >= ``time`` (> if ``after``)."""
        search = bisect_right if after else bisect_left
        return search(self.samples, time, key=_time_of)

    def between(self, lo: int, hi: int) -> list[Sample]:
        """The samples ``[lo, hi)``, oldest first."""
        return list(islice(self.samples, lo, hi))

    def all(self) -> list[Sample]:
        return list(self.samples)


class Subscription:
    """Handle returned by :meth:`KnowledgeBase.subscribe`: call it (or ``cancel()``) to stop."""

    def __init__(
        self, kb: KnowledgeBase, callback: Callback | BatchCallback, *, batches: bool = False
    ) -> None:
        self._kb = kb
        self.callback = callback
        self.batches = batches

    def cancel(self) -> None:
        """Stop the callback; calling it again does nothing."""
        self._kb._unsubscribe(self)

    __call__ = cancel

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.cancel()


class KnowledgeBase:
    """Typed knowledge with a bounded history per key (the Knowledge Manager of the platform).

    ``default_history`` is the history of keys registered without a declaration.
    """

    def __init__(self, *, default_history: int = DEFAULT_HISTORY) -> None:
        Declaration("default", "float", history=default_history)  # validates the number
        self.default_history = default_history
        self._lock = threading.RLock()
        self._series: dict[str, _Series] = {}
        # replaced, never mutated, so a registration can iterate it while another thread
        # subscribes or cancels
        self._subscriptions: tuple[Subscription, ...] = ()

    # -- declarations ---------------------------------------------------------------------------

    def declare(
        self,
        key: str,
        type: str,
        *,
        history: int | None = None,
        minimum: float | None = None,
        maximum: float | None = None,
    ) -> Declaration:
        """Declare what ``key`` holds. Re-declaring is allowed: samples already held must fit the
        new declaration (they are converted, e.g. ints to floats) and the last ``history`` stay.
        """
        decl = Declaration(
            key, type, self.default_history if history is None else history, minimum, maximum
        )
        with self._lock:
            old = self._series.get(key)
            if old is None:
                self._series[key] = _Series(decl)
                return decl
            if old.decl == decl:
                return decl
            fresh = _Series(decl)
            kept = old.all()[-decl.history :]
            try:
                converted = [Sample(s.time, fresh.check(s.value)) for s in kept]
            except KnowledgeError as exc:
                raise KnowledgeError(
                    f"cannot declare {key!r} as {type}: a sample it already holds does not fit "
                    f"({exc})"
                ) from exc
            for sample in converted:  # in time order and checked: add() accepts each as is
                fresh.add(sample.value, sample.time)
            self._series[key] = fresh
            return decl

    def declaration(self, key: str) -> Declaration | None:
        """The declaration of ``key`` (inferred at its first write if never declared)."""
        with self._lock:
            series = self._series.get(key)
            return series.decl if series is not None else None

    def declarations(self) -> dict[str, Declaration]:
        """All declarations, by key."""
        with self._lock:
            return {key: series.decl for key, series in self._series.items()}

    # -- writing --------------------------------------------------------------------------------

    def register_knowledge(self, key: str, value: Any, time: float) -> Sample:
        """Record ``value`` for ``key`` at ``time`` (platform-clock seconds); return the sample.

        Raises :class:`KnowledgeError` for a value of the wrong type or out of its bounds, and for
        a time older than the key's last sample. Subscribers are called before this returns.
        """
        with self._lock:
            sample = self._store(key, value, time)
            self._notify([(key, sample)])
            return sample

    def _store(self, key: str, value: Any, time: float) -> Sample:
        """Check and store one value (the lock is held); subscribers are not called."""
        series = self._series.get(key)
        if series is None:
            series = self._infer(key, value)
        if not isinstance(time, float):
            # the value is checked first: its error is the one raised when both are bad
            series.check(value)
            time = self._time(key, time)
        return series.add(value, time)

    def _notify(self, samples: list[tuple[str, Sample]]) -> None:
        """Call every subscriber; a failing reader must not fail the writer (Telegraf, the loop)."""
        for subscription in self._subscriptions:  # a tuple: a callback may (un)subscribe
            try:
                if subscription.batches:
                    subscription.callback(samples)
                else:
                    for key, sample in samples:
                        subscription.callback(key, sample)
            except Exception:
                _log.exception("knowledge subscriber %r failed", subscription.callback)

    def register_values(self, values: Mapping[str, Any], time: float) -> dict[str, Exception]:
        """Record every value of ``values`` at ``time``, as :meth:`register_knowledge` would one
        after the other, under one acquisition of the lock; return the refused ones.

        Each value is checked on its own: a refused one (``{key: the error register_knowledge
        would raise}``) is not stored and does not stop the others. Subscribers are called for
        the stored values, in order, before this returns (a batch subscriber once for all).
        """
        refused: dict[str, Exception] = {}
        stored: list[tuple[str, Sample]] = []
        with self._lock:
            for key, value in values.items():
                try:
                    stored.append((key, self._store(key, value, time)))
                except Exception as exc:
                    refused[key] = exc
            if stored:
                self._notify(stored)
        return refused

    def load_samples(self, key: str, samples: Iterable[Sample]) -> int:
        """Append samples in bulk **without** notifying subscribers; return how many.

        Used by a storage's restore (so restored samples are not buffered again). All are checked
        before any is stored: on an error nothing changes.
        """
        samples = list(samples)
        with self._lock:
            series = self._series.get(key)
            if series is None:
                if not samples:
                    return 0
                series = _Series(self._inferred(key, samples[0].value))
                new = True
            else:
                new = False
            checked: list[Sample] = []
            last = series.last()
            for time, value in samples:
                value = series.check(value)
                time = self._time(key, time)
                if not last <= time < _INF:
                    raise self._bad_time(key, time, last)
                last = time
                checked.append(Sample(time, value))
            for sample in checked[-series.capacity :]:  # checked and in order: add() takes them
                series.add(sample.value, sample.time)
            if new:
                self._series[key] = series
            return len(checked)

    def _inferred(self, key: str, value: Any) -> Declaration:
        return Declaration(key, infer_type(value), self.default_history)

    def _infer(self, key: str, value: Any) -> _Series:
        series = _Series(self._inferred(key, value))
        self._series[key] = series
        return series

    @staticmethod
    def _time(key: str, time: Any) -> float:
        if isinstance(time, bool) or not isinstance(time, int | float):
            raise KnowledgeError(
                f"knowledge {key!r}: time must be a number of seconds, got {time!r}"
            )
        return float(time)

    @staticmethod
    def _bad_time(key: str, time: float, last: float) -> KnowledgeError:
        if math.isnan(time) or math.isinf(time):
            return KnowledgeError(f"knowledge {key!r}: time must be finite, got {time!r}")
        return KnowledgeError(
            f"knowledge {key!r}: time {time!r} is older than its last sample at {last!r} "
            "(times must not decrease per key)"
        )

    # -- reading --------------------------------------------------------------------------------

    def read_knowledge(self, key: str, default: Any = None) -> Any:
        """The latest value of ``key``, or ``default`` if it has none."""
        sample = self.read_sample(key)
        return default if sample is None else sample.value

    def read_values(self, keys: Iterable[str], default: Any = None) -> dict[str, Any]:
        """``{key: read_knowledge(key, default)}`` for each of ``keys``, read under one lock (a
        consistent view: no write lands between two of them)."""
        with self._lock:
            return {key: self.read_knowledge(key, default) for key in keys}

    def read_sample(self, key: str) -> Sample | None:
        """The latest sample of ``key``, or None."""
        with self._lock:
            series = self._series.get(key)
            return series.latest() if series is not None else None

    def history(
        self,
        key: str,
        *,
        last: int | None = None,
        since: float | None = None,
        until: float | None = None,
    ) -> list[Sample]:
        """Samples of ``key`` held in memory, oldest first: those with ``since <= time <= until``
        (either bound optional), and of those only the ``last`` newest if given.

        The range is found by binary search: O(log n) plus the size of the answer.
        """
        if last is not None and (isinstance(last, bool) or not isinstance(last, int) or last < 0):
            raise KnowledgeError(
                f"history of {key!r}: last must be a whole number >= 0, got {last!r}"
            )
        with self._lock:
            series = self._series.get(key)
            if series is None:
                return []
            lo = 0 if since is None else series.position(since, after=False)
            hi = len(series) if until is None else series.position(until, after=True)
            if last is not None:
                lo = max(lo, hi - last)
            return series.between(lo, hi) if lo < hi else []

    def keys(self) -> list[str]:
        """Every key declared or registered, in the order they became known."""
        with self._lock:
            return list(self._series)

    def snapshot(self) -> dict[str, Any]:
        """The latest value of every key that has one."""
        with self._lock:
            return {
                key: series.samples[-1].value
                for key, series in self._series.items()
                if series.samples
            }

    def close(self) -> None:
        """Release what the store holds (nothing, in memory; a store on a server closes its
        connection)."""

    def __contains__(self, key: object) -> bool:
        with self._lock:
            return key in self._series

    # -- subscribers ----------------------------------------------------------------------------

    def subscribe(self, callback: Callback) -> Subscription:
        """Call ``callback(key, sample)`` after each registration; return the handle that stops it.

        Callbacks run on the writer's thread, in registration order, while the store is locked:
        keep them short (set an event, append to a buffer). They may read the store. An exception
        in a callback is logged and never reaches the writer.
        """
        return self._subscribe(Subscription(self, callback))

    def subscribe_batches(self, callback: BatchCallback) -> Subscription:
        """As :meth:`subscribe`, but ``callback(samples)`` gets the ``(key, sample)`` pairs of
        one registration call at once: one pair from :meth:`register_knowledge`, every stored
        value of :meth:`register_values` (what a Storage Manager buffers, one call a record)."""
        return self._subscribe(Subscription(self, callback, batches=True))

    def _subscribe(self, subscription: Subscription) -> Subscription:
        with self._lock:
            self._subscriptions = (*self._subscriptions, subscription)
        return subscription

    def _unsubscribe(self, subscription: Subscription) -> None:
        with self._lock:
            self._subscriptions = tuple(s for s in self._subscriptions if s is not subscription)

