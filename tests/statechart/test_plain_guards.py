"""Guards read without evaluating them (``after(X)``, ``idle(X)``, ``NAME``, ``not NAME``) give
exactly what evaluating them gives: the value, the error, and the timers recorded."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from sismic.io.datadict import import_from_dict

from rasm.statechart import Interpreter
from rasm.statechart.interpreter import DeadlineEvaluator, _plain_guard


class EvaluatedOnly(DeadlineEvaluator):
    """DeadlineEvaluator that evaluates every guard (no plain form)."""

    def _compile_guard(self, guard):
        code, kind, wanted, _ = super()._compile_guard(guard)
        found = self._guard_codes[guard] = (code, kind, wanted, None)
        return found


class Exploding:
    def __bool__(self):
        raise ValueError("no truth here")

    def __rsub__(self, other):
        raise ValueError("no arithmetic here")


GUARDS = [
    "after(x)", "idle(x)", "after(2)", "idle(0.5)", "after(-1)", "x", "not x", " not  y ",
    "after(x)  # a comment", "idle(True)", "after(x, 1)", "after", "not after(x)", "x or y",
]
VALUES = st.one_of(
    st.integers(-3, 3), st.floats(allow_nan=True, allow_infinity=True), st.booleans(),
    st.text(max_size=2), st.none(), st.lists(st.integers(), max_size=1), st.just(Exploding()),
)
CONTEXTS = st.dictionaries(st.sampled_from(["x", "y", "after", "idle"]), VALUES, max_size=3)


def run(evaluator, guard, context, entered, idled, now):
    chart = import_from_dict({"statechart": {"name": "g", "root state": {
        "name": "root", "initial": "a",
        "states": [{"name": "a", "transitions": [{"target": "b", "guard": guard}]}, {"name": "b"}],
    }}})
    interp = Interpreter(chart, evaluator_klass=evaluator)
    interp._evaluator._context.update(context)
    for times, value in ((interp._entry_time, entered), (interp._idle_time, idled)):
        if value is None:
            times.pop("a", None)
        else:
            times["a"] = value
    interp._time = now
    transition = chart.transitions_from("a")[0]
    try:
        found = ("value", interp._evaluator.evaluate_guard(transition))
    except Exception as exc:  # noqa: BLE001 - the error is what is compared
        found = ("error", type(exc).__name__, str(exc))
    return found, [repr(d) for d in interp._evaluator.deadlines]  # repr: NaN equals NaN


@settings(max_examples=400, deadline=None)
@given(
    guard=st.sampled_from(GUARDS),
    context=CONTEXTS,
    entered=st.none() | st.floats(0, 10),
    idled=st.none() | st.floats(0, 10),
    now=st.floats(0, 20),
)
def test_a_plain_guard_reads_as_it_evaluates(guard, context, entered, idled, now):
    expected = run(EvaluatedOnly, guard, context, entered, idled, now)
    assert run(DeadlineEvaluator, guard, context, entered, idled, now) == expected


def test_the_plain_forms():
    assert _plain_guard("after(stage_budget)") == ("timer", "after", "stage_budget", None)
    assert _plain_guard("idle(3)") == ("timer", "idle", None, 3)
    assert _plain_guard("not managed_online") == ("flag", "managed_online", True)
    assert _plain_guard("managed_online") == ("flag", "managed_online", False)
    for other in ("after(x, 1)", "after(True)", "x < 1", "not not x", "after(x) and y", "1/0"):
        assert _plain_guard(other) is None
