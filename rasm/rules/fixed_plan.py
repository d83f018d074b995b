"""Is a fixed plan legitimate in every context the rules admit? (a fallback action's proof)

A fallback action is sent when nothing else can be trusted, so it must be legitimate whatever
the context: for the variables the action sets, its values; for every other variable, any value
of its declared domain. z3 looks for a point of the domains where the action's values are fixed
and some rule breaks; none is the proof, one is the counterexample context.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import z3

from rasm.rules.engine import CompiledRules
from rasm.rules.model import Rules
from rasm.rules.mus import check, new_solver
from rasm.rules.report import format_context, format_value
from rasm.rules.smt import Encoder, _number

__all__ = ["FixedPlanProof", "prove_fixed_plan"]


@dataclass(frozen=True)
class FixedPlanProof:
    """The answer for one plan: ``legitimate`` in every context, or a ``context`` (values of the
    variables the plan does not set) where the rules named in ``broken`` break."""

    legitimate: bool
    context: dict[str, Any] = field(default_factory=dict)
    broken: tuple[str, ...] = ()
    reason: str = ""

    def explanation(self) -> str:
        """One line: why the plan is not legitimate everywhere ('' when it is)."""
        if self.legitimate:
            return ""
        if self.reason:
            return self.reason
        where = format_context(self.context) if self.context else "any context"
        return f"breaks {', '.join(self.broken)} where {where}"


def prove_fixed_plan(rules: Rules, values: Mapping[str, Any]) -> FixedPlanProof:
    """Whether the plan ``values`` satisfies every rule in every context of the declared domains.

    Keys that are no variable of ``rules`` are not the rules' business and are ignored. A value
    outside its variable's declared domain (or of the wrong type) can never be legitimate.
    Raises :class:`~rasm.rules.mus.SolverGaveUp` if z3 cannot decide (never a guessed answer).
    """
    fixed = {name: value for name, value in values.items() if name in rules.variables}
    for name, value in fixed.items():
        variable = rules.variables[name]
        if not variable.contains(value):
            return FixedPlanProof(
                False,
                reason=f"{name} = {format_value(value)} is not a value of {variable.describe()}",
            )
    encoder = Encoder(rules.variables)
    solver = new_solver()
    free = [name for name in rules.variables if name not in fixed]
    solver.add(*encoder.domain(free))
    for name, value in fixed.items():
        solver.add(encoder.terms[name] == _constant(encoder, rules.variables[name].type, value))
    holds = [z3.Implies(*encoder.rule(rule)) for rule in rules.rules]
    solver.add(z3.Not(z3.And(*holds)) if holds else z3.BoolVal(False))
    if not check(solver):
        return FixedPlanProof(True)
    context = encoder.decode(solver.model(), free)
    decision = CompiledRules(rules).evaluate(dict(fixed), context)
    # z3's exact rationals and Python floats agree except within rounding of a boundary
    broken = decision.broken or tuple(rules.names)
    return FixedPlanProof(False, context, broken)


def _constant(encoder: Encoder, kind: str, value: Any) -> z3.ExprRef:
    if kind == "bool":
        return z3.BoolVal(value)
    if kind == "enum":
        return z3.IntVal(encoder.id(value))
    return _number(value)
