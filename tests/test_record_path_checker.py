"""The Trustworthiness Checker's trace observer (check_record) keeps what observe() keeps.

check_record tallies (property, value) pairs instead of verdict objects when nobody listens for
verdicts; the latest verdicts, the violation and inconclusive counts and the refused records
must be observe()'s, for monitors with and without tally_into, faulty ones included.
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.platform.blocks import TrustworthinessChecker
from rasm.spec import compile as compile_properties
from rasm.spec.monitor import Verdict

SPEC = """
input x: float
event e
property low: always (x < 1)
property answered: always (e -> eventually[0, 2s] x > 0)
property recent: always (once[0, 1s] e)
"""


class _StepOnly:
    """A monitor without tally (another kind of monitor): check_record uses its step."""

    properties = ["odd"]

    def __init__(self) -> None:
        self.count = 0

    def step(self, time, record):
        self.count += 1
        value = None if self.count % 5 == 0 else self.count % 2 == 1
        return [tuple.__new__(Verdict, ("odd", self.count, time, value))]


class _Faulty:
    properties = ["faulty"]

    def step(self, time, record):
        raise RuntimeError("broken monitor")

    tally = step


def _checker(listen: list | None = None) -> TrustworthinessChecker:
    """A checker; with ``listen``, an observer appends every verdict to it."""
    return TrustworthinessChecker(
        monitors=[compile_properties(SPEC), _StepOnly(), _Faulty()],
        effectors={},
        send=lambda effector, action: None,
        mode_of=lambda: None,
        observers=[listen.append] if listen is not None else [],
    )


RECORDS = st.lists(
    st.tuples(
        st.sampled_from([0.0, 0.5, 1.0, 2.5]),
        st.fixed_dictionaries(
            {}, optional={"x": st.sampled_from([-1.0, 0.5, 2.0, "bad"]), "e": st.booleans()}
        ),
    ),
    max_size=30,
)


@settings(max_examples=150, deadline=None)
@given(RECORDS)
def test_check_record_keeps_what_observe_keeps(steps):
    observed, checked = _checker(), _checker()
    time = 0.0
    for step, record in steps:
        time += step
        observed.observe(time, record)
        checked.check_record(time, record)
        assert checked.latest == observed.latest
    assert checked.violations == observed.violations
    assert checked.inconclusive == observed.inconclusive
    assert checked.records_refused == observed.records_refused
    assert checked.monitors[0].rejected == observed.monitors[0].rejected


def test_check_record_hands_verdicts_to_observers_when_there_are_some():
    seen: list = []
    checker, reference = _checker(seen), _checker()
    for time, record in [(0.0, {"x": 0.5, "e": True}), (1.0, {"x": 2.0}), (4.0, {})]:
        checker.check_record(time, record)
        expected = reference.observe(time, record)
        assert seen[-len(expected) :] == expected
    assert checker.latest == reference.latest and checker.violations == reference.violations
