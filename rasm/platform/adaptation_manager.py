"""Adaptation Manager: an action checked by the Trustworthiness Manager, then registered with
the Trustworthiness Checker."""

from __future__ import annotations

from typing import Any, Protocol

from rasm.platform.block import Block
from rasm.platform.components import Action

__all__ = ["ActionGate", "AdaptationManager", "Hold", "TrustJudge"]


class TrustJudge(Protocol):
    """What decides whether an action is trustworthy: the Trustworthiness Manager."""

    def check_trustworthiness(self, action: Action) -> tuple[bool, str]:
        """(trustworthy, why)."""


class ActionGate(Protocol):
    """The only path to the effectors: the Trustworthiness Checker."""

    def register_action(self, action: Action) -> tuple[bool, str]:
        """(sent to its effector, why)."""


class Hold(Protocol):
    """What may hold the loop's actions back: the fallback switch while it holds the effectors."""

    def holds(self, action: Action) -> str | None:
        """Why ``action`` is held back, or None."""

    def correctable(self) -> bool:
        """Whether a corrective action may pass the hold (only vetoes hold it)."""


class AdaptationManager(Block):
    """Adaptation Manager (am): ``perform_adaptation`` / ``perform_diagnosis``.

    Has the Trustworthiness Manager check the action; when trustworthy, registers it with the
    Trustworthiness Checker, which alone hands it to the effector. Otherwise the action is dropped.
    While the fallback switch (``hold``) holds the effectors, only fallback actions go on.
    """

    chart_name = "adaptation_manager"
    short_name = "am"

    def __init__(self, tm: TrustJudge, tc: ActionGate, **kw: Any) -> None:
        self.tm = tm
        self.tc = tc
        self.hold: Hold | None = None
        self._action: Action | None = None
        self._outcome: tuple[bool, str] = (False, "")
        self.last_trusted = False
        super().__init__(**kw)

    def perform_adaptation(self, action: Action) -> tuple[bool, str]:
        """Check and register ``action``; (True, why) when it reached the effector."""
        self.last_trusted = False
        if self.mode != "initialized":
            return False, f"adaptation manager is {self.mode}"
        self._action = action
        self._outcome = (False, "the adaptation did not complete in time")
        self.send("action_requested")
        return self._outcome

    def perform_diagnosis(self, action: Action) -> tuple[bool, str]:
        return self.perform_adaptation(
            Action(action.effector, action.payload, action.plan, "diagnosis")
        )

    def on_enter_checking_trustworthiness(self) -> None:
        held = self.hold.holds(self._action) if self.hold is not None else None
        if held is not None and not self.hold.correctable():
            self._outcome = (False, held)
            self.post("untrustworthy")
            return
        ok, why = self.tm.check_trustworthiness(self._action)
        if held is not None and not (ok and getattr(self.tm, "last_corrective", False)):
            ok, why = False, held  # only a corrective action passes a hold of vetoes
        self.last_trusted = ok
        self._outcome = (False, why)
        self.post("trustworthy" if ok else "untrustworthy")

    def on_enter_registering(self) -> None:
        ok, why = self.tc.register_action(self._action)
        self._outcome = (ok, why)
        self.post("registered" if ok else "registration_refused")

    def on_enter_dropping(self) -> None:
        self.post("dropped")
