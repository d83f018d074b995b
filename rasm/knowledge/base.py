"""The Knowledge Manager's store: typed values with a bounded history per key.

Every key holds a list of its last ``history`` samples (time, value), so a write is an append
(no SQL; the oldest are dropped in bulk) and a time-range query is two binary searches. One
re-entrant lock guards the store: bus callbacks, the loop and the storage flusher use it from
their threads.
"""

from __future__ import annotations

import logging
import math
import sys
import threading
from bisect import bisect_left, bisect_right
from collections.abc import Callable, Iterable, Mapping
from functools import partial
from operator import itemgetter
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


_new_tuple = tuple.__new__
#: ``Sample`` of a plain ``(time, value)`` tuple: tuple.__new__ skips NamedTuple's Python-level
#: __new__, partial keeps the call in C (a map over a slice of the samples makes no Python frame)
_as_sample = partial(_new_tuple, Sample)
_time_of = itemgetter(0)  # the time of a (time, value) sample, for a binary search by time
#: per declared type, the class a value must have exactly to be taken without its full check
#: (by _Series.add here, by the Telegraf's digest); json values always get the full check
EXACT_CLASS: dict[str, type] = {"float": float, "int": int, "bool": bool, "str": str}

Callback = Callable[[str, Sample], object]
"""Called as ``callback(key, sample)`` after each registration."""


class _Series:
    """The samples of one key: a list filled by append, its oldest dropped in bulk.

    The list holds the ``capacity`` newest samples at its end, in time order, and up to
    ``capacity // 4 + 1`` older ones before them, dropped all at once when there are more
    (:meth:`add`): a sample is stored with one append, and the newest is always
    ``samples[-1]``, where a ring overwritten in place would read and move a head index at
    every write. The samples held are ``samples[start():]``; those before are never handed out.

    The list holds plain ``(time, value)`` tuples: a :class:`Sample` (a named tuple, several
    times dearer to make) is made of one only when it is handed out (a read of samples, a
    subscriber, :meth:`KnowledgeBase.register_knowledge`'s answer), so a value stored and
    never read as a sample costs none (:meth:`between` keeps those it makes in the list). The
    times are read from the tuples (a binary search by key), not kept in a second list:
    :meth:`add` runs for every value stored, a search only for a time-range query.
    """

    __slots__ = ("decl", "check", "accept", "capacity", "samples")

    def __init__(self, decl: Declaration) -> None:
        self.decl = decl
        self.check: Check = make_check(decl)
        self.capacity = decl.history
        # what add() accepts without calling check, which returns such a value unchanged:
        # (the declared class exactly, low, high) and, for numbers, within the bounds (low is
        # None: no range test); then the length past which the oldest are dropped. One
        # attribute, as add() reads it for every value
        low = high = None
        if decl.type in ("float", "int"):
            low = -_INF if decl.minimum is None else decl.minimum
            high = _INF if decl.maximum is None else decl.maximum
        limit = self.capacity + self.capacity // 4 + 1
        self.accept: tuple[type | None, Any, Any, int] = (
            EXACT_CLASS.get(decl.type), low, high, limit
        )
        self.samples: list[tuple[float, Any]] = []  # (time, value): see the class's docstring

    def start(self) -> int:
        """The index in ``samples`` of the oldest sample held."""
        excess = len(self.samples) - self.capacity
        return excess if excess > 0 else 0

    def __len__(self) -> int:
        size = len(self.samples)
        capacity = self.capacity
        return size if size < capacity else capacity

    def last(self) -> float:
        """The time of the newest sample (below every finite time when there is none)."""
        samples = self.samples
        return samples[-1][0] if samples else _BEFORE_ALL

    def add(self, value: Any, time: float) -> tuple[float, Any]:
        """Check and store ``value`` at float ``time``; return ``(time, value as stored)``.
        Raise :class:`KnowledgeError` for a refused value or a time before the last sample's
        (or not finite)."""
        exact, low, high, limit = self.accept
        cls = type(value)
        if cls is not exact:
            cls = value.__class__  # what an object says it is decides, as it always did
        if cls is not exact or not (low is None or low <= value <= high):
            value = self.check(value)  # NaN fails the range test: check decides on it
        samples = self.samples
        last = samples[-1][0] if samples else _BEFORE_ALL  # as last(), without the call
        if not last <= time < _INF:  # also false for NaN
            raise KnowledgeBase._bad_time(self.decl.key, time, last)
        sample = (time, value)
        samples.append(sample)
        if len(samples) > limit:  # the oldest past capacity go together (one move of the rest)
            del samples[: len(samples) - self.capacity]
        return sample

    def latest(self) -> Sample | None:
        return _as_sample(self.samples[-1]) if self.samples else None

    def position(self, time: float, after: bool) -> int:
        """Logical index of the first sample with time >= ``time`` (> if ``after``)."""
        search = bisect_right if after else bisect_left
        start = self.start()
        return search(self.samples, time, start, key=_time_of) - start

    def between(self, lo: int, hi: int) -> list[Sample]:
        """Logical slice ``[lo, hi)``, oldest first.

        A plain tuple handed out is made a :class:`Sample` once and kept so in the list: a
        window read at every iteration (a sliding mean) makes one only for each new sample.
        """
        samples = self.samples
        start = self.start()
        out = []
        for index in range(start + lo, start + hi):
            sample = samples[index]
            if type(sample) is not Sample:
                sample = samples[index] = _as_sample(sample)
            out.append(sample)
        return out

    def all(self) -> list[Sample]:
        return self.between(0, len(self))


class Subscription:
    """Handle returned by :meth:`KnowledgeBase.subscribe`: call it (or ``cancel()``) to stop."""

    def __init__(self, kb: KnowledgeBase, callback: Callback) -> None:
        self._kb = kb
        self.callback = callback

    def cancel(self) -> None:
        """Stop the callback; calling it again does nothing."""
        self._kb._unsubscribe(self)

    __call__ = cancel

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.cancel()


def register_each(
    register: Callable[[str, Any, float], Any],
    values: Mapping[str, Any],
    time: float,
    into: dict[str, Any] | None = None,
) -> dict[str, Exception]:
    """Call ``register(key, value, time)`` for each value; return the refused ones with the error
    each raised (a refused value does not stop the others). With ``into``, the value of each
    sample ``register`` returned is put there under its key."""
    refused: dict[str, Exception] = {}
    for key, value in values.items():
        try:
            sample = register(key, value, time)
        except Exception as exc:
            refused[key] = exc
            continue
        if into is not None:
            into[key] = sample.value
    return refused


class KnowledgeBase:
    """Typed knowledge with a bounded history per key (the seed's Knowledge Manager).

    ``default_history`` is the history of keys registered without a declaration.
    """

    # slots for what each record reads, ``__dict__`` for the rest (as rasm.platform.block.Block)
    __slots__ = (
        "default_history", "_lock", "_series", "_subscriptions", "__dict__", "__weakref__",
    )

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
        lock = self._lock
        lock.acquire()  # not `with`: see the note on locks above
        try:
            series_of = self._series
            # a known key at a float time (every value of a running loop) is added directly
            if type(time) is float and key in series_of:
                sample = _as_sample(series_of[key].add(value, time))
            else:
                sample = _as_sample(self._append_sample(key, value, time))
            if self._subscriptions:  # most stores have none: no call then
                self._notify(key, sample)
            return sample
        finally:
            lock.release()

    def _append_sample(self, key: str, value: Any, time: float) -> tuple[float, Any]:
        """Check and store one value (the caller holds the lock); raise as register_knowledge."""
        series_of = self._series
        series = series_of[key] if key in series_of else self._infer(key, value)
        if type(time) is not float:
            # the value is checked first: its error is the one raised when both are bad
            series.check(value)
            time = self._time(key, time)
        return series.add(value, time)

    def _notify(self, key: str, sample: Sample) -> None:
        """Call every subscriber; a failing reader must not fail the writer (Telegraf, the loop)."""
        for subscription in self._subscriptions:  # a tuple: a callback may (un)subscribe
            try:
                subscription.callback(key, sample)
            except Exception:
                _log.exception("knowledge subscriber %r failed on %r", subscription.callback, key)

    def register_values(
        self, values: Mapping[str, Any], time: float, *, into: dict[str, Any] | None = None
    ) -> dict[str, Exception]:
        """Record every value of ``values`` at ``time``, as :meth:`register_knowledge` would one
        after the other, under one acquisition of the lock; return the refused ones.

        Each value is checked on its own: a refused one (``{key: the error register_knowledge
        would raise}``) is not stored and does not stop the others. Subscribers are called for
        each stored value, in order, before this returns. With ``into``, each value stored is
        put there too, under its key, as stored (its declared type's canonical form: what a
        read gives back), so a caller needs no read to know it.
        """
        kind = type(self)
        # (the class itself first: the same answer, without two attribute lookups)
        if kind is not KnowledgeBase and (
            kind.register_knowledge is not KnowledgeBase.register_knowledge
        ):
            # a store that registers its own way (Redis) is asked one value at a time
            return register_each(self.register_knowledge, values, time, into)
        refused: dict[str, Exception] = {}
        lock = self._lock
        lock.acquire()  # not `with`: see the note on locks above
        try:
            # a known key at a float time (every value of a running loop) is added directly
            series_of = self._series if type(time) is float else _NO_SERIES
            for key, value in values.items():
                try:
                    # `in` and [] rather than .get(): two dict lookups, no method call
                    if key in series_of:
                        entry = series_of[key].add(value, time)
                    else:
                        entry = self._append_sample(key, value, time)
                except Exception as exc:
                    refused[key] = exc
                    continue
                if into is not None:
                    into[key] = entry[1]
                if self._subscriptions:
                    self._notify(key, _as_sample(entry))
        finally:
            lock.release()
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
        lock = self._lock
        lock.acquire()  # not `with`: see the note on locks above
        try:
            series_of = self._series
            if key not in series_of:
                return default
            series = series_of[key]
            samples = series.samples
            return samples[-1][1] if samples else default  # the newest, if any
        finally:
            lock.release()

    def read_values(self, keys: Iterable[str], default: Any = None) -> dict[str, Any]:
        """``{key: read_knowledge(key, default)}`` for each of ``keys``, read under one lock (a
        consistent view: no write lands between two of them)."""
        if type(self).read_knowledge is not KnowledgeBase.read_knowledge:
            # a store that reads its own way (Redis) is asked one key at a time
            return {key: self.read_knowledge(key, default) for key in keys}
        out: dict[str, Any] = {}
        with self._lock:
            series_of = self._series
            for key in keys:
                series = series_of.get(key)
                samples = series.samples if series is not None else None
                # series.latest() without the call: the newest sample is the last
                out[key] = samples[-1][1] if samples else default
        return out

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
        lock = self._lock
        lock.acquire()  # not `with`: see the note on locks above
        try:
            series = self._series.get(key)
            if series is None:
                return []
            lo = 0 if since is None else series.position(since, after=False)
            hi = len(series) if until is None else series.position(until, after=True)
            if last is not None:
                lo = max(lo, hi - last)
            return series.between(lo, hi) if lo < hi else []
        finally:
            lock.release()

    def keys(self) -> list[str]:
        """Every key declared or registered, in the order they became known."""
        with self._lock:
            return list(self._series)

    def snapshot(self) -> dict[str, Any]:
        """The latest value of every key that has one."""
        with self._lock:
            return {
                key: series.samples[-1][1]  # the newest: see _Series.latest
                for key, series in self._series.items()
                if series.samples
            }

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
        subscription = Subscription(self, callback)
        with self._lock:
            self._subscriptions = (*self._subscriptions, subscription)
        return subscription

    def _unsubscribe(self, subscription: Subscription) -> None:
        with self._lock:
            self._subscriptions = tuple(s for s in self._subscriptions if s is not subscription)


_NO_SERIES: dict[str, _Series] = {}  # never written: every key takes the general path
