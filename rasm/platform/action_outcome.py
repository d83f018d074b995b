"""What became of an action: one :class:`ActionOutcome`, handed back down the path of an action
(Trustworthiness Checker → Trustworthiness Manager → Adaptation Manager → whoever asked), and
:func:`perform_and_trace`, the one way the loop and the fallback switch send an action and write
what became of it in the trace."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rasm.platform.components import Action

__all__ = ["ActionOutcome", "Emit", "perform_and_trace"]

Emit = Callable[[float, dict[str, Any]], object]
"""Writes one trace record: ``emit(time, record)``."""


@dataclass(frozen=True)
class ActionOutcome:
    """An action's fate: ``sent`` to its effector or not, and why.

    ``trusted`` says the Trustworthiness Manager found it trustworthy (an action may be trusted
    and still not sent: the checker refused it), ``corrective`` that it was trusted as a
    corrective action under a veto (docs/runtime.md).
    """

    sent: bool
    why: str
    trusted: bool = False
    corrective: bool = False


def perform_and_trace(
    perform: Callable[[Action], ActionOutcome],
    action: Action,
    emit: Emit,
    now: Callable[[], float],
) -> ActionOutcome:
    """Send ``action`` down the path of an action (``perform``: the Adaptation Manager's
    ``perform_adaptation``) and trace it: ``trusted`` when it was, then ``executed`` or
    ``dropped`` with the reason, each at the time ``now()`` says once the action's path is done."""
    outcome = perform(action)
    if outcome.trusted:
        emit(now(), {"trusted": True, "plan": action.plan})
    event = "executed" if outcome.sent else "dropped"
    emit(now(), {event: True, "plan": action.plan, "explanation": outcome.why})
    return outcome
