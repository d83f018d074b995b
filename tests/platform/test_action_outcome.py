"""What became of an action is written to the trace one way, by the loop and the fallback alike:
``trusted`` exactly when it was trusted, then ``executed`` when it was sent, else ``dropped``."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from rasm import Action
from rasm.platform.action_outcome import ActionOutcome, perform_and_trace

OUTCOMES = st.builds(ActionOutcome, st.booleans(), st.text(max_size=5), st.booleans(),
                     st.booleans())


@given(outcome=OUTCOMES)
def test_the_trace_says_what_became_of_the_action(outcome: ActionOutcome) -> None:
    records: list[tuple[float, dict]] = []
    action = Action("heater", {"mode": "boost"}, plan="p7")
    got = perform_and_trace(lambda a: outcome, action, lambda t, r: records.append((t, r)),
                            lambda: 2.5)
    assert got is outcome
    expected = [(2.5, {"trusted": True, "plan": "p7"})] if outcome.trusted else []
    event = "executed" if outcome.sent else "dropped"
    expected.append((2.5, {event: True, "plan": "p7", "explanation": outcome.why}))
    assert records == expected
