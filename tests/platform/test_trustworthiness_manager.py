"""The Trustworthiness Manager fails closed: a veto property the checker cannot vouch for now
(violated, in error, inconclusive, or not judged yet) vetoes the action, and the explanation says
which property and why."""

from __future__ import annotations

from decimal import Decimal

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.platform.components import Action, Plan
from rasm.platform.trustworthiness_checker import TrustworthinessChecker
from rasm.platform.trustworthiness_manager import TrustworthinessManager
from rasm.properties import compile_properties

from .scripted import Scripted

PROPS = """
input speed: float
input battery: float
property slow: always (speed <= 1.0)
property charged: always (battery >= 0.2)
"""


def checker_and_manager(monitors, veto):
    tc = TrustworthinessChecker(
        monitors=monitors, effectors={}, send=lambda effector, action: None, mode_of=lambda: None
    )
    tm = TrustworthinessManager(rules=[], veto_properties=tuple(veto), checker=tc, context=dict)
    tm.send("configure")
    assert tm.mode == "initialized"
    tm.accept_plan(Plan({"v": 1}, id="p1"))
    return tc, tm


ACTION = Action("wheels", {"v": 1}, plan="p1")


def trusted(tm: TrustworthinessManager) -> tuple[bool, str]:
    """Whether the manager trusts ACTION, and why."""
    judged = tm.check_trustworthiness(ACTION)
    assert not judged.sent  # the manager judges; only the checker sends
    return judged.trusted, judged.why


def test_a_veto_property_not_judged_yet_vetoes_naming_the_signals_it_waits_for():
    tc, tm = checker_and_manager([compile_properties(PROPS)], ["slow", "charged"])
    ok, why = trusted(tm)
    assert not ok
    assert "veto property slow not judged yet: no value for speed" in why
    assert "veto property charged not judged yet: no value for battery" in why
    tc.observe(0.0, {"speed": 0.5})  # slow starts; charged still waits for its signal
    ok, why = trusted(tm)
    assert not ok and why == "veto property charged not judged yet: no value for battery"
    tc.observe(0.5, {"battery": 0.9})
    assert trusted(tm) == (
        True, "plan accepted by Legitimate, rules hold, every veto property holds"
    )
    tc.observe(1.0, {"speed": 1.5})
    assert trusted(tm) == (False, "veto property slow violated at t=1")


def test_a_veto_property_in_error_vetoes_and_says_why():
    tc, tm = checker_and_manager([Scripted([True, "raise", True])], ["guard"])
    tc.observe(0.0, {})
    assert trusted(tm)[0] is True
    tc.observe(1.0, {})
    ok, why = trusted(tm)
    assert not ok
    assert why == (
        "veto property guard in error at t=1: the monitor raised OverflowError: integer "
        "division result too large for a float"
    )
    tc.observe(2.0, {})  # the monitor works again: so does the action
    assert trusted(tm)[0] is True
    assert tc.outcomes["guard"].state == "error"  # the run's verdict remembers


def test_a_veto_property_whose_first_verdict_is_not_decided_yet_vetoes():
    """A bounded-future veto property has started but decides its first verdict only later:
    until then the checker cannot vouch for it."""
    tc, tm = checker_and_manager(
        [compile_properties("event anomaly\nevent executed\n"
                            "property timely: always (anomaly -> eventually[0, 2s] executed)\n")],
        ["timely"],
    )
    tc.observe(0.0, {"anomaly": True})
    ok, why = trusted(tm)
    assert (ok, why) == (False, "veto property timely not judged yet: no verdict decided so far")
    tc.observe(1.0, {"executed": True})  # answers the anomaly of record 0: decided true
    assert trusted(tm)[0] is True


def test_a_bounded_future_veto_property_vetoes_from_the_decision_of_a_failure_to_its_next_verdict():
    """What "currently violated" means for a bounded-future veto property: its verdicts are
    decided out of record order (an anomaly waits for its window to close, the records after it
    are decided at once), and the latest verdict is the one decided last."""
    tc, tm = checker_and_manager(
        [compile_properties("event anomaly\nevent executed\n"
                            "property timely: always (anomaly -> eventually[0, 2s] executed)\n")],
        ["timely"],
    )
    tc.observe(0.0, {"anomaly": True})  # pending: its window closes at t=2
    tc.observe(1.0, {})  # no anomaly: true, decided at once
    assert trusted(tm)[0] is True  # a pending anomaly does not veto
    decided = tc.observe(2.5, {})  # record 0's window is over: decided false, with record 2's
    assert sorted((v.index, v.value) for v in decided) == [(0, False), (2, True)]
    assert trusted(tm) == (False, "veto property timely violated at t=0")
    tc.observe(3.0, {})  # the next verdict decided lifts the veto
    assert trusted(tm)[0] is True
    assert tc.outcomes["timely"].state == "violated"  # the run's verdict keeps the failure


def test_a_veto_property_vetoes_as_soon_as_its_verdict_is_decided():
    """``(always[0, 0.3] q) and (eventually[0, 5] p)`` is false at a record once q fails
    within 0.3 s of it, whatever its eventually still waits for: the action is refused from
    that record on, not 5 s later."""
    tc, tm = checker_and_manager(
        [compile_properties("event p\nevent q\n"
                            "property guard: (always[0, 0.3] q) and (eventually[0, 5] p)\n")],
        ["guard"],
    )
    tc.observe(0.0, {"q": True, "p": True})
    tc.observe(0.4, {"q": True, "p": True})  # record 0's always is over: true
    tc.observe(0.8, {"q": True})  # record 1's: true; record 2 waits for p (until 5.8 s)
    assert trusted(tm)[0] is True
    decided = tc.observe(0.9, {})  # q fails within 0.3 s of record 2 (and at 3 itself)
    assert sorted((v.index, v.value) for v in decided) == [(2, False), (3, False)]
    assert trusted(tm) == (False, "veto property guard violated at t=0.8")


VALUE = st.sampled_from([True, False, None])
STEPS = st.lists(
    st.one_of(
        VALUE, st.sampled_from(["raise", "nothing"]), st.lists(VALUE, min_size=1, max_size=3)
    ),
    max_size=20,
)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(steps=STEPS)
def test_an_action_passes_only_while_the_veto_propertys_latest_verdicts_hold(steps):
    """For every sequence of verdicts, errors and silent records: after each record the action
    is trusted exactly when every verdict the newest deciding record gave is true; before the
    first verdict it never is. The explanation names the worst of them."""
    tc, tm = checker_and_manager([Scripted(steps)], ["guard"])
    latest: list = []  # the verdict values of the newest record that decided any
    for time, what in enumerate(steps):
        tc.observe(float(time), {})
        if what != "nothing":
            latest = what if isinstance(what, list) else [what]
        ok, why = trusted(tm)
        assert ok == (bool(latest) and all(v is True for v in latest)), (steps[: time + 1], why)
        if not ok:
            if not latest:
                expected = "not judged yet"
            elif "raise" in latest:
                expected = "in error"
            elif False in latest:
                expected = "violated"
            else:
                expected = "inconclusive"
            assert why.startswith(f"veto property guard {expected}"), why


@settings(max_examples=60, deadline=None)
@given(
    time=st.decimals(min_value=0, max_value=2_000_000_000, places=3),
    kind=st.sampled_from([False, "raise", None]),
)
def test_a_veto_names_the_time_of_its_verdict_exactly(time, kind):
    """Epoch times and decimals are written as the decimals they are (1700000000.3, not
    1.7e+09; 0.3, not 0.30000000000000004), whatever the verdict that vetoes."""
    tc, tm = checker_and_manager([Scripted([kind])], ["guard"])
    tc.observe(float(time), {})
    ok, why = trusted(tm)
    written = why.split(" at t=")[1].split(":")[0]
    assert not ok and Decimal(written) == time, why
