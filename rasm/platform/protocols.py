"""What the building blocks know of each other: the roles they play for one another, each a small
:class:`typing.Protocol`, the loop's counts they share, and the callables they report through.

No block module imports another (``tests/test_layering.py``): a block names the role it needs
here, and :func:`rasm.platform.assembly.assemble` gives it the block that plays it.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from rasm.platform.action_outcome import ActionOutcome
from rasm.platform.components import Action, Plan
from rasm.platform.manifest import Effector
from rasm.properties.monitor import Verdict

__all__ = [
    "ActionGate",
    "Adapter",
    "CallStarter",
    "Hold",
    "LoopStats",
    "PlanRegistry",
    "Register",
    "StageTimer",
    "TrustJudge",
    "VerdictSource",
    "Vetoes",
]

Register = Callable[[dict[str, Any], float], object]
"""Stores values in knowledge (and traces them): ``register(values, time)``."""


@dataclass
class LoopStats:
    """The loop's counts: kept by the orchestrator, read by the fallback's stage_failures
    trigger and by the summary of ``rasm run``."""

    iterations: int = 0
    anomalies: int = 0
    plans: int = 0
    rejected: int = 0
    accepted: int = 0
    executed: int = 0
    dropped: int = 0
    cancelled: int = 0
    failed_stages: Counter[str] = field(default_factory=Counter)
    timeouts: Counter[str] = field(default_factory=Counter)


class Adapter(Protocol):
    """What performs an action, the one path to the effectors: the Adaptation Manager."""

    def perform_adaptation(self, action: Action) -> ActionOutcome:
        """What became of the action."""


class TrustJudge(Protocol):
    """What decides whether an action is trustworthy: the Trustworthiness Manager."""

    def check_trustworthiness(self, action: Action) -> ActionOutcome:
        """Whether ``action`` is trusted (and as corrective), and why; not sent yet."""


class ActionGate(Protocol):
    """The only path to the effectors: the Trustworthiness Checker."""

    def register_action(self, action: Action) -> ActionOutcome:
        """Whether ``action`` was sent to its effector, and why."""


class CallStarter(Protocol):
    """What starts a service or action effector's call, off the loop: the effector calls
    (:class:`rasm.platform.calls.CallEffectors`)."""

    def start(self, effector: Effector, action: Action, request: dict[str, Any]) -> str:
        """Start the call with ``request`` (its request or goal message); returns at once,
        saying what it started."""


class Hold(Protocol):
    """What may hold the loop's actions back: the fallback switch's hold, while it holds the
    effectors."""

    def holds(self, action: Action) -> str | None:
        """Why ``action`` is held back, or None."""

    def correctable(self) -> bool:
        """Whether a corrective action may pass the hold (only vetoes hold it)."""


class PlanRegistry(Protocol):
    """What holds the plans actions may come from: the Trustworthiness Manager."""

    def accept_plan(self, plan: Plan) -> None:
        """``plan`` passed the Legitimate stage: its actions may be checked."""

    def forget_plan(self, plan_id: str) -> None:
        """No later action may come from plan ``plan_id``."""


class Vetoes(Protocol):
    """What says which veto properties stop actions: the Trustworthiness Manager."""

    def vetoing(self) -> dict[str, str]:
        """The veto properties that stop actions now, each with why."""

    def veto_reason(self, name: str, verdict: Verdict | None) -> str | None:
        """Why ``verdict`` of veto property ``name`` stops actions (None: it vouches)."""


class VerdictSource(Protocol):
    """What vouches for the veto properties: the Trustworthiness Checker."""

    def latest_verdict(self, name: str) -> Verdict | None:
        """The latest verdict of property ``name``, or None before its first."""

    def missing(self, name: str) -> tuple[str, ...]:
        """The signals property ``name`` still waits for."""


class StageTimer(Protocol):
    """What keeps each stage's timing: the State Manager."""

    def record_stage(self, stage: str, start: float, duration: float) -> None:
        """Stage ``stage`` started at ``start`` and took ``duration`` seconds."""
