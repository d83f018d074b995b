"""Checking properties on a twin's predictions: what Legitimate asks before accepting a plan."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from math import inf
from typing import Any

from rasm.properties import Monitor, load_specification
from rasm.times import format_seconds

__all__ = ["PredictionChecker", "predicted_violations", "worse_than_baseline"]


class PredictionChecker:
    """The properties of one or more ``.rv`` texts, ready to judge predicted records.

    Each call checks a fresh monitor (a prediction is a trace of its own): a property is
    reported when it is false on at least one predicted record. Properties that read signals a
    prediction never sets are not judged and never reported; a
    bounded-future property whose window outlasts the prediction is inconclusive there, and
    inconclusive is not a violation.
    """

    def __init__(self, texts: Iterable[tuple[str, str]]) -> None:
        """``texts``: ``(source name, property-file text)`` pairs."""
        self.specifications = [load_specification(text, source=src) for src, text in texts]

    def violations(self, records: Iterable[tuple[float, Mapping[str, Any]]]) -> list[str]:
        """The names of the properties the records break, in file order, each once."""
        return list(self.first_violations(records))

    def first_violations(
        self, records: Iterable[tuple[float, Mapping[str, Any]]]
    ) -> dict[str, float]:
        """Each broken property's name and the time of its first violation, in file order."""
        records = list(records)
        first: dict[str, float] = {}
        for spec in self.specifications:
            monitor = Monitor(spec)
            verdicts = []
            for time, values in records:
                verdicts += monitor.step(time, values)
            verdicts += monitor.finish()
            for verdict in verdicts:
                if verdict.value is False:
                    first[verdict.property] = min(verdict.time, first.get(verdict.property, inf))
        return first


def predicted_violations(
    twin: Any,
    checker: PredictionChecker,
    plan: Mapping[str, Any],
    state: Mapping[str, Any],
    horizon: float,
    dt: float,
) -> list[str]:
    """``twin.simulate(plan, state, horizon, dt)`` checked: the properties it predicts broken."""
    return checker.violations(twin.simulate(dict(plan), dict(state), horizon, dt))


def worse_than_baseline(
    twin: Any,
    checker: PredictionChecker,
    plan: Mapping[str, Any],
    state: Mapping[str, Any],
    horizon: float,
    dt: float,
    baseline: Mapping[str, Any] | None = None,
) -> dict[str, str]:
    """The properties ``plan`` is predicted to break *where doing nothing would not*.

    ``baseline`` is the plan that "doing nothing" stands for (default ``{}``: the settings the
    twin reads from ``state``). A property counts against ``plan`` when its prediction breaks
    it and the baseline's does not, or breaks it earlier than the baseline's. When every option
    leaves the band (the Hotbox with its lid open on a light content) an absolute check rejects
    the very plan that helps most; this one rejects only plans that make things worse.
    Returns ``{property: why}``.
    """
    ours = checker.first_violations(twin.simulate(dict(plan), dict(state), horizon, dt))
    if not ours:
        return {}
    theirs = checker.first_violations(twin.simulate(dict(baseline or {}), dict(state), horizon, dt))
    worse = {}
    for name, when in ours.items():
        if name not in theirs:
            worse[name] = (
                f"the twin predicts {name} is violated {format_seconds(when)} s after the plan"
            )
        elif when < theirs[name]:
            worse[name] = (
                f"the twin predicts {name} is violated {format_seconds(when)} s after the plan, "
                f"{format_seconds(theirs[name] - when)} s earlier than without it"
            )
    return worse
