"""Trustworthiness Manager: whether an action may go out."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from rasm.platform.action_outcome import ActionOutcome, Emit
from rasm.platform.block import Block
from rasm.platform.components import Action, Plan
from rasm.platform.protocols import VerdictSource
from rasm.properties.monitor import Verdict
from rasm.times import format_seconds

if TYPE_CHECKING:
    from rasm.rules import RuleSet

__all__ = ["Corrective", "TrustworthinessManager", "verdict_veto_reason"]

# (plan values, context, violated veto properties) -> why the plan is corrective, or None
Corrective = Callable[[dict[str, Any], dict[str, Any], list[str]], "str | None"]


class TrustworthinessManager(Block):
    """Trustworthiness Manager (tm): ``check_trustworthiness`` of an action.

    An action is trustworthy when its plan was accepted by the Legitimate stage (the loop hands
    over the accepted plans with :meth:`accept_plan`), the rules still accept the plan now, and
    the Trustworthiness Checker vouches for every *veto* property: its latest verdict holds. A
    veto property whose latest verdict is violated, in error or inconclusive, or that has no
    verdict yet (still in warm-up, or a signal it reads never had a value), vetoes the action:
    fail closed.
    """

    chart_name = "trustworthiness_manager"
    short_name = "tm"

    def __init__(
        self,
        *,
        rules: list[RuleSet],
        veto_properties: tuple[str, ...],
        checker: VerdictSource,
        context: Callable[[], dict[str, Any]],
        corrective: Corrective | None = None,
        emit: Emit | None = None,
        **kw: Any,
    ) -> None:
        # trustworthiness.corrective: while veto properties are violated, a plan the twin
        # predicts brings them back sooner than doing nothing may still act
        self.corrective = corrective
        self.emit = emit
        self.rules = rules
        self.veto_properties = veto_properties
        self.checker = checker
        self.context_of = context
        self._accepted_plans: dict[str, Plan] = {}
        super().__init__(**kw)

    def accept_plan(self, plan: Plan) -> None:
        """``plan`` passed the Legitimate stage: its actions may be checked."""
        self._accepted_plans[plan.id] = plan

    def forget_plan(self, plan_id: str) -> None:
        """The iteration of plan ``plan_id`` is over: no later action may use it."""
        self._accepted_plans.pop(plan_id, None)

    def check_trustworthiness(self, action: Action) -> ActionOutcome:
        """Whether ``action`` is trusted, and why; fail closed when the block is not running."""
        return self.request("check_requested", action, "check did not complete in time")

    def on_enter_gathering_evidence(self) -> None:
        self.post("evidence_gathered")

    def on_enter_evaluating(self) -> None:
        action = self.action
        plan = self._accepted_plans.get(action.plan) if action is not None else None
        judged = self._evaluate(action, plan)
        self.answer(judged, "trustworthy" if judged.trusted else "untrustworthy")

    def _evaluate(self, action: Action | None, plan: Plan | None) -> ActionOutcome:
        if action is None or plan is None:
            return _refused("the action's plan was never accepted by the Legitimate stage")
        context = self.context_of()
        for rules in self.rules:
            decision = rules.evaluate(plan.values, context)
            if not decision.accepted:
                return _refused(f"rules no longer accept the plan: {decision.explanation()}")
            # Execute may put other values in the action than the plan had: the rules judge
            # what is actually sent (payload values win over the plan's of the same name)
            sent = {**plan.values, **action.payload}
            if sent != plan.values:
                decision = rules.evaluate(sent, context)
                if not decision.accepted:
                    return _refused(f"rules do not accept the action: {decision.explanation()}")
        if action.kind == "fallback":
            # the fallback is what runs while a veto holds: its actions were proved legitimate
            # in every context before the run, and the rules have just accepted them again
            return _trusted("fallback action: rules hold (vetoes do not stop the fallback)")
        vetoes = self.vetoes()
        if vetoes:
            why = self._corrective(plan, context)
            if why is not None:
                return ActionOutcome(False, f"corrective under a veto: {why}", trusted=True,
                                     corrective=True)
            return _refused("; ".join(vetoes))
        if self.veto_properties:
            return _trusted("plan accepted by Legitimate, rules hold, every veto property holds")
        return _trusted("plan accepted by Legitimate, rules hold")

    def _corrective(self, plan: Plan, context: dict[str, Any]) -> str | None:
        """Why ``plan`` may act although veto properties stop actions, or None: every vetoing
        property is violated (not in error, not unjudged) and the twin predicts the plan makes
        each hold again sooner than doing nothing. Traced as a ``corrective`` record."""
        if self.corrective is None:
            return None
        violated = []
        for name in self.veto_properties:
            verdict = self.checker.latest_verdict(name)
            if verdict is None or verdict.error is not None or verdict.value is None:
                return None  # the checker cannot say what is wrong: nothing corrects it
            if verdict.value is False:
                violated.append(name)
        why = self.corrective(dict(plan.values), context, violated)
        if why is not None:
            if self.emit is not None:
                self.emit(
                    self.clock.time, {"corrective": True, "plan": plan.id, "explanation": why}
                )
        return why

    def vetoes(self) -> list[str]:
        """Why each veto property the checker cannot vouch for now stops actions."""
        return list(self.vetoing().values())

    def vetoing(self) -> dict[str, str]:
        """The veto properties the checker cannot vouch for now, each with why it stops
        actions."""
        vetoing = {}
        for name in self.veto_properties:
            why = self.veto_reason(name, self.checker.latest_verdict(name))
            if why is not None:
                vetoing[name] = why
        return vetoing

    def veto_reason(self, name: str, verdict: Verdict | None) -> str | None:
        """Why veto property ``name`` stops actions when ``verdict`` is its latest (None: it
        has none yet), or None when that verdict vouches for it."""
        if verdict is None:
            waits = self.checker.missing(name)
            if waits:
                return f"veto property {name} not judged yet: no value for {', '.join(waits)}"
            return f"veto property {name} not judged yet: no verdict decided so far"
        return verdict_veto_reason(name, verdict)


def verdict_veto_reason(name: str, verdict: Verdict) -> str | None:
    """Why veto property ``name`` stops actions when ``verdict`` is its latest, or None when
    the verdict vouches for it (a verdict alone says so: the calls of service and action
    effectors read it before the Trustworthiness Manager is made)."""
    if verdict.value is True and verdict.error is None:
        return None
    at = format_seconds(verdict.time)
    if verdict.error is not None:
        return f"veto property {name} in error at t={at}: {verdict.error}"
    if verdict.value is False:
        return f"veto property {name} violated at t={at}"
    return f"veto property {name} inconclusive at t={at}"


def _trusted(why: str) -> ActionOutcome:
    return ActionOutcome(False, why, trusted=True)


def _refused(why: str) -> ActionOutcome:
    return ActionOutcome(False, why)
