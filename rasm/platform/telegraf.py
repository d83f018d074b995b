"""Telegraf: managed-system data into knowledge, by the manifest's routing table."""

from __future__ import annotations

import logging
import math
import sys
from collections import Counter
from collections.abc import Callable
from typing import Any

from rasm.knowledge.base import EXACT_CLASS
from rasm.platform.block import Block
from rasm.platform.manifest import Probe, Signal

__all__ = ["Telegraf"]


_telegraf_log = logging.getLogger("rasm.telegraf")

_TYPES: dict[str, tuple[type, ...]] = {
    "float": (float, int),
    "int": (int,),
    "bool": (bool,),
    "str": (str,),
}


class Telegraf(Block):
    """Telegraf (tg): managed-system data into knowledge, by the manifest's routing table.

    Each value is checked against its signal's declared type and range; bad data is logged and
    counted, never stored.
    """

    __slots__ = ("routes", "_plans", "register", "digested", "rejected")  # as Block's

    chart_name = "telegraf"
    short_name = "tg"

    def __init__(
        self, probes: list[Probe], register: Callable[[dict[str, Any], float], Any], **kw: Any
    ) -> None:
        self.routes: dict[str, dict[str, Signal]] = {p.topic: p.signals for p in probes}
        # per topic, what digest() tests each field with (built once: probes are frozen)
        self._plans = {topic: _plan(signals) for topic, signals in self.routes.items()}
        self.register = register
        self.digested = 0
        self.rejected: Counter[str] = Counter()
        super().__init__(**kw)

    def digest(self, topic: str, payload: Any, time: float) -> dict[str, Any]:
        """Route one message; returns the values stored (an empty dict if nothing was)."""
        if self._mode != "initialized":
            self.rejected["not running"] += 1
            return {}
        plans = self._plans
        plan = plans[topic] if topic in plans else None  # (no .get method call)
        if plan is None or not isinstance(payload, dict):
            self.rejected["unroutable"] += 1
            return {}
        values: dict[str, Any] = {}
        for key, signal, exact, low, high in plan:
            if key not in payload:
                continue
            value = payload[key]
            cls = type(value)
            if cls is not exact:  # (no attribute lookup for the common value)
                cls = value.__class__  # what an object says it is decides, as it always did
            # the common good value in one test: its exact declared class and in range, which
            # for a float is finite too (see _plan)
            if cls is exact and (low is None or low <= value <= high):
                values[key] = value
                continue
            problem = _check_value(signal, value)
            if problem:
                self.rejected[problem] += 1
                self.logs.log(
                    _telegraf_log,
                    logging.WARNING,
                    f"{topic}: {key} rejected: {problem}",
                    "%s: %s=%r rejected: %s",
                    topic,
                    key,
                    value,
                    problem,
                )
                continue
            values[key] = float(value) if signal.type == "float" else value
        if values:
            self.register(values, time)
            self.digested += 1
        return values


# the range of an int without declared bounds in the fast test; larger ones take the full check
_INT_RANGE = 1 << 1000
_FLOAT_MAX = sys.float_info.max


def _plan(signals: dict[str, Signal]) -> tuple[tuple[str, Signal, Any, Any, Any], ...]:
    """``(field, signal, exact class, low, high)`` per field: the fast test of Telegraf.digest.

    ``low`` is None when the class alone decides (bool, str); numbers need ``low <= value <=
    high``, with the declared bounds or unbounded ones. A float's bounds are within the finite
    floats (an infinite or missing bound is the largest float), so the range test also refuses
    inf, -inf and nan (a nan bound refuses everything): they take the full check, as they did.
    """
    plan = []
    for key, signal in signals.items():
        # an int for a float signal is converted by the full check: only exact classes skip it
        exact = EXACT_CLASS.get(signal.type)
        low, high = signal.minimum, signal.maximum
        if signal.type == "float":
            low = -_FLOAT_MAX if low is None or low < -_FLOAT_MAX else low
            high = _FLOAT_MAX if high is None or high > _FLOAT_MAX else high
        elif signal.type == "int":  # ints are finite; beyond the sentinel the full check fails
            low = -_INT_RANGE if low is None else low
            high = _INT_RANGE if high is None else high
        else:
            low = high = None
        plan.append((key, signal, exact, low, high))
    return tuple(plan)


def _check_value(signal: Signal, value: Any) -> str | None:
    if signal.type == "json":
        return None
    allowed = _TYPES[signal.type]
    if not isinstance(value, allowed) or (signal.type != "bool" and isinstance(value, bool)):
        return f"expected {signal.type}, got {type(value).__name__}"
    if signal.type in ("float", "int"):
        if not math.isfinite(value):
            return "not a finite number"
        if signal.minimum is not None and value < signal.minimum:
            return f"below the declared minimum {signal.minimum}"
        if signal.maximum is not None and value > signal.maximum:
            return f"above the declared maximum {signal.maximum}"
    return None
