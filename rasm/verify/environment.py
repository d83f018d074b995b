"""The environment a chart is verified under: what may arrive, and how the clock may move.

An environment file (``rasm verify CHART --env ENV.yaml``, SPEC §11)::

    events:                          # what may arrive, one at a time, in any order
      - close
      - name: key
        data: {digit: [1, 2, 3]}     # finite domains: every combination is tried
    clock: [0.5, 2]                  # amounts the clock may advance by between events

Without a file, :func:`default_environment` gives the events the chart receives, their data
split into the regions the guards' comparisons make (:mod:`rasm.verify.regions`), and a clock
that advances to the chart's next deadline (the next timer or delayed event).
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rasm.errors import Location, SourceError, not_utf8
from rasm.times import format_nanoseconds, nanoseconds
from rasm.verify.code import ChartCode
from rasm.yamltext import YamlSource, load_yaml, plain

__all__ = ["EnvEvent", "Environment", "default_environment", "load_environment"]

MAX_COMBINATIONS = 10_000  # data combinations one event of an environment file may stand for


@dataclass(frozen=True)
class EnvEvent:
    """An event that may arrive: ``domains`` gives each data key's values (every combination
    is tried); keys a guard reads and ``domains`` leaves out are split into regions."""

    name: str
    domains: tuple[tuple[str, tuple[Any, ...]], ...] = ()
    location: Location | None = field(default=None, compare=False)

    def combinations(self) -> list[dict[str, Any]]:
        """Every data dict the domains stand for ({} when there are none)."""
        keys = [key for key, _ in self.domains]
        values = [domain for _, domain in self.domains]
        return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*values)]


@dataclass(frozen=True)
class Environment:
    """Events that may arrive and clock advances (in nanoseconds; empty: to the next
    deadline). ``source`` names the file, or says the environment is the default."""

    events: tuple[EnvEvent, ...]
    clock_ns: tuple[int, ...] = ()
    source: str = "the default environment"

    def describe(self) -> str:
        names = ", ".join(event.name for event in self.events) or "no event"
        clock = (
            "the clock advancing by " + ", ".join(format_nanoseconds(ns) for ns in self.clock_ns)
            if self.clock_ns else "the clock advancing to each next deadline"
        )
        return f"{names}; {clock} ({self.source})"


def _scalar(value: Any) -> bool:
    return value is None or isinstance(value, bool | int | float | str)


def _event(src: YamlSource, item: Any, index: int, seq: Any) -> EnvEvent:
    where = src.item(seq, index)
    if isinstance(item, str):
        if not item:
            raise src.error("an event name is a non-empty string", where)
        return EnvEvent(item, (), where)
    if not isinstance(item, Mapping):
        raise src.error(
            "an event is a name, or a mapping {name: ..., data: {key: [values]}}", where
        )
    unknown = sorted(set(item) - {"name", "data"})
    if unknown:
        where = src.key(item, unknown[0])
        raise src.error(f"unknown key {unknown[0]!r} (expected name, data)", where)
    name = item.get("name")
    if not isinstance(name, str) or not name:
        raise src.error("an event needs a name (a non-empty string)", src.node(item))
    data = item.get("data", {})
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise src.error("data is a mapping of keys to lists of values", src.value(item, "data"))
    domains = []
    count = 1
    for key, values in data.items():
        at = src.value(data, key)
        if not isinstance(key, str) or not key.isidentifier():
            raise src.error(
                f"data key {key!r} is not a name an event's data can have", src.key(data, key)
            )
        if key in ("name", "data", "delay"):
            raise src.error(
                f"data key {key!r} is reserved by sismic; rename it", src.key(data, key)
            )
        if _scalar(values):
            values = [values]
        if not isinstance(values, list) or not values:
            raise src.error(f"the domain of {key!r} is a non-empty list of values", at)
        for i, value in enumerate(values):
            if not _scalar(plain(value)):
                raise src.error(
                    f"a value of {key!r} is a number, a string, true, false or null",
                    src.item(values, i),
                )
        count *= len(values)
        if count > MAX_COMBINATIONS:
            raise src.error(
                f"the data of {name!r} stands for more than {MAX_COMBINATIONS} combinations; "
                "give smaller domains", src.value(item, "data")
            )
        domains.append((str(key), tuple(plain(v) for v in values)))
    return EnvEvent(name, tuple(domains), where)


def _clock(src: YamlSource, doc: Mapping) -> tuple[int, ...]:
    values = doc.get("clock")
    where = src.value(doc, "clock")
    if values is None:
        return ()
    if not isinstance(values, list):
        values = [values]
    amounts = []
    for i, value in enumerate(values):
        at = src.item(values, i) if isinstance(doc["clock"], list) else where
        ns = None if isinstance(value, bool) else nanoseconds(plain(value))
        if ns is None or ns <= 0:
            raise src.error("a clock advance is a positive number of seconds", at)
        if ns not in amounts:
            amounts.append(ns)
    return tuple(amounts)


def load_environment(path: str | Path, *, text: str | None = None) -> Environment:
    """Read an environment file; problems are :class:`SourceError` at their line and column."""
    file = str(path)
    if text is None:
        try:
            text = Path(path).read_text(encoding="utf-8")
        except UnicodeDecodeError as exc:
            raise not_utf8(file, exc) from None
        except OSError as exc:
            why = f"cannot read the environment: {exc.strerror}"
            raise SourceError(why, Location(file)) from None
    src = load_yaml(text, file)
    doc = src.data
    if doc is None:
        doc = {}
    if not isinstance(doc, Mapping):
        raise src.error("an environment is a mapping with events: and clock:", src.start())
    unknown = sorted(set(doc) - {"events", "clock"})
    if unknown:
        where = src.key(doc, unknown[0])
        raise src.error(f"unknown key {unknown[0]!r} (expected events, clock)", where)
    seq = doc.get("events") or []
    if not isinstance(seq, list):
        raise src.error(
            "events is a list of event names or {name, data} mappings", src.value(doc, "events")
        )
    events = tuple(_event(src, item, i, seq) for i, item in enumerate(seq))
    return Environment(events, _clock(src, doc), file)


def default_environment(code: ChartCode, receives: list[str] | None = None) -> Environment:
    """The events the chart receives (``receives``, e.g. a platform chart's interface, else
    every event a transition waits for), their data left to the regions; the clock advancing to
    each next deadline."""
    names = list(receives) if receives is not None else list(code.events)
    return Environment(tuple(EnvEvent(name) for name in names))


def as_json_value(value: Any) -> str:
    return json.dumps(value)
