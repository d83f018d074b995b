"""verify() against the brute-force oracle, on generated rule sets over finite domains."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings

from rasm.properties import evaluate
from rasm.rules import format_text, parse_rules, smt, verify
from rasm.rules.split import guard_split

from .brute import Oracle, truth
from .brute import points as brute_points
from .gen import (
    guarded_rules_files,
    plan_field_sets,
    planned_guarded_rules_files,
    planned_rules_files,
    rules_files,
    with_plan_fields,
)

SETTINGS = settings(max_examples=50, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def _judge(text):
    rules = parse_rules(text, source="gen.yaml")
    return rules, verify(rules), Oracle(rules)


@SETTINGS
@given(rules_files())
def test_dead_and_unsatisfiable_match_enumeration(text):
    _, report, oracle = _judge(text)
    assert set(report.dead) == oracle.dead
    assert set(report.unsatisfiable) == oracle.unsatisfiable
    assert report.consistent == (not oracle.unsatisfiable and not oracle.conflicts)


@SETTINGS
@given(rules_files())
def test_conflicts_are_all_the_minimal_conflicts(text):
    _, report, oracle = _judge(text)
    found = [frozenset(c.rules) for c in report.conflicts]
    assert len(found) == len(set(found)), "a conflict reported twice"
    assert set(found) == oracle.conflicts
    for conflict in found:  # each is minimal: every proper subset can be obeyed
        assert all(oracle.bodies_meet(conflict - {n}) for n in conflict)


@SETTINGS
@given(rules_files())
def test_conflict_witnesses_show_the_clash(text):
    rules, report, _ = _judge(text)
    for conflict in report.conflicts:
        point = conflict.context
        assert all(truth(rules.rule(n).when, point) for n in conflict.rules)
        broken = {n for n in conflict.rules if not truth(rules.rule(n).require, point)}
        assert broken and broken == set(conflict.broken)
    for name, point in report.unsatisfiable_contexts.items():
        assert truth(rules.rule(name).when, point)
        assert not truth(rules.rule(name).require, point)


@pytest.mark.slow
@SETTINGS
@given(rules_files())
def test_redundant_rules_match_enumeration(text):
    _, report, oracle = _judge(text)
    assert set(report.redundant) == oracle.redundant
    for name, support in report.implied_by.items():
        assert name not in support
        assert oracle.implies(support, name)
        assert oracle.consistent_with_when(support, name)


@pytest.mark.slow
@SETTINGS
@given(rules_files())
def test_redundancy_equals_plain_implication_without_conflicts(text):
    """With no conflict and no unsatisfiable rule, 'redundant' is plain 'implied by the rest'."""
    rules, report, oracle = _judge(text)
    if oracle.conflicts or oracle.unsatisfiable:
        return
    sound = [r.name for r in rules.rules if r.name not in oracle.dead]
    plain = {n for n in sound if oracle.implies([s for s in sound if s != n], n)}
    assert set(report.redundant) == plain


def test_evaluate_is_the_oracles_semantics():
    """The oracle judges with the property language's evaluate: division by zero is false."""
    rules = parse_rules(
        "variables:\n  x: {type: int, min: 0, max: 1}\n"
        "rules:\n  - name: r\n    require: x / 0 >= 0\n", source="z.yaml"
    )
    assert evaluate(rules.rules[0].require, {"x": 1}) is False
    assert verify(rules).unsatisfiable == ["r"]


@pytest.mark.slow
@SETTINGS
@given(guarded_rules_files())
def test_mode_guarded_rule_sets_are_split_by_context_without_losing_a_finding(text):
    rules, report, oracle = _judge(text)
    assert guard_split(rules.rules, rules.variables, range(len(rules.rules))) is not None
    assert {frozenset(c.rules) for c in report.conflicts} == oracle.conflicts
    assert set(report.redundant) == oracle.redundant
    assert set(report.unsatisfiable) == oracle.unsatisfiable


# --------------------------------------------------------------------- plan fields (SPEC §7)


def _matching(oracle, context):
    """The indices of the points that agree with ``context`` (any plan, any other value)."""
    points = brute_points(oracle.rules)
    return [i for i, p in enumerate(points) if all(p[k] == v for k, v in context.items())]


@pytest.mark.slow
@SETTINGS
@given(planned_rules_files())
def test_with_plan_fields_consistent_means_every_context_admits_a_plan(text):
    rules, report, oracle = _judge(text)
    assert rules.plan_fields
    assert set(report.dead) == oracle.dead
    assert set(report.unsatisfiable) == oracle.unsatisfiable
    assert {frozenset(c.rules) for c in report.conflicts} == oracle.conflicts
    everything = [r.name for r in rules.rules]
    assert report.consistent == (not oracle.no_plan_somewhere(everything))


@pytest.mark.slow
@SETTINGS
@given(planned_rules_files())
def test_with_plan_fields_each_witness_is_a_context_admitting_no_plan(text):
    rules, report, oracle = _judge(text)
    found = [(c.rules, c.context) for c in report.conflicts]
    found += [((n,), c) for n, c in report.unsatisfiable_contexts.items()]
    for names, context in found:
        assert not set(context) & set(rules.plan_fields), "a plan field in a witness context"
        assert oracle.no_plan_at(names, _matching(oracle, context))
    for conflict in report.conflicts:
        assert set(conflict.broken) == set(conflict.rules)


@pytest.mark.slow
@SETTINGS
@given(planned_rules_files())
def test_with_plan_fields_redundant_rules_match_enumeration(text):
    _, report, oracle = _judge(text)
    assert set(report.redundant) == oracle.redundant
    for name, support in report.implied_by.items():
        assert oracle.implies(support, name)
        assert oracle.consistent_with_when(support, name)


@pytest.mark.slow
@SETTINGS
@given(planned_guarded_rules_files())
def test_with_plan_fields_the_split_by_context_guards_loses_no_conflict(text):
    rules, report, oracle = _judge(text)
    assert {frozenset(c.rules) for c in report.conflicts} == oracle.conflicts
    assert set(report.unsatisfiable) == oracle.unsatisfiable
    assert set(report.redundant) == oracle.redundant


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(planned_rules_files(max_rules=4))
def test_with_plan_fields_quantified_plans_give_the_same_findings(text):
    """Plan fields with few values are enumerated; with the enumeration off every plan field
    is quantified (as reals are), and z3 must find the same."""
    rules = parse_rules(text, source="gen.yaml")
    oracle = Oracle(rules)
    saved = smt.ENUMERATED_PLANS
    smt.ENUMERATED_PLANS = 1
    try:
        report = verify(rules)
    finally:
        smt.ENUMERATED_PLANS = saved
    assert set(report.unsatisfiable) == oracle.unsatisfiable
    assert {frozenset(c.rules) for c in report.conflicts} == oracle.conflicts


@pytest.mark.slow
@SETTINGS
@given(rules_files(), plan_field_sets)
def test_an_apps_plan_fields_count_as_plan_true_in_the_file(text, plan):
    from_app = verify(parse_rules(text, source="gen.yaml").with_plan_fields(plan))
    in_file = verify(parse_rules(with_plan_fields(text, plan), source="gen.yaml"))
    # the same findings (z3 may pick other witnesses for the same question)
    found = [{k: v for k, v in r.to_dict().items() if k != "witnesses"}
             for r in (from_app, in_file)]
    assert found[0] == found[1]
    assert from_app.plan_fields == in_file.plan_fields


DOCKING = """variables:
  battery: {type: real, min: 0, max: 100}
  dock:    {type: bool}
  speed:   {type: real, min: 0, max: 1}
rules:
  - name: dock_when_low
    when: battery < 10
    require: dock
  - name: keep_moving
    when: not dock
    require: speed >= 0.2
"""


def test_rules_that_disagree_only_on_plans_the_planner_need_not_choose_do_not_conflict():
    """The plan {dock: true, speed: 0} obeys both rules at every battery level."""
    rules = parse_rules(DOCKING, source="dock.yaml")
    assert [c.rules for c in verify(rules).conflicts] == [("dock_when_low", "keep_moving")]
    report = verify(rules.with_plan_fields(["dock", "speed"]))
    assert report.consistent and not report.conflicts and not report.unsatisfiable


def test_a_context_that_admits_no_plan_is_a_conflict_with_that_context_as_witness():
    text = DOCKING + ("  - name: docked_still\n    when: dock\n    require: speed == 0\n"
                      "  - name: crawl_when_critical\n    when: battery < 5\n"
                      "    require: speed >= 0.1\n")
    report = verify(parse_rules(text, source="dock.yaml").with_plan_fields(["dock", "speed"]))
    assert not report.consistent
    [conflict] = report.conflicts
    assert conflict.rules == ("dock_when_low", "docked_still", "crawl_when_critical")
    assert set(conflict.context) == {"battery"} and conflict.context["battery"] < 5
    assert "e.g. battery == " in format_text(report)


def test_redundancy_through_an_unsatisfiable_rule_is_found():
    """``never_armed`` can never be obeyed where it applies (so it holds only where ``armed`` is
    false); together with ``calm`` it implies ``slow``, and both hold where ``slow`` applies."""
    text = """variables:
  armed: {type: bool}
  v: {type: int, min: 0, max: 10}
rules:
  - name: never_armed
    when: armed
    require: v > 20
  - name: calm
    when: not armed
    require: v <= 3
  - name: slow
    require: v <= 5
"""
    report = verify(parse_rules(text, source="u.yaml"))
    assert report.unsatisfiable == ["never_armed"]
    assert report.redundant == ["slow"]
    assert report.implied_by == {"slow": ["never_armed", "calm"]}
