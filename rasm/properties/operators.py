"""Incremental temporal operators: O(1) amortised work per record, whatever the bounds.

Each *core* implements one operator over two-valued inputs arriving in record order:

* past cores (:class:`OnceCore`, :class:`SinceCore`, :class:`WindowCore`) answer at once;
* future cores (:class:`EventuallyCore`, :class:`UntilCore`) keep the records whose window is
  still open and append ``(index, time, ns, value)`` to ``out`` as soon as a value is decided:
  true when a witness arrives, false when a record beyond the window (or one breaking
  ``until``'s left side) arrives. ``flush(default)`` settles the still-open ones at the end of
  a trace.

Times are compared as exact integer nanoseconds (``ns``; see :mod:`rasm.properties.times`), and so
are the bounds ``a`` and ``b`` (``b`` may be ``math.inf``); ``time`` is the record's time as
given, handed back with its verdict. Windows are never re-scanned: each record enters and leaves
a deque once; a window's "last witness" is a time stamp, ``min``/``max`` use monotonic deques
and sums exact integers.

Three-valued inputs (``None``: inconclusive, which only appears while finishing an offline
trace) are handled by :class:`Kleene`: a temporal operator is monotone in its boolean inputs,
so its three-valued value is read off two two-valued copies, a pessimistic one (``None`` read
as false, open windows settled false) and an optimistic one (``None`` read as true, open
windows settled true): true if the pessimistic copy says true, false if the optimistic says
false, inconclusive otherwise.
"""

from __future__ import annotations

import copy
import math
from collections import deque

__all__ = [
    "EventuallyCore",
    "Kleene",
    "OnceCore",
    "SinceCore",
    "UntilCore",
    "WindowCore",
]

NAN = math.nan
INF = math.inf
_SCALE_BITS = 1074  # every finite float is an integer multiple of 2**-1074
_SCALE = 1 << _SCALE_BITS


# --------------------------------------------------------------------------- past


class OnceCore:
    """``once[a,b] v``: the latest matured witness time is all that matters."""

    def __init__(self, a: int, b: int | float) -> None:
        self.a, self.b = a, b
        self.last = None  # latest witness j with t_i - t_j >= a
        self.pending: deque = deque()  # witnesses younger than a

    def push(self, ns: int, v: bool) -> bool:
        if self.a == 0:
            if v:
                self.last = ns
        else:
            pending = self.pending
            if v:
                pending.append(ns)
            while pending and ns - pending[0] >= self.a:
                self.last = pending.popleft()
        last = self.last
        return last is not None and ns - last <= self.b


class SinceCore:
    """``l since[a,b] r``: a false ``l`` forgets every witness before it."""

    def __init__(self, a: int, b: int | float) -> None:
        self.a, self.b = a, b
        self.last = None
        self.pending: deque = deque()

    def push(self, ns: int, left: bool, right: bool) -> bool:
        pending = self.pending
        if not left:
            pending.clear()
            self.last = None
        if right:
            if self.a == 0:
                self.last = ns
            else:
                pending.append(ns)
        while pending and ns - pending[0] >= self.a:
            self.last = pending.popleft()
        last = self.last
        return last is not None and ns - last <= self.b


class WindowCore:
    """``count/sum/avg/min/max[a,b](v)`` over the records j with a <= t_i - t_j <= b.

    Records wait in ``pending`` until they are ``a`` old, then sit in ``window`` until they are
    more than ``b`` old. Undefined values (nan) make the aggregate undefined while in the
    window; inconclusive ones (None) make it inconclusive.

    Sums follow IEEE-754 binary64 and never raise: the finite values are summed exactly (as
    integers, in units of 2**-1074: every float and every int is a whole number of them) and
    the exact sum or average is rounded once, to ±inf beyond the largest float; an infinite
    value makes the result infinite, and +inf with -inf makes it undefined.
    """

    def __init__(self, op: str, a: int, b: int | float) -> None:
        self.op, self.a, self.b = op, a, b
        self.pending: deque = deque()
        self.window: deque = deque()
        self.total = 0  # exact: integer multiples of 2**-1074 (or a plain count)
        self.n = 0
        self.nan = 0
        self.none = 0
        self.up = self.down = 0  # +inf and -inf values in the window (sum and avg)
        self.mono: deque = deque()  # min/max candidates, monotonic

    def _enter(self, item) -> None:
        self.window.append(item)
        v = item[1]
        self.n += 1
        if v is None:
            self.none += 1
        elif v != v:
            self.nan += 1
        elif self.op == "count":
            self.total += 1 if v else 0
        elif self.op in ("sum", "avg"):
            try:
                num, den = v.as_integer_ratio()
            except OverflowError:  # ±inf
                if v > 0:
                    self.up += 1
                else:
                    self.down += 1
            else:
                self.total += num * (_SCALE // den)
        else:
            mono = self.mono
            if self.op == "min":
                while mono and mono[-1][1] >= v:
                    mono.pop()
            else:
                while mono and mono[-1][1] <= v:
                    mono.pop()
            mono.append(item)

    def _leave(self) -> None:
        item = self.window.popleft()
        v = item[1]
        self.n -= 1
        if v is None:
            self.none -= 1
        elif v != v:
            self.nan -= 1
        elif self.op == "count":
            self.total -= 1 if v else 0
        elif self.op in ("sum", "avg"):
            try:
                num, den = v.as_integer_ratio()
            except OverflowError:
                if v > 0:
                    self.up -= 1
                else:
                    self.down -= 1
            else:
                self.total -= num * (_SCALE // den)
        elif self.mono and self.mono[0] is item:
            self.mono.popleft()

    def push(self, ns: int, v):
        item = (ns, v)
        if self.a == 0:
            self._enter(item)
        else:
            pending = self.pending
            pending.append(item)
            while pending and ns - pending[0][0] >= self.a:
                self._enter(pending.popleft())
        window = self.window
        while window and ns - window[0][0] > self.b:
            self._leave()
        return self.value()

    def value(self):
        if self.none:
            return None
        op = self.op
        if op == "count":
            return self.total
        if self.nan:
            return NAN
        if op in ("sum", "avg"):
            if self.up or self.down:
                return NAN if self.up and self.down else (INF if self.up else -INF)
            if op == "sum":
                return _rounded(self.total, _SCALE) if self.total else 0
            return _rounded(self.total, _SCALE * self.n) if self.n else NAN
        return self.mono[0][1] if self.mono else NAN


def _rounded(numerator: int, denominator: int) -> float:
    """The float nearest numerator / denominator; ±inf beyond the largest float."""
    try:
        return numerator / denominator
    except OverflowError:
        return INF if numerator > 0 else -INF


# --------------------------------------------------------------------------- future


class EventuallyCore:
    """``eventually[a,b] v``: open records wait for a witness or for their window to pass."""

    def __init__(self, a: int, b: int) -> None:
        self.a, self.b = a, b
        self.pending: deque = deque()  # (index, time, ns), oldest first
        self.out: deque = deque()  # decided (index, time, ns, value), in index order

    def push(self, i: int, t, ns: int, v: bool) -> None:
        pending, out = self.pending, self.out
        pending.append((i, t, ns))
        b = self.b
        # a record beyond the window of the oldest ones: no witness can come any more
        while ns - pending[0][2] > b:  # never empties: the record itself is inside its window
            j, tj, nj = pending.popleft()
            out.append((j, tj, nj, False))
        if v:
            # witness for every open record at least a older (the older ones are a prefix)
            a = self.a
            while pending and ns - pending[0][2] >= a:
                j, tj, nj = pending.popleft()
                out.append((j, tj, nj, True))

    def close(self, ns_next: int) -> None:
        """The next record to come is at ``ns_next``: windows ending before it are over."""
        pending, out, b = self.pending, self.out, self.b
        while pending and ns_next - pending[0][2] > b:
            j, tj, nj = pending.popleft()
            out.append((j, tj, nj, False))

    def flush(self, default) -> None:
        pending, out = self.pending, self.out
        while pending:
            j, tj, nj = pending.popleft()
            out.append((j, tj, nj, default))


class UntilCore:
    """``l until[a,b] r``: like eventually, and a false ``l`` closes every open record."""

    def __init__(self, a: int, b: int) -> None:
        self.a, self.b = a, b
        self.pending: deque = deque()
        self.out: deque = deque()

    def push(self, i: int, t, ns: int, left: bool, right: bool) -> None:
        pending, out = self.pending, self.out
        pending.append((i, t, ns))
        b = self.b
        while pending and ns - pending[0][2] > b:
            j, tj, nj = pending.popleft()
            out.append((j, tj, nj, False))
        if right:
            a = self.a
            while pending and ns - pending[0][2] >= a:
                j, tj, nj = pending.popleft()
                out.append((j, tj, nj, True))
        if not left:
            # every later witness would need left to hold here
            while pending:
                j, tj, nj = pending.popleft()
                out.append((j, tj, nj, False))

    close = EventuallyCore.close
    flush = EventuallyCore.flush


# --------------------------------------------------------------------------- three values


class Kleene:
    """Three-valued wrapper of a boolean temporal core (see the module docstring).

    ``push(i, t, ns, *values)`` takes values in True/False/None; decided ``(i, t, ns, value)``
    appear in ``out``. Until a ``None`` arrives a single core runs; the first ``None`` splits it
    into the pessimistic and the optimistic copy.
    """

    def __init__(self, core) -> None:
        self.core = core
        self.future = hasattr(core, "flush")
        self.low = self.high = None
        self.out: deque = core.out if self.future else deque()
        self._low_out = self._high_out = None

    def _split(self) -> None:
        self.low = self.core
        self.high = copy.deepcopy(self.core)
        if self.future:
            # ``out`` (which readers hold) stays; the copies get deques of their own, merged
            # into ``out`` once both have decided a record
            self.low.out, self.high.out = deque(), deque()
            self._low_out, self._high_out = self.low.out, self.high.out
        self.core = None

    def push(self, i: int, t, ns: int, *values) -> None:
        if self.core is not None:
            if None not in values:
                if self.future:
                    self.core.push(i, t, ns, *values)
                else:
                    self.out.append((i, t, ns, self.core.push(ns, *values)))
                return
            self._split()
        low_values = [v is True for v in values]
        high_values = [v is not False for v in values]
        if self.future:
            self.low.push(i, t, ns, *low_values)
            self.high.push(i, t, ns, *high_values)
            self._merge()
        else:
            low = self.low.push(ns, *low_values)
            high = self.high.push(ns, *high_values)
            self.out.append((i, t, ns, True if low else (None if high else False)))

    def _merge(self) -> None:
        low_out, high_out, out = self._low_out, self._high_out, self.out
        while low_out and high_out:
            j, tj, nj, low = low_out.popleft()
            high = high_out.popleft()[3]
            out.append((j, tj, nj, True if low else (None if high else False)))

    def close(self, ns_next: int) -> None:
        """See :meth:`EventuallyCore.close` (future cores only)."""
        if self.core is not None:
            self.core.close(ns_next)
            return
        self.low.close(ns_next)
        self.high.close(ns_next)
        self._merge()

    def flush(self) -> None:
        if not self.future:
            return
        if self.core is not None:
            self.core.flush(None)
            return
        self.low.flush(False)
        self.high.flush(True)
        self._merge()
