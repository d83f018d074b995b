"""Rule expressions as z3 formulas over the declared variables.

``real`` variables become z3 reals, ``int`` integers, ``bool`` booleans; an ``enum`` becomes an
integer that ranges over the ids of its values (ids are shared by every enum and string literal,
so ``a == b`` on two enums compares their values by name). The declared ranges are constraints
returned by :meth:`Encoder.domain`, never baked into the variables, so a solver can also be asked
about points outside them.

z3 reasons over exact rationals: ``0.1`` is 1/10. The run-time engine evaluates the same rules
over Python floats, so the two can disagree only on values within rounding of a boundary.
Division by zero is undefined and, as in the property language, makes the comparison that reads
it false: :meth:`Encoder.condition` conjoins "every divisor is non-zero" to each comparison.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from fractions import Fraction
from typing import Any

import z3

from rasm.properties import ast
from rasm.properties.visitor import Visitor
from rasm.rules.model import Rule, Rules, Variable

#: At most this many combinations of values of finite plan fields are enumerated when asking
#: whether a context admits a plan; plan fields beyond are quantified (z3 decides both).
ENUMERATED_PLANS = 64


class Encoder:
    """Translate the expressions of one rule set into z3 terms (one encoder per rule set)."""

    def __init__(self, variables: dict[str, Variable]) -> None:
        self.variables = variables
        self.ids: dict[str, int] = {}
        self.terms: dict[str, z3.ExprRef] = {}
        for name, variable in variables.items():
            if variable.type == "real":
                self.terms[name] = z3.Real(name)
            elif variable.type == "bool":
                self.terms[name] = z3.Bool(name)
            else:
                self.terms[name] = z3.Int(name)
                for value in variable.values:
                    self.id(value)

    def id(self, value: str) -> int:
        """The integer standing for an enum value or string literal."""
        return self.ids.setdefault(value, len(self.ids))

    def domain(self, names: Any = None) -> list[z3.BoolRef]:
        """The declared domains of ``names`` (default: every variable) as constraints."""
        result: list[z3.BoolRef] = []
        for name in self.variables if names is None else names:
            variable, term = self.variables[name], self.terms[name]
            if variable.type == "enum":
                result.append(z3.Or(*[term == self.ids[v] for v in variable.values]))
            elif variable.type in ("real", "int"):
                if variable.minimum is not None:
                    result.append(term >= _number(variable.minimum))
                if variable.maximum is not None:
                    result.append(term <= _number(variable.maximum))
        return result

    def finite_values(self, name: str) -> list[z3.ExprRef] | None:
        """Every value of ``name``'s domain as a z3 constant, or None for an infinite or large
        domain (more than :data:`ENUMERATED_PLANS` values)."""
        variable = self.variables[name]
        if variable.type == "bool":
            return [z3.BoolVal(False), z3.BoolVal(True)]
        if variable.type == "enum":
            return [z3.IntVal(self.ids[v]) for v in variable.values]
        low, high = variable.minimum, variable.maximum
        if variable.type == "int" and low is not None and high is not None:
            if high - low < ENUMERATED_PLANS:
                return [z3.IntVal(v) for v in range(int(low), int(high) + 1)]
        return None

    def no_plan(self, body: z3.BoolRef, plan: Sequence[str]) -> z3.BoolRef:
        """"No value of the plan fields ``plan`` inside their domains makes ``body`` true", a
        formula over the other variables.

        Plan fields with few values (bool, enum, small int ranges: together at most
        :data:`ENUMERATED_PLANS` combinations) are enumerated, which keeps the question
        quantifier-free for them; the others are quantified.
        """
        finite: list[tuple[z3.ExprRef, list[z3.ExprRef]]] = []
        free: list[str] = []
        combinations = 1
        for name in plan:
            values = self.finite_values(name)
            if values is not None and combinations * len(values) <= ENUMERATED_PLANS:
                finite.append((self.terms[name], values))
                combinations *= len(values)
            else:
                free.append(name)
        bound = [self.terms[name] for name in free]
        cases = []
        for values in itertools.product(*(v for _, v in finite)):
            case = z3.substitute(body, *zip((t for t, _ in finite), values, strict=True))
            if bound:
                case = z3.Exists(bound, z3.And(*self.domain(free), case))
            cases.append(case)
        return z3.Not(z3.Or(*cases))

    def somewhere(self, expr: z3.BoolRef, plan: Sequence[str], tag: str) -> z3.BoolRef:
        """"Some value of the plan fields ``plan`` inside their domains makes ``expr`` true",
        without a quantifier: the plan fields are renamed apart (``tag`` makes the new names
        unique) and constrained to their domains."""
        if not plan:
            return expr
        copies = [(self.terms[n], z3.Const(f"{n}@{tag}", self.terms[n].sort())) for n in plan]
        domain = [z3.substitute(c, *copies) for c in self.domain(plan)]
        return z3.And(*domain, z3.substitute(expr, *copies))

    def rule(self, rule: Rule) -> tuple[z3.BoolRef, z3.BoolRef]:
        """The rule's ``when`` (True when left out) and ``require`` as z3 booleans."""
        when = z3.BoolVal(True) if rule.when is None else self.condition(rule.when)
        return when, self.condition(rule.require)

    def condition(self, expr: ast.Expr) -> z3.BoolRef:
        """A boolean expression as a z3 formula."""
        return _Condition(self).visit(expr)

    def value(self, expr: ast.Expr, guards: list[z3.BoolRef]) -> z3.ExprRef:
        """A numeric, enum or boolean value; divisors' non-zero conditions go to ``guards``."""
        return _Value(self).visit(expr, guards)

    def decode(self, model: z3.ModelRef, names: Any) -> dict[str, Any]:
        """Python values of ``names`` in ``model`` (enums by name, reals as floats)."""
        back = {i: v for v, i in self.ids.items()}
        result: dict[str, Any] = {}
        for name in names:
            variable, value = self.variables[name], model.eval(self.terms[name], True)
            if variable.type == "bool":
                result[name] = z3.is_true(value)
            elif variable.type == "int":
                result[name] = value.as_long()
            elif variable.type == "enum":
                result[name] = back.get(value.as_long(), variable.values[0])
            else:
                result[name] = _to_float(value)
        return result


class _Condition(Visitor[z3.BoolRef]):
    """A boolean expression as a z3 formula."""

    def __init__(self, encoder: Encoder) -> None:
        self.encoder = encoder

    def literal(self, expr: ast.Literal) -> z3.BoolRef:
        return z3.BoolVal(bool(expr.value))

    def name(self, expr: ast.Name) -> z3.BoolRef:
        return self.encoder.terms[expr.name]

    def not_(self, expr: ast.Not) -> z3.BoolRef:
        return z3.Not(self.visit(expr.operand))

    def binary(self, expr: ast.Binary) -> z3.BoolRef:
        if expr.op == "and":
            return z3.And(self.visit(expr.left), self.visit(expr.right))
        if expr.op == "or":
            return z3.Or(self.visit(expr.left), self.visit(expr.right))
        if expr.op == "->":
            return z3.Implies(self.visit(expr.left), self.visit(expr.right))
        return self.comparison(expr)

    def comparison(self, expr: ast.Binary) -> z3.BoolRef:
        guards: list[z3.BoolRef] = []
        left = self.encoder.value(expr.left, guards)
        right = self.encoder.value(expr.right, guards)
        op = expr.op
        if z3.is_bool(left) or z3.is_bool(right):
            left, right = self.as_bool(expr.left, left), self.as_bool(expr.right, right)
        if op == "==":
            result = left == right
        elif op == "!=":
            result = left != right
        elif op == "<":
            result = left < right
        elif op == "<=":
            result = left <= right
        elif op == ">":
            result = left > right
        else:
            result = left >= right
        return z3.And(*guards, result) if guards else result

    def as_bool(self, expr: ast.Expr, term: z3.ExprRef) -> z3.BoolRef:
        return term if z3.is_bool(term) else self.visit(expr)

    def _no_condition(self, expr: ast.Expr) -> z3.BoolRef:
        raise TypeError(f"not a rule condition: {expr!r}")  # the type checker rules this out

    unary = call = time = prev = past = future = since = until = aggregate = _no_condition


class _Value(Visitor[z3.ExprRef]):
    """A numeric, enum or boolean value; divisors' non-zero conditions go to ``guards``."""

    def __init__(self, encoder: Encoder) -> None:
        self.encoder = encoder

    def literal(self, expr: ast.Literal, guards: list[z3.BoolRef]) -> z3.ExprRef:
        value = expr.value
        if isinstance(value, bool):
            return z3.BoolVal(value)
        if isinstance(value, str):
            return z3.IntVal(self.encoder.id(value))
        return _number(value)

    def name(self, expr: ast.Name, guards: list[z3.BoolRef]) -> z3.ExprRef:
        return self.encoder.terms[expr.name]

    def unary(self, expr: ast.Unary, guards: list[z3.BoolRef]) -> z3.ExprRef:
        return -self.visit(expr.operand, guards)

    def call(self, expr: ast.Call, guards: list[z3.BoolRef]) -> z3.ExprRef:
        args = [self.visit(arg, guards) for arg in expr.args]
        if expr.func == "abs":
            return z3.If(args[0] >= 0, args[0], -args[0])
        a, b = _same_sort(args[0], args[1])
        if expr.func == "min":
            return z3.If(a <= b, a, b)
        return z3.If(a >= b, a, b)

    def binary(self, expr: ast.Binary, guards: list[z3.BoolRef]) -> z3.ExprRef:
        if expr.op not in ast.ARITHMETIC:
            return self.encoder.condition(expr)
        left, right = self.visit(expr.left, guards), self.visit(expr.right, guards)
        if expr.op == "+":
            return left + right
        if expr.op == "-":
            return left - right
        if expr.op == "*":
            return left * right
        left, right = z3.ToReal(left) if _is_int(left) else left, right
        right = z3.ToReal(right) if _is_int(right) else right
        guards.append(right != 0)
        return left / right

    def _condition(self, expr: ast.Expr, guards: list[z3.BoolRef]) -> z3.ExprRef:
        return self.encoder.condition(expr)

    not_ = time = prev = past = future = since = until = aggregate = _condition


def _number(value: int | float) -> z3.ArithRef:
    if isinstance(value, int):
        return z3.IntVal(value)
    # Fraction(float) is the float's exact binary value; str() gives the decimal the user wrote.
    return z3.RealVal(str(Fraction(repr(value))))


def _is_int(term: z3.ExprRef) -> bool:
    return z3.is_arith(term) and term.sort() == z3.IntSort()


def _same_sort(a: z3.ExprRef, b: z3.ExprRef) -> tuple[z3.ExprRef, z3.ExprRef]:
    if _is_int(a) and not _is_int(b):
        return z3.ToReal(a), b
    if _is_int(b) and not _is_int(a):
        return a, z3.ToReal(b)
    return a, b


def _to_float(value: z3.ExprRef) -> float:
    if z3.is_rational_value(value):
        return float(Fraction(value.numerator_as_long(), value.denominator_as_long()))
    if z3.is_algebraic_value(value):  # an irrational root from nonlinear arithmetic
        return float(value.approx(20).as_fraction())
    return float(value.as_fraction())


def encode_rules(rules: Rules) -> tuple[Encoder, list[tuple[z3.BoolRef, z3.BoolRef]]]:
    """An encoder for ``rules`` and each rule's (when, require) formulas, in file order."""
    encoder = Encoder(rules.variables)
    return encoder, [encoder.rule(rule) for rule in rules.rules]
