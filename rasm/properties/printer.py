"""Printing syntax trees back as property-language text (for explanations and messages)."""

from __future__ import annotations

import math

from rasm.properties.ast import (
    INF,
    Aggregate,
    Binary,
    Bound,
    Call,
    Expr,
    Future,
    Literal,
    Name,
    Not,
    Past,
    Prev,
    Since,
    Time,
    Unary,
    Until,
)
from rasm.properties.times import format_nanoseconds
from rasm.properties.visitor import Transformer

__all__ = ["unparse", "format_value"]

# loosest first, as in grammar.lark
_LEVEL = {"->": 1, "or": 2, "and": 3, "since": 4, "until": 4, "unary": 5, "compare": 6,
          "+": 7, "-": 7, "*": 8, "/": 8, "neg": 9, "atom": 10}
_COMPARE = ("==", "!=", "<", "<=", ">", ">=")


def _bound(bound: Bound, default_unbounded: bool = True) -> str:
    if default_unbounded and bound.low_ns == 0 and bound.high_ns == INF:
        return ""
    return f"[{_seconds(bound.low_ns)}, {_seconds(bound.high_ns)}]"


def _seconds(ns: int | float) -> str:
    """Exact nanoseconds as the shortest decimal number of seconds: 1500000000 is 1.5."""
    return "inf" if ns == INF else format_nanoseconds(ns)


def format_value(value: object) -> str:
    """A value as the language writes it: true/false, "text", numbers, undefined."""
    if value is True:
        return "true"
    if value is False:
        return "false"
    if value is None:
        return "inconclusive"
    if isinstance(value, float) and math.isnan(value):
        return "undefined"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return f"{value:.1f}"
    return str(value)


# a node printed: how tightly its text binds (a _LEVEL), and the text
Printed = tuple[int, str]


def _wrap(printed: Printed, minimum: int) -> str:
    level, text = printed
    return f"({text})" if level < minimum else text


class _Printer(Transformer[Printed]):
    """Each node's text, from its sub-expressions' (parentheses only where needed)."""

    def literal(self, node: Literal) -> Printed:
        value = node.value
        negative = isinstance(value, (int, float)) and value < 0
        return _LEVEL["neg" if negative else "atom"], format_value(value)

    def name(self, node: Name) -> Printed:
        return _LEVEL["atom"], node.name

    def time(self, node: Time) -> Printed:
        return _LEVEL["atom"], "time"

    def prev(self, node: Prev, operand: Printed) -> Printed:
        return _LEVEL["atom"], f"prev({operand[1]})"

    def not_(self, node: Not, operand: Printed) -> Printed:
        return _LEVEL["unary"], f"not {_wrap(operand, _LEVEL['unary'])}"

    def unary(self, node: Unary, operand: Printed) -> Printed:
        return _LEVEL["neg"], f"-{_wrap(operand, _LEVEL['neg'])}"

    def call(self, node: Call, *args: Printed) -> Printed:
        return _LEVEL["atom"], f"{node.func}({', '.join(text for _, text in args)})"

    def aggregate(self, node: Aggregate, operand: Printed) -> Printed:
        return _LEVEL["atom"], f"{node.op}{_bound(node.bound, False)}({operand[1]})"

    def past(self, node: Past | Future, operand: Printed) -> Printed:
        return _LEVEL["unary"], f"{node.op}{_bound(node.bound)} {_wrap(operand, _LEVEL['unary'])}"

    future = past

    def since(self, node: Since | Until, left: Printed, right: Printed) -> Printed:
        word = "since" if isinstance(node, Since) else "until"
        level = _LEVEL["since"]
        return level, f"{_wrap(left, level)} {word}{_bound(node.bound)} {_wrap(right, level + 1)}"

    until = since

    def binary(self, node: Binary, left: Printed, right: Printed) -> Printed:
        op = node.op
        if op in _COMPARE:
            level = _LEVEL["compare"]
            return level, f"{_wrap(left, level + 1)} {op} {_wrap(right, level + 1)}"
        level = _LEVEL[op]
        if op == "->":  # right-associative
            return level, f"{_wrap(left, level + 1)} -> {_wrap(right, level)}"
        return level, f"{_wrap(left, level)} {op} {_wrap(right, level + 1)}"


_PRINTER = _Printer()


def unparse(node: Expr) -> str:
    """Property-language text for ``node`` (parentheses only where needed)."""
    return _PRINTER.visit(node)[1]
