"""Telegraf: managed-system data into knowledge, by the manifest's routing table."""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Callable
from typing import Any

from rasm.errors import Misfit
from rasm.platform.block import Block
from rasm.platform.manifest import Probe, Signal
from rasm.values import fit

__all__ = ["Telegraf"]

_log = logging.getLogger("rasm.telegraf")

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
            try:
                values[key] = fit(
                    value,
                    signal.type,
                    minimum=signal.minimum,
                    maximum=signal.maximum,
                    finite=True,
                )
            except Misfit as misfit:
                self.rejected[misfit.reason] += 1
                self.logs.log(
                    _log,
                    logging.WARNING,
                    f"{topic}: {key} rejected: {misfit.reason}",
                    "%s: %s rejected: %s",
                    topic,
                    key,
                    misfit,
                )
        if values:
            self.register(values, time)
            self.digested += 1
        return values

