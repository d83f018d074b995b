"""Telegraf: managed-system data into knowledge, by the manifest's routing table."""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Callable
from typing import Any

from rasm.errors import Misfit
from rasm.platform.block import Block
from rasm.platform.manifest import Probe, Signal
from rasm.platform.protocols import Register
from rasm.values import fit

__all__ = ["Telegraf"]

_log = logging.getLogger("rasm.telegraf")

"""Stores one message's values, all at one time: ``register(values, time)``."""


class _Route:
    """One probe: its signals, how they are read out of a message, how it is timed."""

    def __init__(self, probe: Probe) -> None:
        self.signals = probe.signals
        self.header_stamp = probe.stamp == "header"
        self.reader = None
        if probe.type:
            from rasm.platform.messages import MessageReader

            self.reader = MessageReader(probe)

    def values(self, payload: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
        """The signals' raw values in ``payload`` and the signals it lacks a field for."""
        if self.reader is not None:
            return self.reader.read(payload)
        return {key: payload[key] for key in self.signals if key in payload}, []


class Telegraf(Block):
    """Telegraf (tg): managed-system data into knowledge, by the manifest's routing table.

    Each value is checked against its signal's declared type and range; bad data is logged and
    counted, never stored. A probe with a ROS 2 type has its signals read by field path; one
    with ``stamp: header`` is timed by its messages' ``header.stamp``, put on the platform's
    timeline by ``timeline`` (the stamp in integer nanoseconds to seconds on the timeline;
    never later than the message arrived). Like knowledge
    registration, digesting a message does not step the block's chart: only the block's mode
    decides whether it is digested.
    """

    chart_name = "telegraf"
    short_name = "tg"

    def __init__(
        self,
        probes: list[Probe],
        register: Register,
        *,
        timeline: Callable[[int], float] = lambda stamp: stamp / 10**9,
        **kw: Any,
    ) -> None:
        self.routes: dict[str, _Route] = {p.topic: _Route(p) for p in probes}
        self.register = register
        self.timeline = timeline
        self.digested = 0
        self.rejected: Counter[str] = Counter()
        super().__init__(**kw)

    def digest(self, topic: str, payload: Any, time: float) -> dict[str, Any]:
        """Route one message received at ``time``; returns the values stored (an empty dict
        if nothing was)."""
        if self.mode != "initialized":
            self.rejected["not running"] += 1
            return {}
        route = self.routes.get(topic)
        if route is None or not isinstance(payload, dict):
            self.rejected["unroutable"] += 1
            return {}
        if route.header_stamp:
            from rasm.platform.messages import header_stamp

            stamp = header_stamp(payload)
            if stamp is None:
                self._refuse(topic, "header", "no header.stamp", "no header.stamp")
                return {}
            time = min(self.timeline(stamp), time)
        raw, missing = route.values(payload)
        for key in missing:
            self._refuse(topic, key, "no such field in this message", "no such field")
        values: dict[str, Any] = {}
        for key, value in raw.items():
            signal: Signal = route.signals[key]
            try:
                values[key] = fit(
                    value,
                    signal.type,
                    minimum=signal.minimum,
                    maximum=signal.maximum,
                    finite=True,
                )
            except Misfit as misfit:
                self._refuse(topic, key, misfit.reason, str(misfit))
        if values:
            self.register(values, time)
            self.digested += 1
        return values

    def _refuse(self, topic: str, key: str, reason: str, detail: str) -> None:
        self.rejected[reason] += 1
        self.logs.log(
            _log,
            logging.WARNING,
            f"{topic}: {key} rejected: {reason}",
            "%s: %s rejected: %s",
            topic,
            key,
            detail,
        )
