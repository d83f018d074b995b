"""Trustworthiness Manager: whether an action may go out."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from rasm.platform.block import Block
from rasm.platform.components import Action, Plan
from rasm.properties.monitor import Verdict

__all__ = ["TrustworthinessManager"]


class TrustworthinessManager(Block):
    """Trustworthiness Manager (tm): ``check_trustworthiness`` of an action (seed §6.4.4).

    An action is trustworthy when its plan was accepted by the Legitimate stage (the loop hands
    over the accepted plans), the rules still accept the plan now, and the Trustworthiness
    Checker vouches for every *veto* property: its latest verdict holds. A veto property whose
    latest verdict is violated, in error or inconclusive, or that has no verdict yet (still in
    warm-up, or a signal it reads never had a value), vetoes the action: fail closed.
    """

    chart_name = "trustworthiness_manager"
    short_name = "tm"

    def __init__(
        self,
        *,
        rules: list[Any],
        veto_properties: tuple[str, ...],
        verdicts: Callable[[], Mapping[str, Verdict]],
        context: Callable[[], dict[str, Any]],
        waiting_for: Callable[[str], tuple[str, ...]] = lambda name: (),
        **kw: Any,
    ) -> None:
        self.rules = rules
        self.veto_properties = veto_properties
        self.verdicts = verdicts  # the latest verdict of each property
        self.waiting_for = waiting_for  # the signals a property not judged yet waits for
        self.context_of = context
        self.accepted_plans: dict[str, Plan] = {}
        self._evidence: tuple[Action, Plan | None] | None = None
        self._verdict: tuple[bool, str] = (False, "not checked")
        super().__init__(**kw)

    def check_trustworthiness(self, action: Action) -> tuple[bool, str]:
        """Return (trustworthy, explanation); fail closed when the block is not running."""
        if self.mode != "initialized":
            return False, f"trustworthiness manager is {self.mode}"
        self._evidence = (action, self.accepted_plans.get(action.plan))
        self._verdict = (False, "check did not complete in time")
        self.send("check_requested")
        return self._verdict

    def on_enter_gathering_evidence(self) -> None:
        self.post("evidence_gathered")

    def on_enter_evaluating(self) -> None:
        action, plan = self._evidence or (None, None)
        ok, why = self._evaluate(action, plan)
        self._verdict = (ok, why)
        self.post("trustworthy" if ok else "untrustworthy")

    def _evaluate(self, action: Action | None, plan: Plan | None) -> tuple[bool, str]:
        if action is None or plan is None:
            return False, "the action's plan was never accepted by the Legitimate stage"
        context = self.context_of()
        for rules in self.rules:
            decision = rules.evaluate(plan.values, context)
            if not decision.accepted:
                return False, f"rules no longer accept the plan: {decision.explanation()}"
            # Execute may put other values in the action than the plan had: the rules judge
            # what is actually sent (payload values win over the plan's of the same name)
            sent = {**plan.values, **action.payload}
            if sent != plan.values:
                decision = rules.evaluate(sent, context)
                if not decision.accepted:
                    return False, f"rules do not accept the action: {decision.explanation()}"
        verdicts = self.verdicts()
        vetoes = [self._veto(name, verdicts.get(name)) for name in self.veto_properties]
        vetoes = [why for why in vetoes if why is not None]
        if vetoes:
            return False, "; ".join(vetoes)
        if self.veto_properties:
            return True, "plan accepted by Legitimate, rules hold, every veto property holds"
        return True, "plan accepted by Legitimate, rules hold"

    def _veto(self, name: str, verdict: Verdict | None) -> str | None:
        """Why veto property ``name`` stops the action, or None when it holds."""
        if verdict is None:
            waits = self.waiting_for(name)
            if waits:
                return f"veto property {name} not judged yet: no value for {', '.join(waits)}"
            return f"veto property {name} not judged yet: no verdict decided so far"
        if verdict.error is not None:
            return f"veto property {name} in error at t={verdict.time:g}: {verdict.error}"
        if verdict.value is False:
            return f"veto property {name} violated at t={verdict.time:g}"
        if verdict.value is None:
            return f"veto property {name} inconclusive at t={verdict.time:g}"
        return None
