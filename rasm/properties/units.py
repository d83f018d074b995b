"""Exact time in the generated code: which values are times, and their source in each unit.

``time`` is exact (:func:`is_time`): its value is the record's time in integer nanoseconds
(``tn``), and so are the sums, differences, negations, ``abs``, ``min``, ``max`` and ``prev`` of
times; a number they meet is read as a time (to the nanosecond) and a comparison with one is
made in nanoseconds. Where a time meets anything else (``*``, ``/``, an aggregate, the value of
a probe) it becomes the float nearest its seconds. So ``time - prev(time) >= 0.2`` holds at 0.3
after 0.1, as ``once[0.2, 0.2]`` does.
"""

from __future__ import annotations

import math
from fractions import Fraction

from rasm.errors import SourceError
from rasm.properties.ast import Expr, Literal, Time, children
from rasm.properties.printer import unparse
from rasm.properties.times import NS_PER_SECOND, from_nanoseconds, nanoseconds
from rasm.properties.visitor import Visitor

__all__ = ["HELPERS", "in_nanoseconds", "in_seconds", "is_time", "looks_ahead"]


class _IsTime(Visitor[bool]):
    """Whether a node's value is a time or a duration, carried as exact nanoseconds."""

    def time(self, node) -> bool:
        return True

    def prev(self, node) -> bool:
        return self.visit(node.operand)

    unary = prev

    def binary(self, node) -> bool:
        return node.op in ("+", "-") and self._of_times(node)

    def call(self, node) -> bool:
        return self._of_times(node)

    def _of_times(self, node) -> bool:
        return any(map(self.visit, children(node))) and not looks_ahead(node)

    def _never(self, node) -> bool:
        return False

    literal = name = not_ = past = future = since = until = aggregate = _never


class _LooksAhead(Visitor[bool]):
    """Whether a node's value depends on records after its own (it comes late)."""

    def future(self, node) -> bool:
        return True

    until = future

    def _below(self, node) -> bool:
        for child in children(node):
            if self.visit(child):
                return True
        return False

    literal = name = time = unary = not_ = binary = call = prev = past = since = aggregate = _below


_IS_TIME = _IsTime()
_LOOKS_AHEAD = _LooksAhead()


def is_time(node: Expr) -> bool:
    """Whether ``node``'s value is a time or a duration, carried as exact nanoseconds: ``time``,
    and the ``prev``, negation, ``abs``, ``min``, ``max``, sums and differences of times.

    Not where a future operator's value takes part in the arithmetic (``time -
    count[0, 1](eventually p)``): such values come late, through streams that compute in
    seconds, so there times are the floats of their seconds."""
    return _IS_TIME.visit(node)


def looks_ahead(node: Expr) -> bool:
    """Whether ``node`` has a future operator in it (its values come late)."""
    return _LOOKS_AHEAD.visit(node)


def _as_nanoseconds(value: object) -> object:
    """A number that meets a time, as exact nanoseconds (:mod:`rasm.times`: a float stands for
    its shortest decimal); what is no finite number stays as it is (undefined stays undefined,
    inf infinite, a string fails the operator as it would have)."""
    if value.__class__ is bool:
        return int(value) * NS_PER_SECOND  # true is 1, as in any arithmetic
    ns = nanoseconds(value)
    return value if ns is None else ns


def _as_seconds(value: object) -> object:
    """A time in nanoseconds as the float nearest its seconds (undefined stays undefined)."""
    return from_nanoseconds(value) if value.__class__ is int else value / NS_PER_SECOND


# what the sources below call at run time, by the names they call it
HELPERS: dict[str, object] = {"_ns": _as_nanoseconds, "_seconds": _as_seconds}


def in_nanoseconds(node: Expr, value: str) -> str:
    """Source of ``node``'s value in nanoseconds (``value``: its source as emitted)."""
    if is_time(node):
        return value
    number = node.value if isinstance(node, Literal) else None
    if isinstance(number, (int, float)) and not isinstance(number, bool):
        if math.isfinite(number):
            exact = Fraction(repr(number)) * NS_PER_SECOND  # the decimal, as written
            if exact.denominator != 1:
                raise SourceError(
                    f"{unparse(node)} is finer than a nanosecond, the resolution of times: "
                    "a number added to or compared with a time is a time",
                    node.location,
                )
            return repr(exact.numerator)
    return f"_ns({value})"


def in_seconds(node: Expr, value: str) -> str:
    """Source of ``node``'s value in seconds (``value``: its source as emitted)."""
    if not is_time(node):
        return value
    return "t" if isinstance(node, Time) else f"_seconds({value})"
