"""The nearest legitimate plan, against brute force over the small finite domains of
``gen.VARIABLES``: a repair satisfies every rule in its context and no plan the test can find
is nearer; when brute force finds no legitimate plan, there is no repair."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.rules import CompiledRules, parse_rules
from rasm.rules.repair import nearest_plan, repair_cost

from .gen import rules_files

DOMAINS = {"x": range(0, 4), "y": range(-2, 3), "m": ("a", "b", "c"), "f": (False, True)}
VALUES = {
    "x": st.integers(-1, 5),  # a rejected plan may leave the domain
    "y": st.integers(-2, 2),
    "m": st.sampled_from("abc"),
    "f": st.booleans(),
}


@st.composite
def situations(draw):
    """(plan, context, weights): the variables split between the plan and the context."""
    names = list(DOMAINS)
    in_plan = draw(st.lists(st.sampled_from(names), min_size=1, unique=True))
    plan = {name: draw(VALUES[name]) for name in in_plan}
    context = {name: draw(st.sampled_from(DOMAINS[name])) for name in names if name not in plan}
    weights = draw(st.dictionaries(st.sampled_from(in_plan), st.sampled_from([0.5, 1.0, 3.0])))
    return plan, context, weights


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(rules_files(), situations())
def test_a_repair_is_legitimate_and_no_legitimate_plan_is_nearer(text, situation):
    plan, context, weights = situation
    rules = parse_rules(text)
    engine = CompiledRules(rules)
    candidates = [
        dict(zip(plan, values, strict=True))
        for values in itertools.product(*(DOMAINS[name] for name in plan))
    ]
    legitimate = [c for c in candidates if engine.evaluate(c, context).accepted]
    repair = nearest_plan(rules, plan, context, weights)
    if not legitimate:
        assert repair is None
        return
    assert repair is not None
    assert engine.evaluate(repair.values, context).accepted
    best = min(repair_cost(rules.variables, plan, c, weights) for c in legitimate)
    assert repair.cost == best
    assert repair.cost == repair_cost(rules.variables, plan, repair.values, weights)
    assert set(repair.changed) == {n for n in plan if repair.values[n] != plan[n]}


HEATER = """variables:
  mode:        {type: enum, values: [normal, boost]}
  setpoint:    {type: real, min: 0, max: 100}
  power_limit: {type: real, min: 0, max: 200}
  temperature: {type: real, min: -40, max: 150}
rules:
  - name: heater_rating
    require: power_limit <= 100
  - name: safe_setpoint
    require: setpoint >= 35 and setpoint <= 39.5
  - name: normal_power
    when: mode == "normal"
    require: power_limit <= 70
  - name: no_boost_when_hot
    when: mode == "boost"
    require: temperature <= 39
"""


def test_enums_are_kept_where_possible_and_numbers_moved_the_least():
    rules = parse_rules(HEATER)
    plan = {"mode": "boost", "setpoint": 41.0, "power_limit": 120.0, "note": "kept"}
    repair = nearest_plan(rules, plan, {"temperature": 36.0})
    assert repair is not None
    assert repair.values == {"mode": "boost", "setpoint": 39.5, "power_limit": 100.0,
                             "note": "kept"}
    assert repair.changed == ("setpoint", "power_limit")
    # too hot to boost: the enum must change, and then normal_power bounds the power
    repair = nearest_plan(rules, plan, {"temperature": 39.5})
    assert repair is not None and repair.values["mode"] == "normal"
    assert repair.values["power_limit"] == 70.0


def test_weights_choose_which_field_moves():
    rules = parse_rules("""variables:
  a: {type: real, min: 0, max: 10}
  b: {type: real, min: 0, max: 10}
rules:
  - name: sum
    require: a + b <= 10
""")
    plan = {"a": 8.0, "b": 8.0}
    cheap_a = nearest_plan(rules, plan, {}, {"b": 5.0})
    assert cheap_a is not None and cheap_a.values == {"a": 2.0, "b": 8.0}
    cheap_b = nearest_plan(rules, plan, {}, {"a": 5.0})
    assert cheap_b is not None and cheap_b.values == {"a": 8.0, "b": 2.0}


def test_no_repair_when_the_context_admits_no_plan():
    rules = parse_rules(HEATER)
    # the context is outside its domain: every rule reading it breaks, whatever the plan
    assert nearest_plan(rules, {"mode": "boost"}, {"temperature": 500.0}) is None
