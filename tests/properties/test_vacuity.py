"""``vacuous`` (SPEC §6): the left sides of ``->`` that never held on a judged record, against a
brute-force oracle; and how ``rasm check`` says it."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.cli import main
from rasm.properties.ast import Binary, children
from rasm.properties.check import check_records, check_stream, format_json, format_text
from rasm.properties.loader import load_specification
from rasm.properties.printer import unparse
from rasm.properties.vacuity import Vacuity

from .reference import Reference
from .strategies import HEADER, formulas, traces


def oracle(spec, records) -> dict[str, set[str]]:
    """Per property, the antecedents whose value was never true at a judged record: every
    value computed from §5's semantics by the reference evaluator."""
    out = {}
    ref = Reference(spec, records)
    for prop in spec.properties:
        judged = ref.verdicts(prop)  # also sets the property's start for the values below
        lefts, stack = [], [prop.formula]
        while stack:
            node = stack.pop()
            if isinstance(node, Binary) and node.op == "->":
                lefts.append(node.left)
            stack.extend(children(node))
        out[prop.name] = {
            unparse(left) for left in lefts
            if not any(ref.value(left, i) is True for i in judged)
        }
    return out


def names(vacuous) -> set[str]:
    return {u.text for u in vacuous}


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(
    st.lists(formulas(3), min_size=1, max_size=3),
    formulas(2),
    traces(),
    st.integers(1, 6),
)
def test_vacuous_iff_the_antecedent_never_held_on_a_judged_record(bodies, left, trace, chunk):
    # every property has at least one "->", the drawn formulas often more, nested anywhere
    text = HEADER + "".join(
        f"property p{k}: always (({left}) -> ({body}))\n" for k, body in enumerate(bodies)
    )
    spec = load_specification(text)
    expected = oracle(spec, trace)
    listed = check_records(spec, trace, explain_violations=False)
    streamed = check_stream(spec, iter(trace), chunk=chunk)
    online = Vacuity(spec)
    for time, record in trace:
        online.step(time, record)
    online.finish()
    for k, prop in enumerate(spec.properties):
        assert names(listed.properties[k].outcome.vacuous) == expected[prop.name]
        assert names(streamed.properties[k].outcome.vacuous) == expected[prop.name]
        assert names(online.vacuous(prop.name)) == expected[prop.name]


PROPS = """\
input velocity: float
event anomaly
event executed
let fast = velocity > 1

property timely:
    always (anomaly -> eventually[0, 5s] executed)
property slow_down:
    always (fast -> eventually[0, 1s] velocity < 0.5)
property limit:
    always (velocity < 3)
"""

QUIET = [
    {"time": 0, "velocity": 0.2},
    {"time": 1, "velocity": 0.4},
    {"time": 2, "velocity": 0.3},
]


@pytest.fixture
def files(tmp_path):
    props = tmp_path / "props.rv"
    props.write_text(PROPS)

    def trace(records):
        path = tmp_path / "trace.jsonl"
        path.write_text("".join(json.dumps(r) + "\n" for r in records))
        return str(path)

    return str(props), trace


def test_rasm_check_says_a_property_was_never_put_to_the_test(files, capsys):
    props, trace = files
    assert main(["check", props, trace(QUIET)]) == 0  # vacuous still passes
    out = capsys.readouterr().out
    assert "  timely: satisfied (vacuously: anomaly never happened), 3 records judged" in out
    # a let is named as written; a sub-formula that is no event "never held"
    assert "  slow_down: satisfied (vacuously: fast never held), 3 records judged" in out
    assert "  limit: satisfied (3 records judged)" in out  # no "->": nothing to be vacuous
    assert "0 of 3 properties fail: 3 satisfied (2 vacuously)" in out
    assert main(["check", props, trace(QUIET), "--format", "json"]) == 0
    report = json.loads(capsys.readouterr().out)
    vacuous = {p["name"]: p["vacuous"] for p in report["properties"]}
    assert vacuous == {"timely": ["anomaly"], "slow_down": ["fast"], "limit": []}


def test_an_antecedent_that_held_once_is_not_vacuous(files, capsys):
    props, trace = files
    records = [*QUIET, {"time": 3, "anomaly": True}, {"time": 4, "executed": True}]
    assert main(["check", props, trace(records), "--format", "json"]) == 0
    vacuous = {p["name"]: p["vacuous"] for p in json.loads(capsys.readouterr().out)["properties"]}
    assert vacuous == {"timely": [], "slow_down": ["fast"], "limit": []}


def test_an_antecedent_that_held_only_during_the_warm_up_is_vacuous():
    # the property reads velocity: before its first value it is not judged, and an anomaly
    # then puts nothing to the test
    spec = load_specification(
        "input velocity: float\nevent anomaly\n"
        "property calm: always (anomaly -> velocity < 1)\n"
    )
    records = [(0, {"anomaly": True}), (1, {"velocity": 0.2}), (2, {"velocity": 0.1})]
    report = check_records(spec, records)
    calm = report.properties[0]
    assert calm.judged == 2
    assert names(calm.outcome.vacuous) == {"anomaly"}
    assert "calm: satisfied (vacuously: anomaly never happened)" in format_text(report)
    assert json.loads(format_json(report))["properties"][0]["vacuous"] == ["anomaly"]
    # the same anomaly once the property has started is a test it passed
    report = check_records(spec, [*records, (3, {"anomaly": True})])
    assert report.properties[0].outcome.vacuous == ()


def test_a_violated_property_lists_its_vacuous_antecedents_too():
    spec = load_specification(
        "input x: float\nevent a\nproperty p: always ((a -> x > 0) and x < 1)\n"
    )
    report = check_records(spec, [(0, {"x": 0.5}), (1, {"x": 2.0})])
    assert report.properties[0].verdict == "violated"
    assert names(report.properties[0].outcome.vacuous) == {"a"}
