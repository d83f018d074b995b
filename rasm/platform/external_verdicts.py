"""Verdicts of monitors outside rasm, taken in as veto sources.

A monitor running beside the loop (the RoboSAPIENS Trustworthiness Checker over MQTT, a
Copilot/Ogma monitor over ROS 2) publishes its verdicts on a topic; the manifest declares it
under ``trustworthiness.external_verdicts`` and the Trustworthiness Manager then counts it as
a veto property of that name. Three kinds of topic:

- JSON (MQTT, the local bus): ``{"value": true|false}``, the public checker's convention;
- ``std_msgs/msg/Bool``: ``data`` is the verdict;
- ``std_msgs/msg/Empty``: every message is a violation (a Copilot handler fires while its
  condition holds); it vetoes ``hold`` seconds after the last one, and holds otherwise.

Fail closed, and only the source itself speaks for it:

- a JSON or Bool source's verdict at time t is true only if it was heard within its
  ``freshness`` window (t - freshness, t] and *every* verdict in that window was true: a false
  keeps the veto for ``freshness`` seconds whatever true verdicts arrive beside it, and a source
  silent for ``freshness`` seconds is stale, an error verdict that vetoes too;
- before its first verdict it is not judged (vetoes); a message that is no verdict
  (``{"value": 3}``) is an error verdict, which vetoes for ``freshness`` seconds like a false;
- ``check`` (the platform's, over MQTT with ``RASM_ACTION_KEY``: the signature and binding)
  refuses messages the source did not send: they are counted and logged, never verdicts;
  over ROS 2 the transport delivers only the declared publisher's messages, and ``alive``
  says whether that node is still in the ROS graph: while it is not, the source is in error.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from rasm.logs import RepeatedLogs
from rasm.platform.manifest import ExternalVerdict
from rasm.properties.monitor import Verdict
from rasm.times import format_seconds

__all__ = ["ExternalVerdicts", "MessageCheck"]

_log = logging.getLogger("rasm.platform")

EMPTY = "std_msgs/msg/Empty"

MessageCheck = Callable[[str, Any], "str | None"]
"""``check(source name, payload)``: why the message is not the source's own, or None."""


@dataclass
class _Heard:
    """What a JSON or Bool source said within reach of its freshness window."""

    last: float = -math.inf  # when its latest verdict came
    bad: float = -math.inf  # when its latest false (or non-verdict) came
    bad_why: str | None = None  # the error of that one, if it was no verdict


class ExternalVerdicts:
    """The external verdict sources of an app, as one monitor of the Trustworthiness Checker.

    :meth:`receive` turns one message into a verdict; :meth:`step`, called on every loop
    record like any monitor's (and at :meth:`next_change`), gives the verdicts that time alone
    decides: a false leaving its window, a source going stale, an Empty source's hold running
    out, a publisher leaving the graph. Its properties are the sources' names.
    """

    def __init__(
        self,
        sources: Mapping[str, ExternalVerdict],
        *,
        check: MessageCheck | None = None,
        alive: Callable[[str], bool] | None = None,
        logs: RepeatedLogs | None = None,
    ) -> None:
        self.sources = dict(sources)
        self.check = check
        self.alive = alive
        self.logs = logs if logs is not None else RepeatedLogs()
        self.refused: Counter[str] = Counter()  # messages not the source's own, by source
        self._received = dict.fromkeys(self.sources, 0)
        self._heard = {name: _Heard() for name, src in self.sources.items() if src.type != EMPTY}
        # Empty sources: when their current veto ends (-inf: none reported yet)
        self._vetoed_until = {
            name: -math.inf for name, src in self.sources.items() if src.type == EMPTY
        }
        # each source's last verdict handed out, as (value, error): step() reports changes
        self._said: dict[str, tuple[bool, str | None]] = {}
        self._index = 0

    @property
    def properties(self) -> list[str]:
        return list(self.sources)

    def receive(self, name: str, payload: Any, time: float) -> Verdict | None:
        """The verdict of one message of source ``name`` received at ``time``; None when
        ``check`` refuses the message (counted in :attr:`refused`, logged)."""
        source = self.sources[name]
        if self.check is not None:
            why = self.check(name, payload)
            if why is not None:
                self.refused[name] += 1
                self.logs.log(
                    _log, logging.WARNING,
                    f"external verdict on {source.topic} refused: {why.split(':')[0]}",
                    "external verdict on %s refused (not counted): %s", source.topic, why,
                )
                return None
        self._received[name] += 1
        if source.type == EMPTY:
            self._vetoed_until[name] = time + source.hold
        else:
            value = payload.get("data") if source.type else _json_value(payload)
            heard = self._heard[name]
            heard.last = time
            if value is not True:
                heard.bad = time
                heard.bad_why = None if value is False else (
                    f"{source.topic} sent {_abridged(payload)}, not a verdict (true or false)"
                )
        return self._verdict(name, time)

    def step(self, time: float, values: Mapping[str, object]) -> list[Verdict]:
        """The sources whose verdict changed by ``time`` alone (and the Empty sources that
        never reported a violation: they hold from the start)."""
        decided = []
        for name in self.sources:
            if self._received[name] or name in self._vetoed_until:
                judged = self._judge(name, time)
                if self._said.get(name) != judged:
                    decided.append(self._verdict(name, time))
        return decided

    def finish(self) -> list[Verdict]:
        return []

    def next_change(self, time: float) -> float | None:
        """The earliest time after ``time`` at which a verdict may change with no message: a
        false leaving its window, a source going stale, an Empty source's hold ending."""
        times = [until for until in self._vetoed_until.values() if until > time]
        for name, heard in self._heard.items():
            freshness = self.sources[name].freshness
            times += [t for t in (heard.last + freshness, heard.bad + freshness) if t > time]
        return min(times, default=None)

    def missing(self, name: str) -> tuple[str, ...]:
        """What source ``name`` waits for: its first message (an Empty source waits for
        nothing)."""
        source = self.sources.get(name)
        if source is None or source.type == EMPTY or self._received[name]:
            return ()
        return (f"a verdict on {source.topic}",)

    def _verdict(self, name: str, time: float) -> Verdict:
        value, error = self._said[name] = self._judge(name, time)
        self._index += 1
        return Verdict(name, self._index - 1, time, value, error)

    def _judge(self, name: str, time: float) -> tuple[bool, str | None]:
        """Source ``name``'s verdict at ``time``: (value, error)."""
        source = self.sources[name]
        if source.publisher is not None and self.alive is not None and not self.alive(
            source.publisher
        ):
            return False, f"its publisher {source.publisher} is not in the ROS graph"
        if source.type == EMPTY:
            return time >= self._vetoed_until[name], None
        heard = self._heard[name]
        if time >= heard.last + source.freshness:
            return False, (
                f"stale: no verdict on {source.topic} for {format_seconds(source.freshness)} "
                f"s (the last at t={format_seconds(heard.last)})"
            )
        if time < heard.bad + source.freshness:
            return False, heard.bad_why
        return True, None


def _json_value(payload: Any) -> Any:
    return payload.get("value") if isinstance(payload, Mapping) else None


def _abridged(payload: Any, limit: int = 200) -> str:
    text = repr(payload)
    return text if len(text) <= limit else f"{text[:limit]}… ({len(text)} characters)"
