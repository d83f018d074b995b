"""rosbag2 recordings as the managed system: replayed into the loop, or read as a trace.

A recording (an ``.mcap`` or ``.db3`` storage file, or a bag folder) is read with the
manifest's probes: each message of a probe's topic is one record of that probe's signals, read
by field path as Telegraf reads a live message. A record's time is the message's log time in
seconds, or with ``stamp: header`` its ``header.stamp`` (never later than its log time).

- :func:`recorded_trace` turns a recording into the records ``rasm check`` judges, one
  by one;
- :class:`Replay` feeds it to a running platform on the simulated clock, message by message
  at its recorded time (``rasm run APP --replay BAG``).

Both stream the recording (:class:`rasm.ros2.BagReader`): it is never loaded whole.
"""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rasm.errors import Misfit
from rasm.losses import Damage
from rasm.platform.manifest import Probe
from rasm.properties.times import NS_PER_SECOND, Seconds
from rasm.values import fit

if TYPE_CHECKING:
    from rasm.platform.scheduler import Scheduler
    from rasm.ros2 import BagReader, TypeStore

__all__ = ["LeftOut", "Recording", "RecordedTrace", "Replay", "recorded_trace"]

_log = logging.getLogger("rasm.replay")


def _seconds(time_ns: int) -> Seconds:
    """Nanoseconds as exact seconds: the float nearest them, carrying them exactly for the
    monitors (what :class:`Seconds` makes of their decimal text, without parsing it)."""
    seconds = float.__new__(Seconds, time_ns / NS_PER_SECOND)  # int / int: correctly rounded
    seconds.ns = time_ns
    return seconds


class Recording:
    """The probes' topics of one recording, streamed in log-time order.

    Raises :class:`rasm.ros2.BagError` for a recording that cannot be read, none of whose
    topics a probe reads, or that records a probe's topic with another type than the probe's.
    ``absent`` lists the probes' topics the recording does not have.
    """

    def __init__(
        self,
        path: str | Path,
        probes: list[Probe],
        store: TypeStore | None,
        *,
        fields: Mapping[str, list[str]] | None = None,
    ) -> None:
        from rasm.ros2 import BagError, BagReader, normalize_type, recorded_topics

        self.path = Path(path)
        recorded = recorded_topics(self.path)
        self.probes = {p.topic: p for p in probes}
        self.topics = [p.topic for p in probes if p.topic in recorded]
        self.absent = [p.topic for p in probes if p.topic not in recorded]
        if not self.topics:
            from rasm.ros2.bags import recorded_damage

            damage = recorded_damage(self.path)
            damaged = "; it is damaged: " + "; ".join(d.describe() for d in damage) if (
                damage) else ""
            raise BagError(
                f"{self.path}: no probe topic ({', '.join(self.probes) or 'none'}) is in this "
                f"recording (it has {', '.join(sorted(recorded)) or 'no topics'}){damaged}"
            )
        for topic in self.topics:
            declared = self.probes[topic].type
            if declared and normalize_type(declared) != normalize_type(recorded[topic]):
                raise BagError(
                    f"{self.path}: topic {topic} is recorded as {recorded[topic]}, but its "
                    f"probe reads {declared}"
                )
        self.types = {topic: recorded[topic] for topic in self.topics}
        self.store = store
        # fields: a topic's messages are the values of these field paths, read from the CDR
        self.reader: BagReader = BagReader(
            self.path, topics=self.topics, store=store, fields=fields
        )

    @property
    def rejected(self) -> int:
        """Messages that did not decode (skipped, logged once per topic)."""
        return self.reader.rejected

    @property
    def damage(self) -> list[Damage]:
        """What could not be read of the probes' topics (complete once read to the end)."""
        return self.reader.damage

    def __iter__(self) -> Iterator[tuple[int, str, dict[str, Any]]]:
        return iter(self.reader)


@dataclass
class LeftOut:
    """What a pass over a recording left out of its records."""

    refused: Counter[str] = field(default_factory=Counter)
    out_of_order: int = 0
    absent: list[str] = field(default_factory=list)

    def notes(self) -> list[str]:
        """What was left out, one line each (nothing when nothing was). Messages that could
        not be read (damage, messages that do not decode) are not notes: see
        :attr:`RecordedTrace.damage`."""
        out = [f"no messages on {topic} in the recording" for topic in self.absent]
        for reason, n in sorted(self.refused.items()):
            out.append(f"{n} value(s) refused: {reason}")
        if self.out_of_order:
            out.append(
                f"{self.out_of_order} record(s) skipped: their header stamp goes back in time"
            )
        return out


class RecordedTrace:
    """A recording read as a trace: iterating gives its ``(time, record)`` items one by one,
    reading the recording message by message (each pass reads it anew, holding nothing). Only
    the fields the probes' signals name (and ``header.stamp`` with ``stamp: header``) are read
    out of each message; the rest is not decoded.

    ``messages`` and ``left_out`` describe the first pass read to its end (None before);
    :attr:`damage` what could not be read (complete once a pass read it to the end).
    """

    def __init__(self, path: str | Path | None, probes: list[Probe],
                 store: TypeStore | None) -> None:
        self.messages: int | None = None
        self.left_out: LeftOut | None = None
        self.probes = {p.topic: p for p in probes}
        fields = {}
        for probe in probes:
            fields[probe.topic] = [s.field or name for name, s in probe.signals.items()]
            if probe.stamp == "header":  # the manifest checked the type has a header
                fields[probe.topic] += ["header.stamp.sec", "header.stamp.nanosec"]
        self.recording = None if path is None else Recording(path, probes, store, fields=fields)

    def notes(self) -> list[str]:
        """What the first whole pass left out, one line each."""
        return [] if self.left_out is None else self.left_out.notes()

    @property
    def damage(self) -> list[Damage]:
        """What could not be read of the probes' topics: damaged parts, undecodable messages."""
        return [] if self.recording is None else self.recording.damage

    def __iter__(self) -> Iterator[tuple[Seconds, dict[str, Any]]]:
        from rasm.ros2.fieldread import MISSING

        if self.recording is None:  # the properties read no probe's signal
            self.messages, self.left_out = 0, LeftOut()
            return
        left = LeftOut(absent=self.recording.absent)
        signals = {topic: list(p.signals.items()) for topic, p in self.probes.items()}
        stamped = {topic for topic, p in self.probes.items() if p.stamp == "header"}
        messages = 0
        last_ns = None
        for time_ns, topic, values in self.recording:
            messages += 1
            record: dict[str, Any] = {}
            for (key, signal), value in zip(signals[topic], values, strict=False):
                if value is MISSING:
                    left.refused["no such field in this message"] += 1
                    continue
                try:
                    record[key] = fit(
                        signal.scaled(value), signal.type, minimum=signal.minimum,
                        maximum=signal.maximum, int_as_float=False,
                    )
                except Misfit as misfit:
                    left.refused[f"{topic} {key}: {misfit.reason}"] += 1
            if not record:
                continue
            if topic in stamped:
                sec, nanosec = values[-2:]
                time_ns = min(time_ns, sec * NS_PER_SECOND + nanosec)
            if last_ns is not None and time_ns < last_ns:
                left.out_of_order += 1
                continue
            last_ns = time_ns
            yield _seconds(time_ns), record
        if self.left_out is None:
            self.messages, self.left_out = messages, left


def recorded_trace(
    path: str | Path,
    probes: list[Probe],
    store: TypeStore | None,
    signals: Mapping[str, str] | None = None,
) -> RecordedTrace:
    """The records of a recording, as ``rasm check`` judges them, streamed (see
    :class:`RecordedTrace`); a recording that cannot be read raises :class:`BagError` now.

    ``signals`` (a property file's ``spec.signals``) limits the records to the signals the
    properties read: a message giving none of them is no record. Values are checked against
    their probe's declared types (a misfit is left out of its record and counted).
    """
    if signals is not None:  # a topic giving none of the signals read is not even decoded
        probes = [
            replace(p, signals={k: v for k, v in p.signals.items() if k in signals})
            for p in probes
        ]
        probes = [p for p in probes if p.signals]
        if not probes:  # the properties read no probe's signal: the records are the loop's
            return RecordedTrace(None, [], store)
    return RecordedTrace(path, probes, store)


class Replay:
    """A recording driving a platform in place of its managed system.

    :meth:`start` puts the recording's messages on the scheduler, one job per message at its
    log time, each handing it to ``digest(topic, message, time)`` (Telegraf); after the last
    one and ``tail`` more seconds the scheduler is stopped. Only the next message is read ahead.

    The replay's timeline starts at the recording's first log time (:attr:`origin_ns`): a
    message is played at its log time less that, in seconds exact to the nanosecond (a log
    time of 2026 in epoch seconds, as a float, would carry float noise into every time).
    """

    def __init__(self, recording: Recording) -> None:
        self.recording = recording
        self.messages = 0
        self.first_time: float | None = None
        self.last_time: float | None = None
        self.origin_ns = 0  # the first log time: 0 s on the replay's timeline
        self._items: Iterator[tuple[int, str, dict[str, Any]]] = iter(recording)
        self._next = next(self._items, None)
        if self._next is not None:
            self.origin_ns = self._next[0]
            self.first_time = 0.0

    @property
    def damage(self) -> list[Damage]:
        """What could not be replayed of the recording (complete once it was played out)."""
        return self.recording.damage

    def start(
        self,
        scheduler: Scheduler,
        digest: Callable[[str, dict[str, Any], float], Any],
        *,
        tail: float,
    ) -> None:
        self._scheduler = scheduler
        self._digest = digest
        self._tail = tail
        self._schedule()

    def _schedule(self) -> None:
        item = self._next
        if item is None:
            end = (self.last_time if self.last_time is not None else self._scheduler.now())
            self._scheduler.at(end + self._tail, self._scheduler.stop)
            return
        time = (item[0] - self.origin_ns) / NS_PER_SECOND  # int / int: correctly rounded
        self._scheduler.at(time, lambda: self._play(item, time))

    def _play(self, item: tuple[int, str, dict[str, Any]], time: float) -> None:
        _, topic, message = item
        self.messages += 1
        self.last_time = time
        self._next = next(self._items, None)
        try:
            self._digest(topic, message, time)
        finally:
            self._schedule()

