"""Adaptation Manager: an action checked by the Trustworthiness Manager, then registered with
the Trustworthiness Checker."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from rasm.platform.action_outcome import ActionOutcome
from rasm.platform.block import Block
from rasm.platform.components import Action
from rasm.platform.protocols import ActionGate, Hold, TrustJudge

__all__ = ["AdaptationManager"]


class AdaptationManager(Block):
    """Adaptation Manager (am): ``perform_adaptation`` / ``perform_diagnosis``.

    Has the ``judge`` (the Trustworthiness Manager) check the action; when trustworthy,
    registers it with the ``gate`` (the Trustworthiness Checker), which alone hands it to the
    effector. Otherwise the action is dropped. While the ``hold`` (the fallback switch's) holds
    the effectors, only fallback actions and corrective ones go on.
    """

    chart_name = "adaptation_manager"
    short_name = "am"

    def __init__(
        self, judge: TrustJudge, gate: ActionGate, *, hold: Hold | None = None, **kw: Any
    ) -> None:
        self.judge = judge
        self.gate = gate
        self.hold = hold
        super().__init__(**kw)

    def perform_adaptation(self, action: Action) -> ActionOutcome:
        """Check and register ``action``: what became of it."""
        return self.request(
            "action_requested", action, "the adaptation did not complete in time"
        )

    def perform_diagnosis(self, action: Action) -> ActionOutcome:
        return self.perform_adaptation(
            Action(action.effector, action.payload, action.plan, "diagnosis")
        )

    def on_enter_checking_trustworthiness(self) -> None:
        action = self.action
        assert action is not None
        held = self.hold.holds(action) if self.hold is not None else None
        if held is not None and not self.hold.correctable():
            self.answer(ActionOutcome(False, held), "untrustworthy")
            return
        judged = self.judge.check_trustworthiness(action)
        if held is not None and not (judged.trusted and judged.corrective):
            judged = ActionOutcome(False, held)  # only a corrective action passes a hold of vetoes
        self.answer(judged, "trustworthy" if judged.trusted else "untrustworthy")

    def on_enter_registering(self) -> None:
        assert self.action is not None
        registered = self.gate.register_action(self.action)
        # the checker's word on sending, with what the judge found
        outcome = replace(registered, trusted=self._answer.trusted,
                          corrective=self._answer.corrective)
        self.answer(outcome, "registered" if outcome.sent else "registration_refused")

    def on_enter_dropping(self) -> None:
        self.post("dropped")
