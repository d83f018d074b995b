"""z3's proof that a fixed plan (the fallback actions) is legitimate in every context the rules
admit, checked against brute force over the small finite domains of ``gen.VARIABLES``."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.rules import CompiledRules, parse_rules
from rasm.rules.fixed_plan import prove_fixed_plan

from .gen import rules_files

DOMAINS = {"x": range(0, 4), "y": range(-2, 3), "m": ("a", "b", "c"), "f": (False, True)}

fixed_plans = st.fixed_dictionaries(
    {},
    optional={
        "x": st.integers(0, 3),
        "y": st.integers(-2, 2),
        "m": st.sampled_from("abc"),
        "f": st.booleans(),
    },
)


def contexts(fixed):
    free = [name for name in DOMAINS if name not in fixed]
    for values in itertools.product(*(DOMAINS[name] for name in free)):
        yield dict(zip(free, values, strict=True))


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(rules_files(), fixed_plans)
def test_the_proof_agrees_with_every_context_of_the_domains(text, plan):
    rules = parse_rules(text)
    engine = CompiledRules(rules)
    proof = prove_fixed_plan(rules, plan)
    breaking = [ctx for ctx in contexts(plan) if not engine.evaluate(plan, ctx).accepted]
    assert proof.legitimate == (not breaking)
    if not proof.legitimate:
        # the witness is a context of the domains where the plan breaks the named rules
        decision = engine.evaluate(plan, proof.context)
        assert not decision.accepted
        assert set(proof.broken) == set(decision.broken)
        assert set(proof.context) == set(DOMAINS) - set(plan)


def test_a_value_outside_its_domain_is_never_legitimate():
    rules = parse_rules("variables:\n  x: {type: int, min: 0, max: 3}\nrules:\n"
                        "  - name: any\n    require: true\n")
    proof = prove_fixed_plan(rules, {"x": 7})
    assert not proof.legitimate
    assert proof.explanation() == "x = 7 is not a value of int in [0, 3]"


def test_keys_the_rules_do_not_declare_are_not_their_business():
    rules = parse_rules("variables:\n  x: {type: int, min: 0, max: 3}\nrules:\n"
                        "  - name: low\n    require: x <= 1\n")
    assert prove_fixed_plan(rules, {"x": 0, "colour": "red"}).legitimate
    proof = prove_fixed_plan(rules, {"colour": "red"})  # x is then any value of its domain
    assert not proof.legitimate and proof.broken == ("low",) and proof.context["x"] > 1


def test_the_explanation_writes_values_as_the_rules_do():
    rules = parse_rules("variables:\n  docked: {type: bool}\n  mode: {type: enum, values: [a, b]}\n"
                        "  v: {type: int, min: 0, max: 3}\nrules:\n"
                        "  - name: still_unless_docked\n    when: not docked and mode == \"a\"\n"
                        "    require: v == 0\n")
    proof = prove_fixed_plan(rules, {"v": 2})
    assert proof.explanation() == (
        'breaks still_unless_docked where docked == false, mode == "a"'
    )
    proof = prove_fixed_plan(rules, {"v": 0, "docked": 1})
    assert proof.explanation() == "docked = 1 is not a value of bool"
    proof = prove_fixed_plan(rules, {"v": True})
    assert proof.explanation() == "v = true is not a value of int in [0, 3]"
