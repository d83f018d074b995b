"""Verdicts of monitors outside rasm, taken in as veto sources.

A monitor running beside the loop (the RoboSAPIENS Trustworthiness Checker over MQTT, a
Copilot/Ogma monitor over ROS 2) publishes its verdicts on a topic; the manifest declares it
under ``trustworthiness.external_verdicts`` and the Trustworthiness Manager then counts it as
a veto property of that name. Three kinds of topic:

- JSON (MQTT, the local bus): ``{"value": true|false}``, the public checker's convention;
- ``std_msgs/msg/Bool``: ``data`` is the verdict;
- ``std_msgs/msg/Empty``: every message is a violation (a Copilot handler fires while its
  condition holds); it vetoes ``hold`` seconds after the last one, and holds otherwise.

Fail closed: a Bool or JSON source vetoes until its first verdict comes; a message that is no
verdict (``{"value": 3}``) is an error verdict, which vetoes too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from rasm.platform.manifest import ExternalVerdict
from rasm.properties.monitor import Verdict

__all__ = ["ExternalVerdicts"]

EMPTY = "std_msgs/msg/Empty"


class ExternalVerdicts:
    """The external verdict sources of an app, as one monitor of the Trustworthiness Checker.

    :meth:`receive` turns one message into a verdict; :meth:`step`, called on every loop
    record like any monitor's, gives the verdicts that time alone decides (an Empty source's
    hold running out). Its properties are the sources' names.
    """

    def __init__(self, sources: Mapping[str, ExternalVerdict]) -> None:
        self.sources = dict(sources)
        self._received = dict.fromkeys(self.sources, 0)
        # Empty sources: when their current veto ends (-inf: none reported yet)
        self._vetoed_until = {
            name: -math.inf for name, src in self.sources.items() if src.type == EMPTY
        }
        self._holding: set[str] = set()  # Empty sources whose latest verdict is true
        self._index = 0

    @property
    def properties(self) -> list[str]:
        return list(self.sources)

    def receive(self, name: str, payload: Any, time: float) -> Verdict:
        """The verdict of one message of source ``name`` received at ``time``."""
        source = self.sources[name]
        self._received[name] += 1
        index = self._next_index()
        if source.type == EMPTY:
            self._vetoed_until[name] = time + source.hold
            self._holding.discard(name)
            return Verdict(name, index, time, False)
        value = payload.get("data") if source.type else _json_value(payload)
        if isinstance(value, bool):
            return Verdict(name, index, time, value)
        why = f"{source.topic} sent {payload!r}, not a verdict (true or false)"
        return Verdict(name, index, time, False, why)

    def step(self, time: float, values: Mapping[str, object]) -> list[Verdict]:
        """The Empty sources whose veto ran out by ``time`` (or that never reported one)."""
        decided = []
        for name, until in self._vetoed_until.items():
            if time >= until and name not in self._holding:
                self._holding.add(name)
                decided.append(Verdict(name, self._next_index(), time, True))
        return decided

    def finish(self) -> list[Verdict]:
        return []

    def missing(self, name: str) -> tuple[str, ...]:
        """What source ``name`` waits for: its first message (an Empty source waits for
        nothing)."""
        source = self.sources.get(name)
        if source is None or source.type == EMPTY or self._received[name]:
            return ()
        return (f"a verdict on {source.topic}",)

    def _next_index(self) -> int:
        self._index += 1
        return self._index - 1


def _json_value(payload: Any) -> Any:
    return payload.get("value") if isinstance(payload, Mapping) else None
