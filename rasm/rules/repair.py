"""The nearest legitimate plan: z3 repairs a rejected plan as little as it can.

The plan's fields that are rule variables may change; every other rule variable keeps its value
in the current context. "Nearest" is lexicographic: first as few enum and bool fields changed as
possible (each change costs its weight), then the smallest weighted distance of the numbers
(``sum(weight * abs(new - old))``). Weights default to 1. z3's answer is checked again by the
run-time engine, so a repair is only ever a plan the rules accept in that context.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import z3

from rasm.rules.engine import CompiledRules
from rasm.rules.model import Rules, Variable
from rasm.rules.smt import Encoder, _number

__all__ = ["REPAIR_TIMEOUT_MS", "Repair", "nearest_plan", "repair_cost"]

#: How long z3 may look for the nearest plan (it runs inside the loop's plan stage).
REPAIR_TIMEOUT_MS = 500


@dataclass(frozen=True)
class Repair:
    """A repaired plan: ``values`` (the rejected plan's, with ``changed`` fields replaced)."""

    values: dict[str, Any]
    changed: tuple[str, ...]
    cost: tuple[float, float]  # (enum and bool changes, numeric distance), both weighted


def repair_cost(
    variables: Mapping[str, Variable],
    old: Mapping[str, Any],
    new: Mapping[str, Any],
    weights: Mapping[str, float] | None = None,
) -> tuple[float, float]:
    """The (changes, distance) of moving plan ``old`` to ``new``, the order :func:`nearest_plan`
    minimises (the fields of ``old`` that are variables)."""
    weights = weights or {}
    changes = distance = 0.0
    for name, value in old.items():
        variable = variables.get(name)
        if variable is None:
            continue
        weight = weights.get(name, 1.0)
        if variable.type in ("enum", "bool"):
            changes += weight * (new[name] != value)
        elif _numeric(value):
            distance += weight * abs(new[name] - value)
    return changes, distance


def nearest_plan(
    rules: Rules,
    plan: Mapping[str, Any],
    context: Mapping[str, Any],
    weights: Mapping[str, float] | None = None,
    *,
    timeout_ms: int = REPAIR_TIMEOUT_MS,
) -> Repair | None:
    """The plan nearest to ``plan`` that every rule accepts in ``context``, or None (none exists,
    z3 gave up in time, or the engine does not accept z3's answer: fail closed)."""
    weights = weights or {}
    fields = [name for name in plan if name in rules.variables]
    if not fields:
        return None
    encoder = Encoder(rules.variables)
    opt = z3.Optimize()
    opt.set("timeout", timeout_ms)
    opt.add(*encoder.domain(fields))
    for name, variable in rules.variables.items():
        if name in plan:
            continue
        value = context.get(name)
        if value is not None and variable.contains(value):
            opt.add(encoder.terms[name] == _constant(encoder, variable, value))
        else:  # no usable value: left free here, and the engine's check below decides
            opt.add(*encoder.domain([name]))
    for rule in rules.rules:
        opt.add(z3.Implies(*encoder.rule(rule)))
    changes: list[z3.ArithRef] = []
    distance: list[z3.ArithRef] = []
    for name in fields:
        variable, term, old = rules.variables[name], encoder.terms[name], plan[name]
        weight = _number(float(weights.get(name, 1.0)))
        if variable.type in ("enum", "bool"):
            if variable.contains(old):
                changed = term != _constant(encoder, variable, old)
                changes.append(z3.If(changed, weight, _number(0.0)))
        elif _numeric(old):
            diff = term - _number(old)
            distance.append(weight * z3.If(diff >= 0, diff, -diff))
    opt.minimize(z3.Sum(changes) if changes else _number(0.0))
    opt.minimize(z3.Sum(distance) if distance else _number(0.0))
    if opt.check() != z3.sat:
        return None
    found = encoder.decode(opt.model(), fields)
    values = {**plan, **found}
    if not CompiledRules(rules).evaluate(values, context).accepted:
        return None  # z3's rationals and the engine's floats disagree at a boundary
    changed = tuple(name for name in fields if not _same(plan[name], found[name]))
    return Repair(values, changed, repair_cost(rules.variables, plan, values, weights))


def _constant(encoder: Encoder, variable: Variable, value: Any) -> z3.ExprRef:
    if variable.type == "bool":
        return z3.BoolVal(value)
    if variable.type == "enum":
        return z3.IntVal(encoder.id(value))
    return _number(value)


def _numeric(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and value == value


def _same(a: Any, b: Any) -> bool:
    return type(a) is type(b) and a == b or (_numeric(a) and _numeric(b) and a == b)
