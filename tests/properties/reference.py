"""A reference evaluator written straight from the semantics in docs/properties.md: slow,
quadratic, obviously correct.

Values are three-valued: True, False, None (inconclusive: depends on records after the end).
Numbers may be ``nan`` (undefined: prev at the first record, an empty window, x / 0).

A ``count`` over inconclusive values is a :class:`CountRange` (the counts it may still take):
a comparison of it with a value that does not look ahead is decided where every count in the
range gives the same answer (docs/properties.md, "Verdicts come as soon as they are decided");
anything else makes of a range an inconclusive value.

Times are exact: a record's time and a window's bounds are the decimals they were written as
(a float stands for its shortest decimal, ``repr``), held as :class:`fractions.Fraction`, so
``0.3 - 0.1`` is exactly ``0.2`` here. Arithmetic follows IEEE-754 binary64 without ever
raising: the exact result rounded to a float, ±inf beyond the largest one.

``time`` is exact too: its value is an :class:`Exact` (the record's time as a fraction), and so
are the negations, ``abs``, ``min``, ``max``, ``prev``, sums and differences it takes part in,
with every number in them read as its decimal; comparing an :class:`Exact` with a number is
exact. Anywhere else (``*``, ``/``, an aggregate, arithmetic with a future operator's value
below it) an :class:`Exact` is the float nearest it.
"""

from __future__ import annotations

import math
import operator
import sys
from decimal import Decimal
from fractions import Fraction

from rasm.properties.ast import (
    Aggregate,
    Binary,
    Call,
    Future,
    Literal,
    Name,
    Not,
    Past,
    Prev,
    Since,
    Specification,
    Time,
    Unary,
    Until,
    children,
)
from rasm.properties.loader import signals_of
from rasm.properties.types import TypeScope

NAN = math.nan
INF = math.inf


def exact_seconds(time) -> Fraction:
    """A record time as the exact number of seconds it stands for."""
    if isinstance(time, float):
        return Fraction(repr(time))
    if isinstance(time, (int, Decimal, Fraction)):
        return Fraction(time)
    raise TypeError(time)


class Exact(Fraction):
    """A time or a duration, in exact seconds."""


def exact_number(value) -> Fraction:
    """A number as the decimal it is written as: a float stands for its shortest decimal."""
    return Fraction(repr(value)) if isinstance(value, float) else Fraction(value)


def finite(value) -> bool:
    """Not ±inf nor nan (an int of any size is finite)."""
    return not isinstance(value, float) or math.isfinite(value)


def plain(value):
    """An :class:`Exact` where a plain number is needed: the float nearest it."""
    return to_float(value) if isinstance(value, Exact) else value


def exact_arithmetic(op: str, a, b):
    """``a op b`` where ``a`` or ``b`` is a time: exact, or undefined / infinite as IEEE says."""
    if not all(map(finite, (a, b))):
        return arithmetic(op, plain(a), plain(b))
    return Exact(OPERATORS[op](exact_number(a), exact_number(b)))


def looks_ahead(node) -> bool:
    """Whether ``node`` reads a future operator's value."""
    if isinstance(node, (Future, Until)):
        return True
    return any(looks_ahead(child) for child in children(node))


def exact_bound(seconds: float):
    return seconds if seconds == INF else Fraction(repr(float(seconds)))


def to_float(exact: Fraction) -> float:
    """The float nearest ``exact``; ±inf beyond the largest float."""
    try:
        return float(exact)
    except OverflowError:
        return INF if exact > 0 else -INF


OPERATORS = {"+": operator.add, "-": operator.sub, "*": operator.mul, "/": operator.truediv}


def arithmetic(op: str, a, b):
    """``a op b`` by IEEE-754 rules on the exact operands; two ints stay an exact int."""
    if op == "/":
        if b == 0 or a != a or b != b:
            return NAN
    elif isinstance(a, int) and isinstance(b, int):
        return OPERATORS[op](a, b)
    if a != a or b != b:
        return NAN
    infinite = [v for v in (a, b) if isinstance(v, float) and math.isinf(v)]
    if infinite:
        # an infinite operand decides as any finite number of the other's sign would
        big = sys.float_info.max
        x, y = (v if isinstance(v, float) else math.copysign(big, v) if v else 0.0
                for v in (a, b))
        return OPERATORS[op](x, y)
    return to_float(OPERATORS[op](Fraction(a), Fraction(b)))


def ieee_sum(values) -> float:
    """The exact sum of ``values`` (floats and ints, ±inf allowed, no nan) rounded to a float."""
    infinities = {v for v in values if isinstance(v, float) and math.isinf(v)}
    if len(infinities) == 2:
        return NAN
    if infinities:
        return infinities.pop()
    return to_float(sum((Fraction(v) for v in values), Fraction(0)))


def ieee_avg(values) -> float:
    infinities = {v for v in values if isinstance(v, float) and math.isinf(v)}
    if len(infinities) == 2:
        return NAN
    if infinities:
        return infinities.pop()
    return to_float(sum((Fraction(v) for v in values), Fraction(0)) / len(values))


def held_values(spec: Specification, records):
    """The value of every signal at every record (sample-and-hold; events only where set)."""
    events = {e.name for e in spec.events}
    current = {i.name: i.default for i in spec.inputs if i.default is not None}
    held = []
    for _, rec in records:
        for name in events:
            current[name] = False
        for key, value in rec.items():
            current[key] = value
        held.append(dict(current))
    return held


def k_and(a, b):
    if a is False or b is False:
        return False
    if a is None or b is None:
        return None
    return True


def k_or(a, b):
    if a is True or b is True:
        return True
    if a is None or b is None:
        return None
    return False


def k_not(a):
    return None if a is None else (not a)


def k_any(values):
    result = False
    for v in values:
        result = k_or(result, v)
    return result


def k_all(values):
    result = True
    for v in values:
        result = k_and(result, v)
    return result


class CountRange(tuple):
    """The counts ``(lo, hi)`` a count over inconclusive values may still take."""


def settled(v):
    """A value as anything but a comparison with a count reads it (a range: inconclusive)."""
    return None if isinstance(v, CountRange) else v


class Reference:
    def __init__(self, spec: Specification, records) -> None:
        self.spec = spec
        self.times = [t for t, _ in records]  # what ``time`` reads
        self.exact = [exact_seconds(t) for t, _ in records]  # what windows compare
        self.env = held_values(spec, records)
        self.n = len(records)
        self.types = TypeScope({k: v for k, v in spec.signals.items() if v != "any"})
        self.memo: dict = {}
        self.start = 0

    def verdicts(self, prop):
        """{index: value} for every judged record of ``prop``."""
        reads = [s for s in signals_of(prop.formula)]
        start = None
        for i in range(self.n):
            if all(s in self.env[i] for s in reads):
                start = i
                break
        if start is None:
            return {}
        self.start = start
        self.memo = {}
        return {i: self.value(prop.formula, i) for i in range(start, self.n)}

    def value(self, node, i):
        key = (id(node), i)
        if key not in self.memo:
            self.memo[key] = self._value(node, i)
        return self.memo[key]

    def _value(self, node, i):  # noqa: C901
        t = self.exact
        if isinstance(node, Literal):
            return node.value
        if isinstance(node, Name):
            return self.env[i][node.name]
        if isinstance(node, Time):
            return Exact(exact_seconds(self.times[i]))
        if isinstance(node, Not):
            return k_not(self.value(node.operand, i))
        if isinstance(node, Unary):
            v = settled(self.value(node.operand, i))
            return None if v is None else Exact(-v) if isinstance(v, Exact) else -v
        if isinstance(node, Binary):
            a, b = self.value(node.left, i), self.value(node.right, i)
            if isinstance(a, CountRange) or isinstance(b, CountRange):
                return self._range_comparison(node, a, b)
            if node.op == "and":
                return k_and(a, b)
            if node.op == "or":
                return k_or(a, b)
            if node.op == "->":
                return k_or(k_not(a), b)
            if a is None or b is None:
                return None
            timed = (isinstance(a, Exact) or isinstance(b, Exact)) and not looks_ahead(node)
            if node.op in ("+", "-") and timed:
                return exact_arithmetic(node.op, a, b)
            if node.op in ("+", "-", "*", "/"):
                return arithmetic(node.op, plain(a), plain(b))
            if a != a or b != b:  # undefined: every comparison is false
                return False
            if timed and all(map(finite, (a, b))):
                a, b = exact_number(a), exact_number(b)
            else:
                a, b = plain(a), plain(b)
            return {
                "==": a == b, "!=": a != b, "<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b,
            }[node.op]
        if isinstance(node, Call):
            args = [settled(self.value(x, i)) for x in node.args]
            if None in args:
                return None
            if any(x != x for x in args):
                return NAN
            if any(isinstance(x, Exact) for x in args) and not looks_ahead(node):
                if all(map(finite, args)):
                    args = [exact_number(x) for x in args]
                    found = {"abs": lambda: abs(args[0]), "min": lambda: min(args),
                             "max": lambda: max(args)}[node.func]()
                    return Exact(found)
                args = [plain(x) for x in args]
            return {"abs": lambda: abs(args[0]), "min": lambda: min(args),
                    "max": lambda: max(args)}[node.func]()
        if isinstance(node, Prev):
            if i == self.start:
                return False if self.types.check(node.operand) == "bool" else NAN
            return settled(self.value(node.operand, i - 1))
        a, b = exact_bound(node.bound.low), exact_bound(node.bound.high)
        past = range(self.start, i + 1)
        future = range(i, self.n)
        if isinstance(node, Past):
            window = [self.value(node.operand, j) for j in past if a <= t[i] - t[j] <= b]
            if node.op == "once":
                return k_any(window)
            return k_all(window)
        if isinstance(node, Since):
            terms = []
            for j in past:
                if a <= t[i] - t[j] <= b:
                    term = self.value(node.right, j)
                    for k in range(j + 1, i + 1):
                        term = k_and(term, self.value(node.left, k))
                    terms.append(term)
            return k_any(terms)
        if isinstance(node, Future):
            window = [self.value(node.operand, j) for j in future if a <= t[j] - t[i] <= b]
            open_ = t[-1] - t[i] <= b  # a later record could still fall in the window
            if node.op == "eventually":
                return k_or(k_any(window), None if open_ else False)
            return k_and(k_all(window), None if open_ else True)
        if isinstance(node, Until):
            terms = []
            for j in future:
                if a <= t[j] - t[i] <= b:
                    term = self.value(node.right, j)
                    for k in range(i, j):
                        term = k_and(term, self.value(node.left, k))
                    terms.append(term)
            if t[-1] - t[i] <= b:
                # a later record could be the witness, if left holds on all records from i on
                lefts = k_all(self.value(node.left, k) for k in range(i, self.n))
                terms.append(k_and(None, lefts))
            return k_any(terms)
        if isinstance(node, Aggregate):
            window = [plain(settled(self.value(node.operand, j)))
                      for j in past if a <= t[i] - t[j] <= b]
            if node.op == "count":
                if None in window:
                    return CountRange((window.count(True), len(window) - window.count(False)))
                return sum(1 for v in window if v)
            if None in window:
                return None
            if any(v != v for v in window):
                return NAN
            if node.op == "sum":
                return ieee_sum(window) if window else 0
            if not window:
                return NAN
            if node.op == "avg":
                return ieee_avg(window)
            return min(window) if node.op == "min" else max(window)
        raise TypeError(node)

    def _range_comparison(self, node, a, b):
        """A comparison with a count over inconclusive values: decided where the other side
        does not look ahead and every count the range allows gives the same answer."""
        if node.op not in ("==", "!=", "<", "<=", ">", ">="):
            return None
        other = node.right if isinstance(a, CountRange) else node.left
        if looks_ahead(other) or (isinstance(a, CountRange) and isinstance(b, CountRange)):
            return None
        if isinstance(a, CountRange):
            answers = {_compare(node.op, c, b) for c in range(a[0], a[1] + 1)}
        else:
            answers = {_compare(node.op, a, c) for c in range(b[0], b[1] + 1)}
        return answers.pop() if len(answers) == 1 else None


def _compare(op: str, a, b) -> bool:
    if a != a or b != b:
        return False
    a, b = plain(a), plain(b)
    return {"==": a == b, "!=": a != b, "<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b}[op]


def reference_verdicts(spec: Specification, records) -> dict[str, dict[int, object]]:
    ref = Reference(spec, records)
    return {prop.name: ref.verdicts(prop) for prop in spec.properties}


# --------------------------------------------------------------------------- robustness (§12)


def _distance(op: str, a, b) -> float:
    """The robustness of ``a op b`` for two numbers neither undefined (``b - a`` for ``<=``)."""
    d = (b - a) if op in ("<", "<=") else (a - b)
    if isinstance(d, Fraction):
        d = to_float(d)
    if d != d:  # inf - inf: two equal infinities
        d = 0.0
    return -abs(d) if op == "==" else abs(d) if op == "!=" else d


class RobustReference(Reference):
    """SPEC §12 by its definition, over the records of the trace (windows compared exactly).

    ``robustness(node, i)`` is the value where every window it reaches is covered by the trace;
    ``open_(node, i)`` says whether some window might still take a record after the end (then
    the value is not final)."""

    def robust_verdicts(self, prop):
        """{index: robustness, or None where it is not final} for every judged record."""
        if not self.verdicts(prop):
            return {}
        self.rmemo: dict = {}
        self.omemo: dict = {}
        out = {}
        for i in range(self.start, self.n):
            out[i] = None if self.open_(prop.formula, i) else float(
                self.robustness(prop.formula, i))
        return out

    def open_(self, node, i) -> bool:
        key = (id(node), i)
        if key not in self.omemo:
            self.omemo[key] = self._open(node, i)
        return self.omemo[key]

    def _open(self, node, i) -> bool:
        t = self.exact
        if isinstance(node, (Future, Until)):
            a, b = exact_bound(node.bound.low), exact_bound(node.bound.high)
            if t[-1] - t[i] <= b:
                return True
            window = [j for j in range(i, self.n) if t[j] - t[i] <= b]
            if isinstance(node, Future):
                return any(self.open_(node.operand, j) for j in window if t[j] - t[i] >= a)
            return any(self.open_(node.left, j) or self.open_(node.right, j) for j in window)
        if isinstance(node, Prev):
            return i > self.start and self.open_(node.operand, i - 1)
        if isinstance(node, Aggregate):  # a value: final where its boolean operands are
            return settled(self.value(node, i)) is None
        if isinstance(node, (Past, Since)):
            a, b = exact_bound(node.bound.low), exact_bound(node.bound.high)
            window = [j for j in range(self.start, i + 1) if a <= t[i] - t[j] <= b]
            if not window:
                return False
            if isinstance(node, Since):
                return any(self.open_(node.right, j) for j in window) or any(
                    self.open_(node.left, k) for k in range(window[0] + 1, i + 1))
            return any(self.open_(node.operand, j) for j in window)
        return any(self.open_(child, i) for child in children(node))

    def robustness(self, node, i):
        key = (id(node), i)
        if key not in self.rmemo:
            self.rmemo[key] = self._robustness(node, i)
        return self.rmemo[key]

    def _robustness(self, node, i):  # noqa: C901
        t = self.exact
        rob = self.robustness
        if isinstance(node, (Literal, Name)):
            return INF if self.value(node, i) else -INF
        if isinstance(node, Not):
            return -rob(node.operand, i)
        if isinstance(node, Binary):
            if node.op in ("and", "or", "->"):
                a, b = rob(node.left, i), rob(node.right, i)
                if node.op == "and":
                    return min(a, b)
                if node.op == "or":
                    return max(a, b)
                return max(-a, b)
            a, b = self.value(node.left, i), self.value(node.right, i)
            if any(isinstance(v, (str, bool)) for v in (a, b)):
                return INF if self.value(node, i) else -INF
            if a != a or b != b:
                return -INF
            timed = (isinstance(a, Exact) or isinstance(b, Exact)) and not looks_ahead(node)
            if timed and all(map(finite, (a, b))):
                return _distance(node.op, exact_number(a), exact_number(b))
            return _distance(node.op, plain(a), plain(b))
        if isinstance(node, Prev):
            return -INF if i == self.start else rob(node.operand, i - 1)
        a, b = exact_bound(node.bound.low), exact_bound(node.bound.high)
        if isinstance(node, Past):
            window = [rob(node.operand, j) for j in range(self.start, i + 1)
                      if a <= t[i] - t[j] <= b]
            if node.op == "once":
                return max(window, default=-INF)
            return min(window, default=INF)
        if isinstance(node, Future):
            window = [rob(node.operand, j) for j in range(i, self.n) if a <= t[j] - t[i] <= b]
            if node.op == "eventually":
                return max(window, default=-INF)
            return min(window, default=INF)
        if isinstance(node, Since):
            terms = [min([rob(node.right, j)] + [rob(node.left, k) for k in range(j + 1, i + 1)])
                     for j in range(self.start, i + 1) if a <= t[i] - t[j] <= b]
            return max(terms, default=-INF)
        if isinstance(node, Until):
            terms = [min([rob(node.right, j)] + [rob(node.left, k) for k in range(i, j)])
                     for j in range(i, self.n) if a <= t[j] - t[i] <= b]
            return max(terms, default=-INF)
        raise TypeError(node)


def reference_robustness(spec: Specification, records) -> dict[str, dict[int, object]]:
    ref = RobustReference(spec, records)
    return {prop.name: ref.robust_verdicts(prop) for prop in spec.properties}
