"""Evaluating the non-temporal expression sub-language (shared with legitimacy rules).

Arithmetic follows IEEE-754 binary64 and never raises: a result beyond the largest float is
±inf (also when an int too large for a float meets a float: the exact result is rounded), and
undefined results (``x / 0``, ``inf - inf``, arithmetic on an undefined value) are *undefined*,
represented as ``float("nan")``. Every comparison with an undefined operand is **false** (also
``!=``), so a rule or property built on it fails rather than crashing the caller. Values of
the wrong type in ``env`` (e.g. a string where a number is needed) raise
:class:`~rasm.errors.SpecError` naming the expression's location.
"""

from __future__ import annotations

import math
import operator
import sys
from collections.abc import Callable, Mapping
from fractions import Fraction
from typing import NoReturn

from rasm.errors import SpecError
from rasm.properties.ast import Binary, Call, Expr, Literal, Name, Not, Unary
from rasm.properties.visitor import Visitor

__all__ = ["NAN", "compile_expression", "evaluate", "python_source", "HELPERS"]

NAN = math.nan
INF = math.inf


def _add(a, b):
    try:
        return a + b
    except OverflowError:  # an int too large for a float, with a float
        return _overflowed(operator.add, a, b)


def _sub(a, b):
    try:
        return a - b
    except OverflowError:
        return _overflowed(operator.sub, a, b)


def _mul(a, b):
    try:
        return a * b
    except OverflowError:
        return _overflowed(operator.mul, a, b)


def _div(a, b):
    try:
        return a / b
    except ZeroDivisionError:
        return NAN
    except OverflowError:  # an int too large for a float, or an int quotient beyond the largest
        return NAN if b == 0 else _overflowed(operator.truediv, a, b)


def _overflowed(op, a, b) -> float:
    """``op(a, b)`` when Python raised OverflowError (an int too large for a float): what
    IEEE-754 gives, the exact result rounded to the nearest float, ±inf beyond the largest.
    An infinite or undefined float operand decides the result as any finite number would."""
    if a != a or b != b:
        return NAN
    if _infinite(a) or _infinite(b):
        return op(_as_float(a), _as_float(b))
    exact = op(Fraction(a), Fraction(b))
    try:
        return float(exact)
    except OverflowError:
        return INF if exact > 0 else -INF


def _infinite(value) -> bool:
    return isinstance(value, float) and math.isinf(value)


def _as_float(value) -> float:
    try:
        return float(value)
    except OverflowError:  # a huge int: the largest float of its sign stands in for it
        return sys.float_info.max if value > 0 else -sys.float_info.max


def _ne(a, b) -> bool:
    # undefined (nan) compares false under every operator, != included
    return a == a and b == b and a != b


def _min2(a, b):
    if a != a or b != b:
        return NAN
    return a if a <= b else b


def _max2(a, b):
    if a != a or b != b:
        return NAN
    return a if a >= b else b


HELPERS: dict[str, object] = {
    "_add": _add, "_sub": _sub, "_mul": _mul, "_div": _div,
    "_ne": _ne, "_min2": _min2, "_max2": _max2, "NAN": NAN,
}

_ARITH = {"+": _add, "-": _sub, "*": _mul, "/": _div}
_ARITH_NAMES = {"+": "_add", "-": "_sub", "*": "_mul", "/": "_div"}
_COMPARE = {
    "==": lambda a, b: a == b,
    "!=": _ne,
    "<": lambda a, b: a < b,
    "<=": lambda a, b: a <= b,
    ">": lambda a, b: a > b,
    ">=": lambda a, b: a >= b,
}


def evaluate(expr: Expr, env: Mapping[str, object]) -> object:
    """Evaluate a non-temporal expression directly (slow, plain; see :func:`compile_expression`)."""
    try:
        return _Evaluate(env).visit(expr)
    except (TypeError, ValueError) as exc:
        raise SpecError(f"{expr.location}: cannot evaluate: {exc}") from None


def _temporal(self: Visitor, node: Expr) -> NoReturn:
    # the passes' method for every temporal node: the sub-language has none
    raise SpecError(f"{node.location}: temporal operator not allowed here")


class _Evaluate(Visitor[object]):
    """A node's value, its operands evaluated only as far as needed (``p and q`` reads no
    ``q`` where ``p`` is false)."""

    def __init__(self, env: Mapping[str, object]) -> None:
        self.env = env

    def literal(self, node: Literal) -> object:
        return node.value

    def name(self, node: Name) -> object:
        try:
            return self.env[node.name]
        except KeyError:
            raise SpecError(f"{node.location}: no value for {node.name!r}") from None

    def not_(self, node: Not) -> object:
        return not self.visit(node.operand)

    def unary(self, node: Unary) -> object:
        return -self.visit(node.operand)

    def binary(self, node: Binary) -> object:
        op = node.op
        if op == "and":
            return bool(self.visit(node.left)) and bool(self.visit(node.right))
        if op == "or":
            return bool(self.visit(node.left)) or bool(self.visit(node.right))
        if op == "->":
            return (not self.visit(node.left)) or bool(self.visit(node.right))
        left, right = self.visit(node.left), self.visit(node.right)
        if op in _ARITH:
            return _ARITH[op](left, right)
        return _COMPARE[op](left, right)

    def call(self, node: Call) -> object:
        args = [self.visit(a) for a in node.args]
        if node.func == "abs" and len(args) == 1:
            return abs(args[0])
        if node.func == "min" and len(args) == 2:
            return _min2(*args)
        if node.func == "max" and len(args) == 2:
            return _max2(*args)
        raise SpecError(f"{node.location}: unknown function {node.func!r}")

    time = prev = past = future = since = until = aggregate = _temporal


class _Source(Visitor[str]):
    """Python source computing a node."""

    def __init__(self, name: Callable[[str], str]) -> None:
        self.read = name  # the source reading a signal

    def literal(self, node: Literal) -> str:
        return repr(node.value)

    def name(self, node: Name) -> str:
        return self.read(node.name)

    def not_(self, node: Not) -> str:
        return f"(not {self.visit(node.operand)})"

    def unary(self, node: Unary) -> str:
        return f"(-{self.visit(node.operand)})"

    def binary(self, node: Binary) -> str:
        left, right = self.visit(node.left), self.visit(node.right)
        op = node.op
        if op == "and":
            return f"({left} and {right})"
        if op == "or":
            return f"({left} or {right})"
        if op == "->":
            return f"((not {left}) or {right})"
        if op in _ARITH_NAMES:
            return f"{_ARITH_NAMES[op]}({left}, {right})"
        if op == "!=":
            return f"_ne({left}, {right})"
        return f"({left} {op} {right})"

    def call(self, node: Call) -> str:
        args = [self.visit(a) for a in node.args]
        if node.func == "abs" and len(args) == 1:
            return f"abs({args[0]})"
        if node.func in ("min", "max") and len(args) == 2:
            return f"_{node.func}2({', '.join(args)})"
        raise SpecError(f"{node.location}: unknown function {node.func!r}")

    time = prev = past = future = since = until = aggregate = _temporal


def python_source(node: Expr, name: Callable[[str], str]) -> str:
    """Python source computing ``node``; ``name(signal)`` gives the source reading a signal."""
    return _Source(name).visit(node)


def compile_expression(expr: Expr) -> Callable[[Mapping[str, object]], object]:
    """Compile a non-temporal expression once into a fast function of an environment.

    Same results as :func:`evaluate`; a missing name or a badly typed value raises
    :class:`~rasm.errors.SpecError`.
    """
    body = python_source(expr, lambda n: f"env[{n!r}]")
    source = (
        "def _compiled(env):\n"
        "    try:\n"
        f"        return {body}\n"
        "    except KeyError as exc:\n"
        "        raise SpecError(f'{LOCATION}: no value for {exc.args[0]!r}') from None\n"
        "    except (TypeError, ValueError) as exc:\n"
        "        raise SpecError(f'{LOCATION}: cannot evaluate: {exc}') from None\n"
    )
    namespace = dict(HELPERS, SpecError=SpecError, LOCATION=str(expr.location))
    exec(compile(source, f"<rasm expression at {expr.location}>", "exec"), namespace)
    function = namespace["_compiled"]
    function.__doc__ = f"Compiled from {expr.location}."
    return function
