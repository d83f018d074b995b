"""Telegraf: managed-system data into knowledge, by the manifest's routing table."""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Callable
from typing import Any

from rasm.platform.block import Block
from rasm.platform.manifest import Probe, Signal

__all__ = ["Telegraf"]

_log = logging.getLogger("rasm.telegraf")

_TYPES: dict[str, tuple[type, ...]] = {
    "float": (float, int),
    "int": (int,),
    "bool": (bool,),
    "str": (str,),
}

Register = Callable[[dict[str, Any], float], Any]
"""Stores one message's values, all at one time: ``register(values, time)``."""


class Telegraf(Block):
    """Telegraf (tg): managed-system data into knowledge, by the manifest's routing table.

    Each value is checked against its signal's declared type and range; bad data is logged and
    counted, never stored. Like knowledge registration, digesting a message does not step the
    block's chart: only the block's mode decides whether it is digested.
    """

    chart_name = "telegraf"
    short_name = "tg"

    def __init__(self, probes: list[Probe], register: Register, **kw: Any) -> None:
        self.routes: dict[str, dict[str, Signal]] = {p.topic: p.signals for p in probes}
        self.register = register
        self.digested = 0
        self.rejected: Counter[str] = Counter()
        super().__init__(**kw)

    def digest(self, topic: str, payload: Any, time: float) -> dict[str, Any]:
        """Route one message; returns the values stored (an empty dict if nothing was)."""
        if self.mode != "initialized":
            self.rejected["not running"] += 1
            return {}
        signals = self.routes.get(topic)
        if signals is None or not isinstance(payload, dict):
            self.rejected["unroutable"] += 1
            return {}
        values: dict[str, Any] = {}
        for key, signal in signals.items():
            if key not in payload:
                continue
            value = payload[key]
            problem = _check_value(signal, value)
            if problem:
                self.rejected[problem] += 1
                self.logs.log(
                    _log,
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
