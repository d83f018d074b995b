"""The run-time rule engine and the consistent-only rule-set swap."""

from __future__ import annotations

import math

import pytest
import z3
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.errors import RulesError
from rasm.rules import CompiledRules, RuleSet, parse_rules
from rasm.rules.smt import Encoder

from .brute import Oracle, points
from .gen import rules_files

RULES = """\
variables:
  velocity: {type: real, min: 0, max: 1.0}
  stops:    {type: int, min: 0, max: 10}
  mode:     {type: enum, values: [navigate, dock, idle]}
  armed:    {type: bool}
rules:
  - name: slow_docking
    when: mode == "dock"
    require: velocity <= 0.1
  - name: few_stops
    require: stops <= 5
  - name: armed_only_moving
    when: armed
    require: velocity > 0 and mode != "idle"
"""

INCONSISTENT = RULES + """\
  - name: fast_docking
    when: mode == "dock"
    require: velocity >= 0.5
"""

GOOD = {"velocity": 0.05, "stops": 2, "mode": "dock", "armed": True}


@pytest.fixture
def engine():
    return CompiledRules(parse_rules(RULES, source="r.yaml"))


def test_a_legitimate_plan_is_accepted(engine):
    decision = engine.evaluate(GOOD)
    assert decision.accepted and bool(decision) and decision.broken == ()


def test_a_rejected_plan_names_the_broken_rules_in_file_order(engine):
    decision = engine.evaluate({**GOOD, "velocity": 0.5, "stops": 9})
    assert not decision
    assert decision.broken == ("slow_docking", "few_stops")
    assert decision.reasons["slow_docking"] == "requires velocity <= 0.1"
    assert "slow_docking: requires velocity <= 0.1" in decision.explanation()


def test_plan_values_win_over_the_context(engine):
    decision = engine.evaluate({"velocity": 0.05}, {"velocity": 0.9, "stops": 1, "mode": "dock",
                                                    "armed": False})
    assert decision.accepted


def test_a_value_outside_its_domain_breaks_the_rules_reading_it(engine):
    decision = engine.evaluate({**GOOD, "stops": 11})
    assert decision.broken == ("few_stops",)
    assert "stops = 11 is not a value of int in [0, 10]" in decision.reasons["few_stops"]


def test_a_missing_value_breaks_a_rule_only_when_it_is_needed(engine):
    # armed is False: armed_only_moving does not apply, so its require's values are not needed
    decision = engine.evaluate({"stops": 1, "mode": "navigate", "armed": False})
    assert decision.accepted
    decision = engine.evaluate({"stops": 1, "mode": "dock", "armed": False})
    assert decision.broken == ("slow_docking",)
    assert decision.reasons["slow_docking"] == "no value for velocity"


WRONG = st.one_of(
    st.none(), st.text(max_size=3), st.binary(max_size=2), st.lists(st.integers(), max_size=2),
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**20, 10**20), st.booleans(),
    st.dictionaries(st.text(max_size=2), st.integers(), max_size=1),
)


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(st.fixed_dictionaries({}, optional={k: WRONG for k in GOOD}))
def test_any_plan_gets_a_decision_never_an_exception(plan):
    engine = CompiledRules(parse_rules(RULES, source="r.yaml"))
    decision = engine.evaluate(plan)
    assert decision.accepted == (not decision.broken)
    for name in decision.broken:
        assert decision.reasons[name]
    # a value of the wrong type for a variable is a rejection naming a rule that reads it
    if "velocity" in plan and not isinstance(plan["velocity"], int | float):
        if plan.get("mode") == "dock" or plan.get("armed") is True:
            assert not decision.accepted


def test_wrong_types_are_rejections_naming_the_rule(engine):
    decision = engine.evaluate({**GOOD, "velocity": "fast"})
    assert decision.broken == ("slow_docking", "armed_only_moving")
    decision = engine.evaluate({**GOOD, "armed": 1})  # 1 is not a bool
    assert decision.broken == ("armed_only_moving",)
    decision = engine.evaluate({**GOOD, "velocity": math.nan})
    assert "slow_docking" in decision.broken


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rules_files())
def test_engine_breaks_exactly_the_rules_whose_when_holds_and_require_fails(text):
    rules = parse_rules(text, source="gen.yaml")
    engine, oracle = CompiledRules(rules), Oracle(rules)
    for index, point in enumerate(points(rules)):
        expected = tuple(r.name for r in rules.rules
                         if oracle.when[r.name][index] and not oracle.require[r.name][index])
        assert engine.evaluate(point).broken == expected


@pytest.mark.slow
@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rules_files(max_rules=3))
def test_z3_translation_agrees_with_evaluation_at_every_point(text):
    rules = parse_rules(text, source="gen.yaml")
    encoder, oracle = Encoder(rules.variables), Oracle(rules)
    for index, point in enumerate(points(rules)):
        substitution = [
            (encoder.terms[n], z3.BoolVal(v) if isinstance(v, bool)
             else z3.IntVal(encoder.ids[v] if isinstance(v, str) else v))
            for n, v in point.items()
        ]
        for rule in rules.rules:
            when, require = encoder.rule(rule)
            assert z3.is_true(z3.simplify(z3.substitute(when, *substitution))) == \
                oracle.when[rule.name][index]
            assert z3.is_true(z3.simplify(z3.substitute(require, *substitution))) == \
                oracle.require[rule.name][index]


# --------------------------------------------------------------------------- swaps


def test_an_inconsistent_initial_set_is_refused():
    with pytest.raises(RulesError, match="rules 'slow_docking', 'fast_docking' conflict"):
        RuleSet(parse_rules(INCONSISTENT, source="bad.yaml"))


def test_require_consistent_false_allows_judging_a_broken_set():
    rule_set = RuleSet(parse_rules(INCONSISTENT, source="bad.yaml"), require_consistent=False)
    assert rule_set.evaluate({**GOOD, "velocity": 0.3}).broken == ("slow_docking",
                                                                   "fast_docking")


def test_a_consistent_swap_takes_effect():
    rule_set = RuleSet(parse_rules(RULES, source="old.yaml"))
    stricter = RULES.replace("velocity <= 0.1", "velocity <= 0.01")
    result = rule_set.swap(parse_rules(stricter, source="new.yaml"))
    assert result.accepted and result.report.consistent
    assert rule_set.rules.source == "new.yaml"
    assert rule_set.evaluate(GOOD).broken == ("slow_docking",)


def test_an_inconsistent_swap_is_refused_and_the_old_set_stays():
    rule_set = RuleSet(parse_rules(RULES, source="old.yaml"))
    result = rule_set.swap(parse_rules(INCONSISTENT, source="new.yaml"))
    assert not result.accepted
    assert "inconsistent" in result.reason and "'fast_docking'" in result.reason
    assert [list(c.rules) for c in result.report.conflicts] == [["slow_docking", "fast_docking"]]
    assert rule_set.rules.source == "old.yaml"
    assert rule_set.evaluate(GOOD).accepted


def test_a_swap_to_text_that_does_not_load_is_refused_with_the_place():
    rule_set = RuleSet(parse_rules(RULES, source="old.yaml"))
    result = rule_set.swap_text("variables: {}\nrules:\n  - name: r\n    require: q > 1\n",
                                source="new.yaml")
    assert not result.accepted and result.report is None
    assert "new.yaml:4:14: unknown variable 'q'" in result.reason
    assert rule_set.rules.source == "old.yaml"


def test_swap_file(tmp_path):
    rule_set = RuleSet(parse_rules(RULES, source="old.yaml"))
    bad, good = tmp_path / "bad.yaml", tmp_path / "good.yaml"
    bad.write_text(INCONSISTENT, encoding="utf-8")
    good.write_text(RULES, encoding="utf-8")
    assert not rule_set.swap_file(bad)
    assert not rule_set.swap_file(tmp_path / "absent.yaml")
    assert rule_set.rules.source == "old.yaml"
    assert rule_set.swap_file(good) and rule_set.rules.source == str(good)
    assert RuleSet.load(good).rules.source == str(good)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rules_files())
def test_a_swap_takes_effect_exactly_when_enumeration_finds_the_set_consistent(text):
    rule_set = RuleSet(parse_rules("variables: {}\nrules: []\n", source="empty.yaml"))
    new = parse_rules(text, source="gen.yaml")
    oracle = Oracle(new)
    consistent = not oracle.unsatisfiable and not oracle.conflicts
    assert rule_set.swap(new).accepted == consistent
    assert rule_set.rules.source == ("gen.yaml" if consistent else "empty.yaml")


def test_api_misuse_says_what_to_pass(tmp_path):
    # each of these failed deep inside: "'str' object has no attribute 'variables'" (smt.py),
    # "'NoneType' object is not subscriptable", "'PosixPath' object has no attribute 'splitlines'"
    from rasm.rules import load_rules, verify

    path = tmp_path / "rules.yaml"
    path.write_text(
        "variables:\n  v: {type: real, min: 0, max: 1}\n"
        "rules:\n  - name: r\n    require: v <= 0.5\n"
    )
    rules = load_rules(path)
    cases = [
        (lambda: verify(str(path)), "verify() takes Rules: load them with rasm.rules.load_rules("),
        (lambda: RuleSet(str(path)), "RuleSet() (or RuleSet.load(path) for a file) takes Rules"),
        (lambda: RuleSet(rules).swap("rules: []"), "swap() (or swap_text(text), swap_file(path))"),
        (lambda: CompiledRules(None), "CompiledRules() takes Rules"),
        (lambda: parse_rules(path), "parse_rules() takes the text of a rules file, not PosixPath"),
        (lambda: load_rules(path.read_text()), "load_rules() takes a path; for the text of a"),
        (lambda: load_rules(None), "load_rules() takes the path of a rules file, not NoneType"),
        (lambda: RuleSet(rules).evaluate(None), "evaluate(plan, context) takes dicts of values"),
        (lambda: RuleSet(rules).evaluate({"v": 0.1}, [1]), "evaluate(plan, context) takes dicts"),
    ]
    for call, message in cases:
        with pytest.raises(TypeError) as caught:
            call()
        assert str(caught.value).startswith(message), str(caught.value)
    assert RuleSet(rules).evaluate({"v": 0.1}).accepted


def test_a_rules_file_is_proved_once_and_reloaded_when_its_bytes_change(tmp_path):
    path = tmp_path / "r.yaml"
    path.write_text(RULES, encoding="utf-8")
    first = RuleSet.load(path)
    again = RuleSet.load(path)
    assert again.rules is first.rules  # same bytes: parsed and proved once
    assert again is not first  # but each caller gets its own (swappable) rule set
    assert again.report is first.report and again.report.consistent
    # same length, written at once (a modification time can stay the same): still reloaded
    path.write_text(RULES.replace("<= 5", "<= 4"), encoding="utf-8")
    changed = RuleSet.load(path)
    assert not changed.evaluate({**GOOD, "stops": 5}).accepted
    assert first.evaluate({**GOOD, "stops": 5}).accepted
    path.write_text(INCONSISTENT, encoding="utf-8")
    with pytest.raises(RulesError):
        RuleSet.load(path)


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


def test_a_rule_sets_plan_fields_hold_for_its_load_and_every_swap(tmp_path):
    path = tmp_path / "dock.yaml"
    path.write_text(DOCKING, encoding="utf-8")
    with pytest.raises(RulesError, match="'dock_when_low', 'keep_moving' conflict"):
        RuleSet.load(path)  # without plan fields every variable is context
    rule_set = RuleSet.load(path, plan_fields=["dock", "speed"])
    assert rule_set.rules.plan_fields == ["dock", "speed"]
    assert rule_set.evaluate({"dock": True, "speed": 0.0}, {"battery": 5.0}).accepted
    assert rule_set.evaluate({"dock": False, "speed": 0.5}, {"battery": 5.0}).broken == (
        "dock_when_low",
    )
    # a new version is judged with the same plan fields
    result = rule_set.swap_text(DOCKING.replace(">= 0.2", ">= 0.3"), source="v2.yaml")
    assert result.accepted, result.reason
    assert rule_set.rules.plan_fields == ["dock", "speed"]
    stuck = DOCKING + "  - name: never_docked\n    when: dock\n    require: false\n"
    result = rule_set.swap_text(stuck, source="v3.yaml")
    assert not result.accepted and "rules 'dock_when_low', 'never_docked' conflict" in result.reason
    assert rule_set.rules.source == "v2.yaml"
