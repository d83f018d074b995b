"""MQTT topic names, subscription patterns and a fast subscription index.

Every transport uses MQTT's rules (OASIS MQTT 3.1.1 §4.7), so an application behaves the same on
the in-process bus and over a broker: levels separated by ``/``; ``+`` matches exactly one level;
``#`` (last, alone in its level) matches the parent level and any number of levels below it; a
wildcard in the first level does not match topics starting with ``$`` (broker-internal topics).
"""

from __future__ import annotations

import threading
from collections.abc import Hashable
from typing import Generic, TypeVar

from rasm.errors import CommError

__all__ = ["validate_topic", "validate_pattern", "topic_matches", "TopicIndex"]

_MAX_TOPIC_BYTES = 65535  # MQTT encodes topic lengths in two bytes


def _check_common(text: object, what: str) -> str:
    if not isinstance(text, str):
        raise CommError(f"{what} must be a string, got {type(text).__name__}")
    if not text:
        raise CommError(f"{what} must not be empty")
    if "\x00" in text:
        raise CommError(f"{what} {text!r} contains a NUL character")
    if len(text) * 4 > _MAX_TOPIC_BYTES and len(text.encode("utf-8")) > _MAX_TOPIC_BYTES:
        raise CommError(f"{what} is longer than {_MAX_TOPIC_BYTES} bytes")
    return text


def validate_topic(topic: str) -> str:
    """Return ``topic`` if it is a valid topic name to publish on, else raise :class:`CommError`."""
    _check_common(topic, "topic")
    if "+" in topic or "#" in topic:
        raise CommError(
            f"topic {topic!r} contains a wildcard ('+' or '#'); wildcards are only allowed in "
            "subscription patterns"
        )
    return topic


def validate_pattern(pattern: str) -> str:
    """Return ``pattern`` if it is a valid subscription pattern, else raise :class:`CommError`."""
    _check_common(pattern, "pattern")
    levels = pattern.split("/")
    for i, level in enumerate(levels):
        if "#" in level and (level != "#" or i != len(levels) - 1):
            raise CommError(
                f"pattern {pattern!r}: '#' must be the whole last level (as in 'robot/#')"
            )
        if "+" in level and level != "+":
            raise CommError(f"pattern {pattern!r}: '+' must be a whole level (as in 'a/+/pose')")
    return pattern


def is_wildcard(pattern: str) -> bool:
    """True if ``pattern`` contains ``+`` or ``#`` (assumes it was validated)."""
    return "+" in pattern or "#" in pattern


def _match_levels(levels: list[str], topic: str) -> bool:
    if topic[:1] == "$" and levels[0] in ("+", "#"):
        return False
    parts = topic.split("/")
    n = len(parts)
    for i, level in enumerate(levels):
        if level == "#":
            return True  # '#' also matches the parent level: 'a/#' matches 'a'
        if i >= n or (level != "+" and level != parts[i]):
            return False
    return len(levels) == n


def topic_matches(pattern: str, topic: str) -> bool:
    """True if the subscription ``pattern`` matches the topic name ``topic``."""
    return _match_levels(pattern.split("/"), topic)


T = TypeVar("T", bound=Hashable)

_CACHE_LIMIT = 4096  # distinct topics remembered; beyond that the cache starts afresh


class TopicIndex(Generic[T]):
    """Subscriptions by pattern: a dict of exact topics plus a list of wildcard patterns.

    :meth:`match` is lock-free and memoises the answer per topic, so a steady stream on a few
    topics costs one dict lookup per message. Changes copy the structures and swap them in under
    a lock (subscriptions change rarely; messages are many), which also keeps readers on other
    threads consistent: they always see one whole generation, never a half-applied change.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        # (exact topic -> items, ((pattern, levels, item), ...), topic -> matching items)
        self._state: tuple[dict[str, tuple[T, ...]], tuple[tuple[str, list[str], T], ...],
                           dict[str, tuple[T, ...]]] = ({}, (), {})

    def add(self, pattern: str, item: T) -> None:
        """Register ``item`` under ``pattern`` (validated by the caller)."""
        with self._lock:
            exact, wild, _ = self._state
            if is_wildcard(pattern):
                wild = (*wild, (pattern, pattern.split("/"), item))
            else:
                exact = dict(exact)
                exact[pattern] = (*exact.get(pattern, ()), item)
            self._state = (exact, wild, {})

    def remove(self, pattern: str, item: T) -> bool:
        """Unregister ``item`` from ``pattern``; False if it was not registered."""
        with self._lock:
            exact, wild, _ = self._state
            if is_wildcard(pattern):
                kept = tuple(w for w in wild if not (w[0] == pattern and w[2] is item))
                if len(kept) == len(wild):
                    return False
                wild = kept
            else:
                items = exact.get(pattern, ())
                left = tuple(i for i in items if i is not item)
                if len(left) == len(items):
                    return False
                exact = dict(exact)
                if left:
                    exact[pattern] = left
                else:
                    del exact[pattern]
            self._state = (exact, wild, {})
            return True

    def match(self, topic: str) -> tuple[T, ...]:
        """Items whose pattern matches ``topic``: exact ones first, then wildcards in order."""
        exact, wild, cache = self._state
        found = cache.get(topic)
        if found is None:
            found = exact.get(topic, ()) + tuple(
                item for _, levels, item in wild if _match_levels(levels, topic)
            )
            if len(cache) >= _CACHE_LIMIT:
                cache.clear()
            cache[topic] = found
        return found

    def patterns(self) -> list[str]:
        """Every distinct pattern with at least one item, in no particular order."""
        exact, wild, _ = self._state
        return list(dict.fromkeys([*exact, *(w[0] for w in wild)]))

    def items(self) -> list[T]:
        """Every registered item."""
        exact, wild, _ = self._state
        return [i for items in exact.values() for i in items] + [w[2] for w in wild]

    def get(self, pattern: str) -> tuple[T, ...]:
        """The items registered under exactly ``pattern``."""
        exact, wild, _ = self._state
        if is_wildcard(pattern):
            return tuple(w[2] for w in wild if w[0] == pattern)
        return exact.get(pattern, ())

    def count(self, pattern: str) -> int:
        """How many items are registered under exactly ``pattern``."""
        exact, wild, _ = self._state
        if is_wildcard(pattern):
            return sum(1 for w in wild if w[0] == pattern)
        return len(exact.get(pattern, ()))

    def __len__(self) -> int:
        exact, wild, _ = self._state
        return sum(len(v) for v in exact.values()) + len(wild)
