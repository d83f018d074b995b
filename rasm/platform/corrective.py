"""Corrective actions under a veto: does the twin predict a plan makes a violated property hold
again sooner than doing nothing?

While a veto property is violated, ``trustworthiness: {corrective: true}`` lets an action through
when the digital twin predicts that its plan brings every violated veto property back to true
sooner than keeping the current settings. The same prediction the Legitimate stage's twin check
makes, read the other way: not "does the plan break a property", but "when does the property
hold again". A property the prediction cannot judge is not corrected (fail closed).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from rasm.errors import SourceError, SourceErrors, is_interrupt
from rasm.platform.manifest import AppManifest, manifest_location
from rasm.properties import Monitor, load_specification
from rasm.times import format_seconds

__all__ = ["CorrectiveCheck", "corrective_check", "recovery_times"]


def recovery_times(
    specifications: Sequence[Any],
    records: Iterable[tuple[float, Mapping[str, Any]]],
    names: Iterable[str],
) -> dict[str, float | None]:
    """Per property of ``names``: the time of the first predicted record after which it holds
    on every record (the prediction's first record if it never fails there; ``inf`` if it is
    false on the last), or None when the prediction never judges it."""
    records = list(records)
    wanted = set(names)
    verdicts: dict[str, list[tuple[float, bool | None]]] = {name: [] for name in wanted}
    for spec in specifications:
        if wanted.isdisjoint(prop.name for prop in spec.properties):
            continue
        monitor = Monitor(spec)
        found = []
        for time, values in records:
            found += monitor.step(time, values)
        found += monitor.finish()
        for verdict in found:
            if verdict.property in wanted:
                verdicts[verdict.property].append((verdict.time, verdict.value))
    result: dict[str, float | None] = {}
    for name, judged in verdicts.items():
        judged.sort(key=lambda tv: tv[0])
        decided = [(t, v) for t, v in judged if v is not None]
        if not decided:
            result[name] = None
            continue
        false_times = [t for t, v in decided if v is False]
        if not false_times:
            result[name] = decided[0][0]
            continue
        after = [t for t, v in decided if v is True and t > false_times[-1]]
        result[name] = after[0] if after else math.inf
    return result


class CorrectiveCheck:
    """``check(plan values, context, violated names)``: why the plan is corrective, or None."""

    def __init__(
        self, twin: Any, texts: Iterable[tuple[str, str]], horizon: float, dt: float
    ) -> None:
        self.twin = twin
        self.specifications = [load_specification(text, source=src) for src, text in texts]
        self.properties = {prop.name for spec in self.specifications for prop in spec.properties}
        self.horizon = horizon
        self.dt = dt

    def check(
        self, plan: Mapping[str, Any], context: Mapping[str, Any], violated: Sequence[str]
    ) -> str | None:
        if not violated or not set(violated) <= self.properties:
            return None  # a property the twin's predictions do not check: no vouching for it
        try:
            ours = recovery_times(
                self.specifications,
                self.twin.simulate(dict(plan), dict(context), self.horizon, self.dt),
                violated,
            )
            theirs = recovery_times(
                self.specifications,
                self.twin.simulate({}, dict(context), self.horizon, self.dt),
                violated,
            )
        except BaseException as exc:  # a twin that cannot predict vouches for nothing
            if is_interrupt(exc):
                raise
            return None
        reasons = []
        for name in violated:
            mine, base = ours.get(name), theirs.get(name)
            if mine is None or base is None or not mine < base:
                return None
            without = (
                f"{format_seconds(base)} s" if math.isfinite(base) else "not within the horizon"
            )
            reasons.append(
                f"the twin predicts {name} holds again {format_seconds(mine)} s after the plan "
                f"({without} without it)"
            )
        return "; ".join(reasons)


def corrective_check(m: AppManifest, twin: Any) -> Callable[..., str | None]:
    """``trustworthiness.corrective``: the twin's predictions of the app's properties, or
    an error at its place when the app has no twin to predict with."""
    if twin is None:
        raise SourceErrors([SourceError(
            "corrective actions need a digital twin to predict with (twin: in app.yaml)",
            manifest_location(m, ["trustworthiness", "corrective"]),
        )])
    texts = [(str(p), p.read_text(encoding="utf-8")) for p in m.properties]
    return CorrectiveCheck(twin, texts, m.twin_horizon, m.twin_dt).check
