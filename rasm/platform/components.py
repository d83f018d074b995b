"""What user components see and return: the stage context, anomalies, plans and actions.

A user component is a plain class with one method per stage it implements, each taking a
:class:`StageContext`::

    class Analyse:
        def analyse(self, ctx):
            if ctx.knowledge.read_knowledge("temperature") > 30:
                return Anomaly("too hot")

Return values are forgiving (a dict for a plan, ``True`` for an anomaly) but checked: anything
else fails the stage with an explanation, and no action comes out of a failed stage.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from rasm.errors import PlatformError
from rasm.loop import reserved_key

if TYPE_CHECKING:
    from rasm.knowledge.base import KnowledgeBase

__all__ = [
    "Action",
    "Anomaly",
    "Plan",
    "StageContext",
    "StageError",
    "as_actions",
    "as_anomaly",
    "as_plan",
    "as_signals",
    "as_verdict",
    "describe_failure",
    "missing_stage_method",
]


def describe_failure(exc: BaseException | None) -> str:
    """``Type: message`` of an exception from user code, whose ``__str__`` may itself fail."""
    try:
        text = str(exc)
    except Exception:
        text = "<str() of the exception failed>"
    return f"{type(exc).__name__}: {text}"


def missing_stage_method(stage: str, component: object) -> str | None:
    """Why ``component`` cannot serve ``stage`` (it has no ``stage(ctx)`` method), or None."""
    if callable(getattr(component, stage, None)):
        return None
    return f"{type(component).__name__} has no {stage}(ctx) method"


class StageError(PlatformError):
    """A stage's user code raised or returned something unusable."""


@dataclass(frozen=True)
class Anomaly:
    """What Analyse found: a short reason and any data the planner needs."""

    reason: str = "anomaly"
    data: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Plan:
    """A candidate adaptation: values for the rule variables (and anything else Execute needs)."""

    values: dict[str, Any]
    id: str = ""
    explanation: str = ""

    def __getitem__(self, key: str) -> Any:
        return self.values[key]

    def get(self, key: str, default: Any = None) -> Any:
        return self.values.get(key, default)


@dataclass(frozen=True)
class Action:
    """One command for one effector, produced by Execute from an accepted plan."""

    effector: str
    payload: dict[str, Any]
    plan: str = ""
    kind: str = "adaptation"  # or "diagnosis" (the RoboSAPIENS performDiagnosis)


@dataclass
class StageContext:
    """Everything a stage may read: knowledge, time, and what the earlier stages decided."""

    knowledge: KnowledgeBase
    time: float
    iteration: int
    anomaly: Anomaly | None = None
    plan: Plan | None = None
    rejections: list[tuple[Plan, list[str], str]] = field(default_factory=list)
    log: Any = None


def as_signals(value: object) -> dict[str, Any]:
    """Monitor's result: derived signals to register (a dict), or nothing."""
    if value is None:
        return {}
    if not isinstance(value, dict) or not all(isinstance(key, str) for key in value):
        raise StageError(
            f"monitor must return a dict of signals or None, not {type(value).__name__}"
        )
    for key in sorted(value):
        if (reason := reserved_key(key)) is not None:
            raise StageError(f"monitor returned {key!r}, {reason}: give the signal another name")
    return value


def as_anomaly(value: object) -> Anomaly | None:
    """Analyse's result: an :class:`Anomaly`, ``True``/a reason string, or falsy for none."""
    if value is None or value is False:
        return None
    if value is True:
        return Anomaly()
    if isinstance(value, Anomaly):
        if not isinstance(value.data, dict):
            raise StageError(
                f"analyse: Anomaly data must be a dict, not {type(value.data).__name__}"
            )
        return value if isinstance(value.reason, str) else Anomaly(str(value.reason), value.data)
    if isinstance(value, str):
        return Anomaly(value)
    if isinstance(value, dict):
        return Anomaly(str(value.get("reason", "anomaly")), dict(value))
    raise StageError(
        f"analyse must return an Anomaly, a bool, a reason or None, not {type(value).__name__}"
    )


def as_plan(value: object, plan_id: str) -> Plan | None:
    """Plan's result: a :class:`Plan` or a dict of plan values, or None for no plan."""
    if value is None:
        return None
    if isinstance(value, Plan):
        if not isinstance(value.values, dict) or not all(isinstance(k, str) for k in value.values):
            raise StageError(
                f"plan: Plan values must be a dict with str keys, not {type(value.values).__name__}"
            )
        explanation = value.explanation if isinstance(value.explanation, str) else str(
            value.explanation
        )
        return Plan(dict(value.values), plan_id, explanation)
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return Plan(dict(value), plan_id)
    raise StageError(
        f"plan must return a Plan, a dict of plan values or None, not {type(value).__name__}"
    )


def as_verdict(value: object) -> tuple[bool, str]:
    """Legitimate's own opinion: ``True``/``None`` to accept, ``False`` or ``(False, why)``."""
    if value is None or value is True:
        return True, ""
    if value is False:
        return False, "rejected by the application's legitimate stage"
    if isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], bool):
        return value[0], str(value[1])
    raise StageError(
        f"legitimate must return a bool, (bool, reason) or None, not {type(value).__name__}"
    )


def as_actions(value: object, plan_id: str) -> list[Action]:
    """Execute's result: an :class:`Action`, a list of them, or ``{effector: payload}``."""
    if value is None:
        return []
    items = value if isinstance(value, list) else [value]
    out: list[Action] = []
    for item in items:
        if isinstance(item, Action):
            if not isinstance(item.payload, dict):
                raise StageError(
                    f"execute: the payload for {item.effector!r} must be a dict, "
                    f"not {type(item.payload).__name__}"
                )
            out.append(Action(item.effector, dict(item.payload), plan_id, item.kind))
        elif isinstance(item, dict):
            for effector, payload in item.items():
                if not isinstance(payload, dict):
                    raise StageError(f"execute: the payload for {effector!r} must be a dict")
                out.append(Action(str(effector), dict(payload), plan_id))
        else:
            raise StageError(
                f"execute must return Actions or {{effector: payload}}, not {type(item).__name__}"
            )
    return out
