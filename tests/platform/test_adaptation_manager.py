"""The Adaptation Manager sends an action on only when it is trustworthy, and only through the
Trustworthiness Checker; what it depends on is two small roles, played here by test doubles."""

from __future__ import annotations

from rasm import Action
from rasm.platform.action_outcome import ActionOutcome
from rasm.platform.adaptation_manager import AdaptationManager

ACTION = Action("heater", {"mode": "boost"}, plan="p1")


class Judge:
    """A Trustworthiness Manager that answers as told."""

    def __init__(self, trustworthy: bool, why: str = "") -> None:
        self.answer = ActionOutcome(False, why, trusted=trustworthy)
        self.asked: list[Action] = []

    def check_trustworthiness(self, action: Action) -> ActionOutcome:
        self.asked.append(action)
        return self.answer


class Gate:
    """A Trustworthiness Checker that registers as told."""

    def __init__(self, registered: bool = True, why: str = "sent") -> None:
        self.answer = ActionOutcome(registered, why)
        self.registered: list[Action] = []

    def register_action(self, action: Action) -> ActionOutcome:
        self.registered.append(action)
        return self.answer


def started(judge: Judge, gate: Gate) -> AdaptationManager:
    am = AdaptationManager(judge, gate)
    am.send("configure")
    assert am.mode == "initialized"
    return am


def test_a_trustworthy_action_is_registered_with_the_checker() -> None:
    judge, gate = Judge(True), Gate()
    am = started(judge, gate)
    assert am.perform_adaptation(ACTION) == ActionOutcome(True, "sent", trusted=True)
    assert judge.asked == gate.registered == [ACTION]


def test_an_untrustworthy_action_is_dropped_with_the_judges_reason() -> None:
    gate = Gate()
    am = started(Judge(False, "veto property band violated at t=3"), gate)
    assert am.perform_adaptation(ACTION) == ActionOutcome(
        False, "veto property band violated at t=3"
    )
    assert gate.registered == []


def test_a_registration_the_checker_refuses_is_reported() -> None:
    am = started(Judge(True), Gate(False, "not applicable in managed-system mode 'docked'"))
    # trusted, but the checker did not send it
    assert am.perform_adaptation(ACTION) == ActionOutcome(
        False, "not applicable in managed-system mode 'docked'", trusted=True
    )


def test_nothing_is_performed_unless_initialized() -> None:
    judge, gate = Judge(True), Gate()
    am = AdaptationManager(judge, gate)
    assert am.perform_adaptation(ACTION) == ActionOutcome(
        False, "adaptation manager is instantiated"
    )
    assert judge.asked == gate.registered == []


def test_a_diagnosis_is_an_action_of_its_own_kind() -> None:
    gate = Gate()
    am = started(Judge(True), gate)
    assert am.perform_diagnosis(ACTION).sent
    assert gate.registered == [Action("heater", {"mode": "boost"}, "p1", "diagnosis")]
