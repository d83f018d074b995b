"""verify() on hand-written rule sets over reals and mixed domains (beyond brute force)."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.errors import RulesError
from rasm.properties import parse_expression
from rasm.rules import parse_rules, verify
from rasm.rules.against import check_properties

from .brute import Oracle, points, truth
from .gen import conditions, rules_files

HEAD = """\
variables:
  velocity: {type: real, min: 0, max: 1.0}
  rotation: {type: real, min: -360, max: 360}
  stops:    {type: int, min: 0, max: 10}
  mode:     {type: enum, values: [navigate, dock, idle]}
  other:    {type: enum, values: [dock, charge]}
  armed:    {type: bool}
rules:
"""


def report_of(*rules: str):
    return verify(parse_rules(HEAD + "".join(rules), source="r.yaml"))


def rule(name: str, require: str, when: str | None = None) -> str:
    text = f"  - name: {name}\n"
    if when is not None:
        text += f"    when: '{when}'\n"
    return text + f"    require: '{require}'\n"


def test_real_valued_conflict_with_a_witness_inside_the_domain():
    report = report_of(rule("a", "velocity * 2 >= 1.2", "rotation > 90"),
                       rule("b", "velocity + rotation / 360 <= 0.6"))
    assert [c.rules for c in report.conflicts] == [("a", "b")]
    context = report.conflicts[0].context
    assert context["rotation"] > 90 and 0 <= context["velocity"] <= 1.0


def test_a_rule_implied_by_the_domain_alone_is_redundant():
    report = report_of(rule("bounded", "velocity <= 5"), rule("other", "stops < 3"))
    assert report.redundant == ["bounded"] and report.implied_by == {"bounded": []}


def test_exact_rationals_at_a_boundary():
    # 0.1 + 0.2 <= 0.3 is false in floats but true in the rationals z3 uses (documented)
    report = report_of(rule("r", "velocity == 0.1", "velocity + 0.2 <= 0.3 and velocity >= 0.1"))
    assert report.unsatisfiable == [] and report.dead == []


def test_no_rule_appears_in_two_categories():
    report = report_of(
        rule("dead", "velocity < 0", "stops > 10"),
        rule("unsat", "velocity > 1", 'mode == "idle"'),
        rule("c1", "velocity <= 0.1", 'mode == "dock"'),
        rule("c2", "velocity >= 0.3", 'mode == "dock"'),
        rule("nav", "rotation <= 50", 'mode == "navigate"'),
        rule("red", "rotation <= 100", 'mode == "navigate" and armed'),
    )
    assert report.dead == ["dead"] and report.unsatisfiable == ["unsat"]
    assert [c.rules for c in report.conflicts] == [("c1", "c2")]
    assert report.redundant == ["red"] and report.implied_by["red"] == ["nav"]


def test_rules_that_never_apply_together_do_not_conflict():
    report = report_of(rule("dock", "velocity <= 0.1", 'mode == "dock"'),
                       rule("nav", "velocity >= 0.5", 'mode == "navigate"'))
    assert report.consistent and report.conflicts == []


def test_enums_compare_by_value_across_variables():
    report = report_of(rule("same", "mode == other"), rule("charge", 'other == "charge"'))
    assert [c.rules for c in report.conflicts] == [("same", "charge")]


def test_an_undecidable_rule_set_is_an_error_not_a_guess(monkeypatch):
    monkeypatch.setattr("rasm.rules.mus.SOLVER_TIMEOUT_MS", 300)
    text = ("variables:\n  a: {type: int}\n  b: {type: int}\n  c: {type: int}\nrules:\n"
            "  - name: fermat\n    require: a*a*a + b*b*b != c*c*c or a*b*c == 0\n"
            "  - name: positive\n    require: a > 0 and b > 0 and c > 0 and a*b > 1000000000\n")
    try:
        verify(parse_rules(text, source="f.yaml"))
    except RulesError as exc:  # z3 may give up on nonlinear integers; then it must say so
        assert "could not decide" in str(exc)


@pytest.mark.parametrize("count", [2, 5])
def test_many_pairwise_conflicts_are_all_found(count):
    rules = [rule(f"at_{k}", f"stops == {k}") for k in range(count)]
    report = report_of(*rules)
    assert len(report.conflicts) == count * (count - 1) // 2


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rules_files(max_rules=4), conditions)
def test_against_finds_an_admitted_violation_iff_one_exists(text, invariant):
    rules = parse_rules(text, source="gen.yaml")
    oracle = Oracle(rules)
    (violation,) = check_properties(rules, f"property p:\n    always ({invariant})\n")
    prop = parse_expression(invariant)
    admitted_bad = [p for i, p in enumerate(points(rules))
                    if all(oracle.holds[r.name][i] for r in rules.rules) and not truth(prop, p)]
    assert (violation.witness is not None) == bool(admitted_bad)
    if violation.witness is not None:
        point = violation.witness
        assert all(truth(r.require, point) for r in rules.rules if truth(r.when, point))
        assert not truth(prop, point)


@settings(max_examples=11, deadline=None)
@given(st.integers(0, 10))
def test_a_threshold_redundancy_chain_reports_all_but_the_strongest(k):
    rules = [rule(f"le_{j}", f"stops <= {j}") for j in range(k, 11)]
    report = report_of(*rules)
    # stops <= 10 is implied by the declared domain (max 10) even when it stands alone
    assert report.redundant == [f"le_{j}" for j in range(k, 11) if j > k or j == 10]


def test_against_judges_a_bare_invariant_and_skips_foreign_signals():
    rules = parse_rules(HEAD + rule("slow", "velocity <= 0.5"), source="r.yaml")
    props = ("property bare:\n    velocity <= 0.6\n"
             "property loose:\n    always (velocity <= 0.4)\n"
             "property foreign:\n    always (battery > 0.2)\n")
    bare, loose, foreign = check_properties(rules, props)
    assert bare.witness is None and bare.skipped is None
    assert loose.witness is not None and 0.4 < loose.witness["velocity"] <= 0.5
    assert foreign.skipped and "battery" in foreign.skipped
