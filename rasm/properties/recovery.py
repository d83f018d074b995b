"""Recovering a property whose evaluation raised: from which record its verdicts are exact again.

When evaluating a property raises at record r, the monitor gives record r (and every earlier
record still waiting in the property's future windows) an error verdict and resets the
property's state: from then on the property has seen only the records after r. A later verdict
is exact again once nothing it depends on lies at or before r; until then it is an error too.
What a sub-formula's value at record x depends on:

* a signal, a literal, ``time``: record x (held signal values are the monitor's, never reset);
* ``prev(e)``: what ``e`` at record x - 1 depends on;
* a past operator or an aggregate with upper bound b: what its operands depend on from the first
  record no more than b before x on; with no upper bound, every record (the property stays in
  error for the rest of the trace: it cannot vouch for anything any more);
* a future operator: what its operands depend on from x on;
* anything else: what its operands depend on at x.

Each of these moves forward with x, so once a record's verdict is exact, every later one is.
"""

from __future__ import annotations

from bisect import bisect_left

from rasm.properties.ast import INF, Aggregate, Expr, Past, Prev, Since, children
from rasm.properties.visitor import Transformer, Visitor

__all__ = ["Recovery"]


class Recovery:
    """A property reset after its evaluation raised at record ``reset`` (time ``reset_ns``).

    Feed it every later record with :meth:`note`; :meth:`tainted` tells which verdicts still
    depend on records before the reset. ``until`` (set when the property raises again) ends
    the records this reset speaks for.
    """

    def __init__(self, formula: Expr, reset: int, reset_ns: int, why: str) -> None:
        self.formula = formula
        self.reset = reset
        self.why = f"depends on records before a reset at record {reset}, after: {why}"
        self.exact_from: int | None = None  # the first record whose verdict is exact again
        self.until: int | None = None
        self.given = 0  # tainted verdicts given so far (online)
        # the times of records reset, reset + 1, …: what window look-ups need, until exact
        self.times: list[int] | None = [reset_ns] if _bounded(formula) else None

    def note(self, index: int, ns: int) -> None:
        """Record ``index``, at ``ns``, has been evaluated by the fresh state."""
        if self.times is None or index <= self.reset:
            return
        self.times.append(ns)
        if self._exact(self.formula, index):
            self.exact_from = index
            self.times = None

    def tainted(self, index: int) -> bool:
        """The verdict at ``index`` depends on records from before the reset."""
        return (
            index > self.reset
            and (self.exact_from is None or index < self.exact_from)
            and (self.until is None or index <= self.until)
        )

    @property
    def over(self) -> bool:
        """Every tainted verdict has been given (online): the property is exact from now on."""
        return self.exact_from is not None and self.given == self.exact_from - self.reset - 1

    def _exact(self, node: Expr, x: int) -> bool:
        """Whether ``node``'s value at record ``x`` depends only on records after the reset."""
        assert self.times is not None
        return _After(self.reset, self.times).visit(node, x)


class _After(Visitor[bool]):
    """Whether a node's value at record ``x`` depends only on records after ``reset``."""

    def __init__(self, reset: int, times: list[int]) -> None:
        self.reset = reset
        self.times = times  # of records reset, reset + 1, …

    def visit(self, node: Expr, x: int) -> bool:  # type: ignore[override]
        return x > self.reset and super().visit(node, x)

    def prev(self, node: Prev, x: int) -> bool:
        return self.visit(node.operand, x - 1)

    def past(self, node: Past | Since | Aggregate, x: int) -> bool:
        # its operands from the first record no more than its upper bound before x on
        reset, times = self.reset, self.times
        first = reset + bisect_left(times, times[x - reset] - node.bound.high_ns)
        return all(self.visit(child, first) for child in children(node))

    since = aggregate = past

    def _pointwise(self, node: Expr, x: int) -> bool:
        # its operands at x (a future operator's from x on: dependence only moves
        # forward with x, so x decides)
        return all(self.visit(child, x) for child in children(node))

    literal = name = time = unary = not_ = binary = call = future = until = _pointwise


class _Bounded(Transformer[bool]):
    """No past operator or aggregate without an upper bound: the property can recover."""

    def past(self, node: Past | Since | Aggregate, *operands: bool) -> bool:
        return node.bound.high_ns != INF and all(operands)

    since = aggregate = past

    def _others(self, node: Expr, *operands: bool) -> bool:
        return all(operands)

    literal = name = time = unary = not_ = binary = call = prev = future = until = _others


_BOUNDED = _Bounded()


def _bounded(node: Expr) -> bool:
    """No past operator or aggregate without an upper bound: the property can recover."""
    return _BOUNDED.visit(node)
