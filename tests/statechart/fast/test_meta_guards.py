"""Static guard predicates (rasm.statechart.fast.meta_guards) agree with evaluating the guard."""

from __future__ import annotations

from typing import Any

from hypothesis import given
from hypothesis import strategies as st
from sismic.model import Event, MetaEvent

from rasm.statechart.fast.meta_guards import DISCRIMINANT, MISSING, NO_EVENT, guard_predicate

VALUES = ["s1", "s2", "idle", "a", "b", "", "s"]
CONSTANTS = ["'s1'", "'a'", "('s1', 's2')", "['a', 'idle']", "{'s2', 'b'}", "'s1s2'", "NAMES",
             "OTHER", "k", "LISTED"]
CONTEXTS = [
    {"NAMES": ("s2", "a"), "OTHER": frozenset({"idle"}), "k": "s", "LISTED": ("s1",)},
    {"NAMES": "s1", "OTHER": ("b",), "k": "s1", "LISTED": ("x",)},
    {"NAMES": ("s2",), "OTHER": frozenset(), "k": 1, "LISTED": ["s1"]},  # unusable k, LISTED
    {"NAMES": ("s2",), "OTHER": "", "event": "shadow", "k": "a", "LISTED": ()},
]
READERS = ["event.state", "event.event.name", "event.source"]


@st.composite
def guards(draw: Any, reader: str, depth: int = 2) -> str:
    """Guards over ``reader`` (mostly: the name's own discriminant), with some others mixed in."""
    kinds = ["compare", "compare", "not", "and", "or"] if depth else ["compare"]
    kind = draw(st.sampled_from(kinds))
    if kind == "not":
        return f"not ({draw(guards(reader, depth - 1))})"
    if kind in ("and", "or"):
        return f"({draw(guards(reader, depth - 1))}) {kind} ({draw(guards(reader, depth - 1))})"
    if draw(st.integers(0, 9)) == 0:
        reader = draw(st.sampled_from(READERS))
    if reader.startswith("event.event") and draw(st.integers(0, 3)) == 0:
        return f"event.event is {draw(st.sampled_from(['None', 'not None']))}"
    op = draw(st.sampled_from(["==", "!=", "in", "not in"]))
    constant = draw(st.sampled_from(CONSTANTS))
    if draw(st.booleans()):
        return f"{constant} {op} {reader}"
    return f"{reader} {op} {constant}"


def _meta(name: str, value: Any) -> MetaEvent:
    if DISCRIMINANT[name] == "event.state":
        return MetaEvent(name, state=value)
    inner = None if value is NO_EVENT else Event(value)
    if name == "transition processed":
        return MetaEvent(name, source="s1", target="s2", event=inner)
    return MetaEvent(name, event=inner)


def _evaluate(guard: str, meta: MetaEvent, context: dict) -> Any:
    # how sismic's evaluators look names up: the context first, then the exposed names
    try:
        return ("value", bool(eval(guard, {"event": meta}, dict(context))))
    except Exception as exc:  # noqa: BLE001 - any error: a predicate must not claim a value
        return ("error", type(exc))


@st.composite
def cases(draw: Any) -> tuple[str, str]:
    name = draw(st.sampled_from(sorted(DISCRIMINANT)))
    return draw(guards(DISCRIMINANT[name])), name


@given(case=cases(), value=st.sampled_from(VALUES), context=st.sampled_from(CONTEXTS))
def test_a_predicate_decides_the_guard_exactly(case, value, context):
    guard, name = case
    if name == "transition processed" and value == "":
        value = NO_EVENT  # an eventless transition (only this meta-event can have none)
    found = guard_predicate(guard, name, context)
    if found is None:
        return  # undecided: the guard is evaluated, nothing to compare
    predicate, watch = found
    decided = predicate(value)
    outcome = _evaluate(guard, _meta(name, value), context)
    if decided is None:  # the guard raises for this value
        assert outcome[0] == "error"
    else:
        assert outcome == ("value", decided)
    for key, bound in watch.items():
        assert context.get(key, MISSING) is bound


def test_recognised_forms_are_decided():
    context = {"STAGES": ("monitoring", "analysing")}
    decided = {
        "event.state == 'idle'": ("state entered", "idle", True),
        "'idle' != event.state": ("state exited", "idle", False),
        "event.state in STAGES": ("state entered", "analysing", True),
        "not (event.state in STAGES or event.state == 'x')": ("state entered", "x", False),
        "event.event.name == 'accepted'": ("event consumed", "accepted", True),
        "event.event.name in ('a', 'b') and event.event.name != 'a'": ("event sent", "a", False),
        "event.event is None": ("transition processed", NO_EVENT, True),
        "event.event is not None and event.event.name == 'a'": (
            "transition processed", NO_EVENT, False,
        ),
    }
    for guard, (name, value, expected) in decided.items():
        found = guard_predicate(guard, name, context)
        assert found is not None, guard
        assert found[0](value) is expected, guard
    assert guard_predicate("event.state in STAGES", "state entered", context)[1] == {
        "STAGES": context["STAGES"], "event": MISSING,
    }


def test_other_forms_are_left_to_evaluation():
    context = {"STAGES": ("a",), "MUTABLE": ["a"], "N": 3}
    undecided = [
        ("event.state == 'a'", "event consumed"),  # no such attribute on that meta-event
        ("event.event.name == 'a'", "state entered"),
        ("event.source == 'a'", "transition processed"),  # not its discriminant
        ("event.state is None", "state entered"),  # `is` only tests for no event
        ("event.state in MUTABLE", "state entered"),  # a list can change in place
        ("event.state == N", "state entered"),
        ("event.state in UNBOUND", "state entered"),  # a global or builtin, not the context
        ("'a' in event.state", "state entered"),  # a substring test
        ("event.state == event.state", "state entered"),
        ("'a' == 'a'", "state entered"),
        ("event.state == 'a' == 'a'", "state entered"),
        ("len(event.state) > 1", "state entered"),
        ("event.state ==", "state entered"),  # a syntax error: evaluation reports it
    ]
    for guard, name in undecided:
        assert guard_predicate(guard, name, context) is None, guard
    # the name of no event: evaluating the guard raises, the predicate says so with None
    predicate = guard_predicate("event.event.name == 'a'", "transition processed", {})[0]
    assert predicate(NO_EVENT) is None
    # a context name `event` hides the meta-event from every guard
    assert guard_predicate("event.state == 'a'", "state entered", {"event": 1}) is None
