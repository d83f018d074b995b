"""verify() against the brute-force oracle, on generated rule sets over finite domains."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings

from rasm.properties import evaluate
from rasm.rules import parse_rules, verify
from rasm.rules.split import guard_split

from .brute import Oracle, truth
from .gen import guarded_rules_files, rules_files

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


@SETTINGS
@given(rules_files())
def test_redundant_rules_match_enumeration(text):
    _, report, oracle = _judge(text)
    assert set(report.redundant) == oracle.redundant
    for name, support in report.implied_by.items():
        assert name not in support
        assert oracle.implies(support, name)
        assert oracle.consistent_with_when(support, name)


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


@SETTINGS
@given(guarded_rules_files())
def test_mode_guarded_rule_sets_are_split_by_context_without_losing_a_finding(text):
    rules, report, oracle = _judge(text)
    assert guard_split(rules.rules, rules.variables, range(len(rules.rules))) is not None
    assert {frozenset(c.rules) for c in report.conflicts} == oracle.conflicts
    assert set(report.redundant) == oracle.redundant
    assert set(report.unsatisfiable) == oracle.unsatisfiable
