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

__all__ = ["unparse", "format_value"]

# loosest first, as in grammar.lark
_LEVEL = {"->": 1, "or": 2, "and": 3, "since": 4, "until": 4, "unary": 5, "compare": 6,
          "+": 7, "-": 7, "*": 8, "/": 8, "neg": 9, "atom": 10}
_COMPARE = ("==", "!=", "<", "<=", ">", ">=")


def _level(node: Expr) -> int:
    if isinstance(node, Binary):
        return _LEVEL["compare"] if node.op in _COMPARE else _LEVEL[node.op]
    if isinstance(node, (Since, Until)):
        return _LEVEL["since"]
    if isinstance(node, (Not, Past, Future)):
        return _LEVEL["unary"]
    if isinstance(node, Unary):
        return _LEVEL["neg"]
    if isinstance(node, Literal) and isinstance(node.value, (int, float)) and node.value < 0:
        return _LEVEL["neg"]
    return _LEVEL["atom"]


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


def _wrap(node: Expr, minimum: int) -> str:
    text = unparse(node)
    return f"({text})" if _level(node) < minimum else text


def unparse(node: Expr) -> str:  # noqa: C901 - one case per node
    """Property-language text for ``node`` (parentheses only where needed)."""
    if isinstance(node, Literal):
        return format_value(node.value)
    if isinstance(node, Name):
        return node.name
    if isinstance(node, Time):
        return "time"
    if isinstance(node, Prev):
        return f"prev({unparse(node.operand)})"
    if isinstance(node, Not):
        return f"not {_wrap(node.operand, _LEVEL['unary'])}"
    if isinstance(node, Unary):
        return f"-{_wrap(node.operand, _LEVEL['neg'])}"
    if isinstance(node, Call):
        return f"{node.func}({', '.join(unparse(a) for a in node.args)})"
    if isinstance(node, Aggregate):
        return f"{node.op}{_bound(node.bound, False)}({unparse(node.operand)})"
    if isinstance(node, (Past, Future)):
        return f"{node.op}{_bound(node.bound)} {_wrap(node.operand, _LEVEL['unary'])}"
    if isinstance(node, (Since, Until)):
        word = "since" if isinstance(node, Since) else "until"
        level = _LEVEL["since"]
        return (f"{_wrap(node.left, level)} {word}{_bound(node.bound)} "
                f"{_wrap(node.right, level + 1)}")
    if isinstance(node, Binary):
        level = _level(node)
        if node.op == "->":  # right-associative
            return f"{_wrap(node.left, level + 1)} -> {_wrap(node.right, level)}"
        if node.op in _COMPARE:
            return f"{_wrap(node.left, level + 1)} {node.op} {_wrap(node.right, level + 1)}"
        return f"{_wrap(node.left, level)} {node.op} {_wrap(node.right, level + 1)}"
    raise TypeError(f"not an expression node: {node!r}")
