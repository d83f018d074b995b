"""Incremental robustness operators (SPEC §12): O(1) amortised work per record, whatever the
bounds, and memory bounded by each operator's window.

Robustness values are floats (ints where an int comparison gave them), never nan: an undefined
value compares to −inf. A sub-formula's robustness at record i is *final* once every record its
windows reach has come, which for a bounded-future operator is the first record later than its
window. Unlike boolean values (:mod:`rasm.properties.operators`), robustness values are given in
**record order**: a window's value waits for the whole window, and windows close in record
order. So a stream here is a deque ``out`` of final values, one per record from its first, in
order, with no index: the k-th value of every stream of a property is the k-th record's.

Between two records a stream also knows, for each record whose value is not final yet, an
interval that contains the final value (``intervals()``): the robust satisfaction intervals
of Deshmukh et al., narrowing as records arrive. An unknown future value lies in [−inf, inf].
``intervals()`` costs in proportion to the records open (or worse); ``at(p)`` gives the
interval of one of them (the p-th not final, oldest first) in O(log w) for a future window
and O(1) for the pointwise operators, ``prev`` and a count's comparison, and (−inf, inf),
"nothing known", where an operator cannot answer as cheaply (past windows, ``since`` and
``until`` over values that come late).

* :class:`PastWindow` — ``once``/``historically[a,b]`` (sliding max/min: a monotonic wedge);
* :class:`SinceCore` — ``since[a,b]`` by the identity ``l S[a,b] r = H[0,a) l ∧ Y(hi) ∧
  O[a,b] r`` (hi: the last record at least a old; Y: the unbounded since), which holds in any
  distributive lattice, so in (max, min) as in (or, and);
* :class:`FutureWindow` — ``eventually``/``always[a,b]``, by the same wedge once the window is
  complete;
* :class:`UntilStream` — ``until[a,b]``: the minimum of l before the window, then a fold of
  ``X ↦ max(r, min(l, X))`` over the window: such functions compose into one of the same form,
  so a two-stack queue gives the fold of a sliding window in O(1) amortised;
* :class:`PrevStream`, :class:`Pointwise` and :class:`Ordered` (the values of a boolean
  stream — a count over a future operand — in record order).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence

__all__ = [
    "RCMP",
    "FutureWindow",
    "Ordered",
    "PastStream",
    "PastWindow",
    "Pointwise",
    "PrevStream",
    "SinceCore",
    "SinceStream",
    "UntilStream",
    "as_float",
    "compare",
    "pending_at",
]

INF = math.inf
EVERYTHING = (-INF, INF)
Interval = tuple[float, float]


def as_float(value) -> float:
    """A robustness value as a float (a huge int difference is ±inf)."""
    try:
        return float(value)
    except OverflowError:
        return INF if value > 0 else -INF


# --------------------------------------------------------------------------- comparisons


def _difference(a, b):
    """``b − a`` for two numbers that are not nan; 0 for two equal infinities."""
    d = b - a
    return 0.0 if d != d else d


def compare(op: str, a, b):
    """The robustness of ``a op b`` (SPEC §12): a distance for numbers, ±inf for strings and
    booleans (by the comparison's truth), −inf where a value is undefined."""
    if a.__class__ in (str, bool) or b.__class__ in (str, bool):
        return INF if _PLAIN[op](a, b) else -INF
    if a != a or b != b:
        return -INF
    if op in ("<", "<="):
        return _difference(a, b)
    if op in (">", ">="):
        return _difference(b, a)
    d = _difference(a, b)
    return -abs(d) if op == "==" else abs(d)


_PLAIN: dict[str, Callable] = {
    "==": lambda a, b: a == b, "!=": lambda a, b: a != b, "<": lambda a, b: a < b,
    "<=": lambda a, b: a <= b, ">": lambda a, b: a > b, ">=": lambda a, b: a >= b,
}

RCMP: dict[str, Callable] = {op: (lambda a, b, op=op: compare(op, a, b)) for op in _PLAIN}


def compare_interval(op: str, a: Interval, b: Interval) -> Interval:
    """``compare`` of values known to lie in intervals ``a`` and ``b``."""
    if a[0] != a[0] or b[0] != b[0]:  # an undefined value (nan): −inf, as compare gives
        return (-INF, -INF)
    if a[0] == a[1] and b[0] == b[1]:
        v = compare(op, a[0], b[0])
        return (v, v)
    if a[0].__class__ in (str, bool) or b[0].__class__ in (str, bool):
        return EVERYTHING
    if op in ("<", "<="):
        return (_low(b[0], a[1]), _high(b[1], a[0]))
    if op in (">", ">="):
        return (_low(a[0], b[1]), _high(a[1], b[0]))
    low, high = _low(b[0], a[1]), _high(b[1], a[0])  # the range of b − a
    if low <= 0 <= high:
        return (-max(-low, high), 0.0) if op == "==" else (0.0, max(-low, high))
    distance = (min(abs(low), abs(high)), max(abs(low), abs(high)))
    return (-distance[1], -distance[0]) if op == "==" else distance


def _low(x, y):
    d = x - y
    return -INF if d != d else d


def _high(x, y):
    d = x - y
    return INF if d != d else d


# --------------------------------------------------------------------------- past


class PastWindow:
    """``once[a,b]`` (``high``: max) or ``historically[a,b]`` (min) of values given in record
    order: ``push(ns, v)`` returns the value at that record. A monotonic wedge of the values in
    the window; records younger than ``a`` wait in ``young``."""

    __slots__ = ("a", "b", "high", "empty", "young", "wedge", "best")

    def __init__(self, high: bool, a: int, b: int | float) -> None:
        self.high, self.a, self.b = high, a, b
        self.empty = -INF if high else INF  # over no record
        self.young: deque = deque()
        self.wedge: deque = deque()
        self.best = self.empty  # a = 0, b = inf: the running max or min

    def push(self, ns: int, v):
        a, wedge = self.a, self.wedge
        if a == 0:
            if self.b == INF:
                best = self.best
                if (v > best) if self.high else (v < best):
                    self.best = best = v
                return best
            self._enter((ns, v))
        else:
            young = self.young
            young.append((ns, v))
            while young and ns - young[0][0] >= a:
                self._enter(young.popleft())
        if self.b != INF:
            b = self.b
            while wedge and ns - wedge[0][0] > b:
                wedge.popleft()
        return wedge[0][1] if wedge else self.empty

    def _enter(self, item) -> None:
        wedge, v = self.wedge, item[1]
        if self.high:
            while wedge and wedge[-1][1] <= v:
                wedge.pop()
        else:
            while wedge and wedge[-1][1] >= v:
                wedge.pop()
        wedge.append(item)

    def at(self, ns: int, pending: Sequence[tuple[int, Interval]]) -> Interval:
        """The value at a record at ``ns`` whose window also holds ``pending`` (records whose
        values are not final, oldest first, after the ones pushed): an interval."""
        lo = hi = self._peek(ns)
        pick = max if self.high else min
        for t, (low, high) in pending:
            if self.a <= ns - t <= self.b:
                lo, hi = pick(lo, low), pick(hi, high)
        return (lo, hi)

    def _peek(self, ns: int):
        """The value over the records pushed, at a later record at ``ns`` (no change)."""
        if self.a == 0 and self.b == INF:
            return self.best
        pick = max if self.high else min
        best = self.empty
        for t, v in (*self.wedge, *self.young):
            if self.a <= ns - t <= self.b:
                best = pick(best, v)
        return best


class _Ordered:
    """A stream of final values in record order (``out``) over input streams; ``times`` holds
    the records whose values are not final yet."""

    def __init__(self) -> None:
        self.out: deque = deque()

    def intervals(self) -> list[Interval]:
        """An interval for each record whose value is not final yet, oldest first."""
        raise NotImplementedError

    def waiting(self) -> int:
        """How many records' values are not final yet (``len(self.intervals())``)."""
        return len(self.intervals())

    def at(self, p: int) -> Interval:
        """``self.intervals()[p]``, or wider, at a cost independent of the bounds: here
        (−inf, inf), nothing known (the operators that answer better say how)."""
        return EVERYTHING


def pending_at(stream: _Ordered, p: int) -> Interval:
    """``_pending(stream)[p]``: the p-th of the input's records not taken yet."""
    out = stream.out
    if p < len(out):
        v = out[p]
        return (v, v)
    return stream.at(p - len(out))


def _first_in(items, i: int, first) -> int:
    """The position of the first of ``items`` (``(seq, ns, …)`` in record order) with
    ``seq >= i`` and ``ns >= first``, ``len(items)`` if none: a search galloping from the
    newest end, O(log d) probes for an answer d items from that end."""
    n = len(items)
    good, bad, step = n, -1, 1
    while good > 0:
        probe = n - step if step < n else 0
        item = items[probe]
        if item[0] < i or item[1] < first:
            bad = probe
            break
        good = probe
        step += step
    while good - bad > 1:
        middle = (good + bad) // 2
        item = items[middle]
        if item[0] < i or item[1] < first:
            bad = middle
        else:
            good = middle
    return good


def _pending(stream: _Ordered | None, value=None) -> list[Interval]:
    """The intervals of an input's records not final yet (an immediate input has none)."""
    if stream is None:
        return []
    return [(v, v) for v in stream.out] + stream.intervals()


class PastStream(_Ordered):
    """``once``/``historically[a,b]`` of a stream."""

    def __init__(self, source: _Ordered, high: bool, a: int, b: int | float) -> None:
        super().__init__()
        self.source = source
        self.core = PastWindow(high, a, b)
        self.times: deque = deque()

    def step(self, ns: int) -> None:
        times, queue, out, push = self.times, self.source.out, self.out, self.core.push
        times.append(ns)
        while queue:
            out.append(push(times.popleft(), queue.popleft()))

    def intervals(self) -> list[Interval]:
        pending = list(zip(self.times, self.source.intervals(), strict=True))
        return [self.core.at(ns, pending[: k + 1]) for k, (ns, _) in enumerate(pending)]


class SinceCore:
    """``l since[a,b] r`` of values given in record order: ``push(ns, l, r)`` returns the value
    at that record, ``max over j in the window of min(r@j, min over j < k <= i of l@k)``."""

    __slots__ = ("a", "y", "young", "yhi", "lefts", "rights")

    def __init__(self, a: int, b: int | float) -> None:
        self.a = a
        self.y = -INF  # the unbounded since at the newest record
        self.young: deque = deque()  # (ns, Y) of records less than a old
        self.yhi = None  # Y at the last record at least a old (None: no such record)
        self.lefts = PastWindow(False, 0, a - 1) if a > 0 else None  # l over the young
        self.rights = PastWindow(True, a, b)  # r over the window

    def push(self, ns: int, left, right):
        y = self.y
        self.y = y = right if right > (left if left < y else y) else (left if left < y else y)
        window = self.rights.push(ns, right)
        if self.a == 0:
            return y if y < window else window
        recent = self.lefts.push(ns, left)
        young = self.young
        young.append((ns, y))
        while young and ns - young[0][0] >= self.a:
            self.yhi = young.popleft()[1]
        if self.yhi is None:
            return -INF
        return min(recent, self.yhi, window)


class SinceStream(_Ordered):
    """``since[a,b]`` where an operand is a stream (the other may be immediate)."""

    def __init__(self, left: _Ordered | None, right: _Ordered | None, a: int,
                 b: int | float) -> None:
        super().__init__()
        self.left, self.right = left, right
        self.core = SinceCore(a, b)
        self.a, self.b = a, b
        self.times: deque = deque()  # (ns, immediate value or None) not pushed yet
        self.seen: deque = deque()  # (ns, l, r) of the records in reach of the pending ones

    def step(self, ns: int, *now) -> None:
        self.times.append((ns, now))
        lq = self.left.out if self.left is not None else None
        rq = self.right.out if self.right is not None else None
        times, push, out = self.times, self.core.push, self.out
        while times and (lq is None or lq) and (rq is None or rq):
            t, v = times.popleft()
            left = v[0] if lq is None else lq.popleft()
            right = v[-1] if rq is None else rq.popleft()
            out.append(push(t, left, right))
            self._remember(t, left, right)

    def _remember(self, ns: int, left, right) -> None:
        # the records a pending one may reach back to: b old, and the chain of Y before
        seen = self.seen
        seen.append((ns, left, right))
        if self.b != INF:
            while seen and ns - seen[0][0] > self.b:
                seen.popleft()

    def intervals(self) -> list[Interval]:
        lefts = _pending(self.left) if self.left is not None else None
        rights = _pending(self.right) if self.right is not None else None
        rows: list[tuple[int, Interval, Interval, bool]] = []
        for k, (t, v) in enumerate(self.times):
            left = (v[0], v[0]) if lefts is None else lefts[k]
            right = (v[-1], v[-1]) if rights is None else rights[k]
            rows.append((t, left, right, True))
        seen = [(t, (lv, lv), (rv, rv), False) for t, lv, rv in self.seen]
        out = []
        y_before = (self.core.y, self.core.y) if self.b == INF else None
        for k in range(len(rows)):
            out.append(_since_interval(seen, rows[: k + 1], self.a, self.b, y_before))
        return out


def _since_interval(seen, rows, a, b, y_before) -> Interval:
    """The since at the last of ``rows`` by its definition, over the records ``seen`` (final)
    and ``rows`` (intervals); with an unbounded window, ``y_before`` is the since at the record
    before ``rows`` (the older records are not kept)."""
    if y_before is not None and a > 0:
        return EVERYTHING  # (the records it would need are not kept)
    records = seen + rows if y_before is None else rows
    ns = records[-1][0]
    lo = hi = -INF
    if y_before is not None:
        # the terms of the records before: min(Y there, l over all of rows)
        lmin = (min(r[1][0] for r in rows), min(r[1][1] for r in rows))
        lo, hi = min(y_before[0], lmin[0]), min(y_before[1], lmin[1])
    for j in range(len(records)):
        t = records[j][0]
        if not a <= ns - t <= b:
            continue
        term_lo, term_hi = records[j][2]
        for k in range(j + 1, len(records)):
            term_lo = min(term_lo, records[k][1][0])
            term_hi = min(term_hi, records[k][1][1])
        lo, hi = max(lo, term_lo), max(hi, term_hi)
    return (lo, hi)


# --------------------------------------------------------------------------- future


class FutureWindow(_Ordered):
    """``eventually[a,b]`` (``high``: max) or ``always[a,b]`` (min) of an immediate value or of
    a stream's. A record's value is final once a record later than its window has come and
    every value in its window is known; then the values in its window enter a monotonic
    wedge (each record enters and leaves once). Records are numbered (``seq``): one at the
    same time as record i but before it is not in i's window."""

    def __init__(self, source: _Ordered | None, high: bool, a: int, b: int) -> None:
        super().__init__()
        self.source, self.high, self.a, self.b = source, high, a, b
        self.empty = -INF if high else INF
        self.seq = 0  # the number of the next record
        self.outs: deque = deque()  # (seq, ns) of the records whose value is not given yet
        self.times: deque = deque()  # (seq, ns) of the records whose operand value waits
        self.vals: deque = deque()  # (seq, ns, v) known, beyond the oldest open window
        self.wedge: deque = deque()  # (seq, ns, v)
        self.newest = None
        # for at(): a wedge of the values in ``vals`` up to record ``caught``, brought up to
        # date when asked (each value enters and leaves it once)
        self.tail: deque = deque()
        self.caught = -1

    def step(self, ns: int, now=None) -> None:
        self.newest = ns
        seq = self.seq
        self.seq = seq + 1
        self.outs.append((seq, ns))
        source = self.source
        if source is None:
            self.vals.append((seq, ns, now))
        else:
            times, queue, vals = self.times, source.out, self.vals
            times.append((seq, ns))
            while queue:
                k, t = times.popleft()
                vals.append((k, t, queue.popleft()))
        self._settle()

    def _settle(self) -> None:
        outs, vals, wedge, times, out = self.outs, self.vals, self.wedge, self.times, self.out
        a, b, high, newest = self.a, self.b, self.high, self.newest
        while outs:
            i, ti = outs[0]
            last = ti + b
            if newest <= last or (times and times[0][1] <= last):
                return  # the window may still grow, or a value in it is not known
            first = ti + a
            while vals and vals[0][1] <= last:
                item = vals.popleft()
                if item[1] >= first and item[0] >= i:
                    v = item[2]
                    if high:
                        while wedge and wedge[-1][2] <= v:
                            wedge.pop()
                    else:
                        while wedge and wedge[-1][2] >= v:
                            wedge.pop()
                    wedge.append(item)
            while wedge and (wedge[0][1] < first or wedge[0][0] < i):
                wedge.popleft()
            out.append(wedge[0][2] if wedge else self.empty)
            outs.popleft()

    def waiting(self) -> int:
        return len(self.outs)

    def at(self, p: int) -> Interval:
        """The interval of the p-th open record, in O(log w). Its window's known values are
        the newest known from its start on (a window waits for the values in it, and the
        windows close in record order): the first of them in the wedge (the oldest open
        window's) and in a wedge of ``vals`` bounds them. Values in it still to come from a
        late operand only make the other end infinite (their intervals are not looked at)."""
        i, ti = self.outs[p]
        first, last = ti + self.a, ti + self.b
        best = self.empty
        for wedge in (self.wedge, self._tail()):
            k = _first_in(wedge, i, first)
            if k < len(wedge):
                v = wedge[k][2]
                if (v > best) if self.high else (v < best):
                    best = v
        # the window is open while records still to come may fall in it
        open_ = self.outs[-1][1] <= last
        times = self.times
        if times and not open_:
            k = _first_in(times, i, first)
            open_ = k < len(times) and times[k][1] <= last
        if not open_:
            return (best, best)
        return (best, INF) if self.high else (-INF, best)

    def _tail(self) -> deque:
        """``tail``, up to date: a monotonic wedge of the values in ``vals``."""
        vals, tail, high = self.vals, self.tail, self.high
        if not vals:
            tail.clear()
            return tail
        oldest, caught = vals[0][0], self.caught
        while tail and tail[0][0] < oldest:  # entered the wedge since
            tail.popleft()
        new = []
        for item in reversed(vals):
            if item[0] <= caught:
                break
            new.append(item)
        for item in reversed(new):
            v = item[2]
            if high:
                while tail and tail[-1][2] <= v:
                    tail.pop()
            else:
                while tail and tail[-1][2] >= v:
                    tail.pop()
            tail.append(item)
        self.caught = vals[-1][0]
        return tail

    def intervals(self) -> list[Interval]:
        """One pass: the records known (oldest first) in each open window are a run whose
        ends only move forward from one open record to the next, so a monotonic wedge per
        end of the interval gives each window's max (min)."""
        records = [(k, t, v, v) for k, t, v in (*self.wedge, *self.vals)]
        records += [(k, t, lo, hi) for (k, t), (lo, hi) in zip(self.times, _pending(self.source),
                                                               strict=True)]
        high, a, b, empty = self.high, self.a, self.b, self.empty
        lows: deque = deque()  # (position, value): a wedge of the lower ends in the window
        highs: deque = deque()
        out = []
        start = end = 0  # the window of the open record: records[start:end]
        # the newest record is the last owed a value (the generated code sets no ``newest``)
        newest = self.outs[-1][1] if self.outs else self.newest
        for i, ti in self.outs:
            while end < len(records) and records[end][1] <= ti + b:
                _, _, low, up = records[end]
                for wedge, v in ((lows, low), (highs, up)):
                    while wedge and (wedge[-1][1] <= v if high else wedge[-1][1] >= v):
                        wedge.pop()
                    wedge.append((end, v))
                end += 1
            while start < end and (records[start][0] < i or records[start][1] < ti + a):
                start += 1
            for wedge in (lows, highs):
                while wedge and wedge[0][0] < start:
                    wedge.popleft()
            lo = lows[0][1] if lows else empty
            hi = highs[0][1] if highs else empty
            if newest <= ti + b:  # records still to come may fall in the window
                lo, hi = (lo, INF) if high else (-INF, hi)
            out.append((lo, hi))
        return out


_IDENTITY = (-INF, INF)  # X ↦ max(-inf, min(inf, X)) = X


class UntilStream(_Ordered):
    """``l until[a,b] r``: ``max over j in the window of min(r@j, min over i <= k < j of l@k)``.

    Each record j of the window is the function ``X ↦ max(r@j, min(l@j, X))``; the value is the
    minimum of l over the records before the window and the composition of the window's
    functions applied to −inf. Compositions of such functions are of the same form, ``(r, l)``,
    so the window is a two-stack queue of compositions: O(1) amortised per record.
    """

    def __init__(self, left: _Ordered | None, right: _Ordered | None, a: int, b: int) -> None:
        super().__init__()
        self.left, self.right, self.a, self.b = left, right, a, b
        self.seq = 0
        self.outs: deque = deque()  # (seq, ns) of records whose value is not given yet
        self.times: deque = deque()  # (seq, ns, immediate value) of records whose operands wait
        self.before: deque = deque()  # (seq, ns, l) not yet in the wedge of l before the window
        self.lwedge: deque = deque()  # min of l: records from i to before the window
        self.inside: deque = deque()  # (seq, ns, r, l) not yet in the window's queue
        self.front: list = []  # (seq, ns, (R, L)): compositions from each to the front's end
        self.back: list = []  # (seq, ns, r, l), oldest first
        self.back_all = _IDENTITY
        self.newest = None
        self.known: deque = deque()  # (seq, ns, l, r) of the records the open windows reach

    def step(self, ns: int, *now) -> None:
        self.newest = ns
        seq = self.seq
        self.seq = seq + 1
        self.outs.append((seq, ns))
        self.times.append((seq, ns, now))
        lq = self.left.out if self.left is not None else None
        rq = self.right.out if self.right is not None else None
        times = self.times
        while times and (lq is None or lq) and (rq is None or rq):
            k, t, v = times.popleft()
            left = v[0] if lq is None else lq.popleft()
            right = v[-1] if rq is None else rq.popleft()
            self.before.append((k, t, left))
            self.inside.append((k, t, right, left))
            self.known.append((k, t, left, right))
        self._settle()

    def _settle(self) -> None:
        outs, times, a, b, newest = self.outs, self.times, self.a, self.b, self.newest
        before, lwedge, inside = self.before, self.lwedge, self.inside
        while outs:
            i, ti = outs[0]
            last = ti + b
            if newest <= last or (times and times[0][1] <= last):
                return
            first = ti + a
            while before and (before[0][1] < first or before[0][0] < i):
                item = before.popleft()
                while lwedge and lwedge[-1][2] >= item[2]:
                    lwedge.pop()
                lwedge.append(item)
            while lwedge and lwedge[0][0] < i:
                lwedge.popleft()
            while inside and inside[0][1] <= last:
                self._push(inside.popleft())
            while True:
                oldest = self._oldest()
                if oldest is None or (oldest[1] >= first and oldest[0] >= i):
                    break
                self._pop()
            fold = self._fold()[0]
            if lwedge and lwedge[0][2] < fold:
                fold = lwedge[0][2]
            self.out.append(fold)
            outs.popleft()
            known = self.known
            while known and known[0][0] < (outs[0][0] if outs else self.seq):
                known.popleft()

    # the two-stack queue of the window's functions
    def _push(self, item) -> None:
        self.back.append(item)
        self.back_all = _compose(self.back_all, (item[2], item[3]))

    def _oldest(self):
        if self.front:
            return self.front[-1]
        return self.back[0] if self.back else None

    def _pop(self) -> None:
        if not self.front:
            acc = _IDENTITY
            front = self.front
            for k, ns, r, left in reversed(self.back):
                acc = _compose((r, left), acc)
                front.append((k, ns, acc))
            self.back.clear()
            self.back_all = _IDENTITY
        self.front.pop()

    def _fold(self):
        head = self.front[-1][2] if self.front else _IDENTITY
        return _compose(head, self.back_all)

    def waiting(self) -> int:
        return len(self.outs)

    def intervals(self) -> list[Interval]:
        lefts = _pending(self.left) if self.left is not None else None
        rights = _pending(self.right) if self.right is not None else None
        records = [(k, t, (lv, lv), (rv, rv)) for k, t, lv, rv in self.known]
        for n, (k, t, v) in enumerate(self.times):
            left = (v[0], v[0]) if lefts is None else lefts[n]
            right = (v[-1], v[-1]) if rights is None else rights[n]
            records.append((k, t, left, right))
        out = []
        for i, ti in self.outs:
            lo = hi = -INF
            lmin_lo = lmin_hi = INF  # l over the records from i to before j
            for k, t, left, right in records:
                if k < i:
                    continue
                if t > ti + self.b:
                    break
                if t >= ti + self.a:
                    lo = max(lo, min(right[0], lmin_lo))
                    hi = max(hi, min(right[1], lmin_hi))
                lmin_lo, lmin_hi = min(lmin_lo, left[0]), min(lmin_hi, left[1])
            if self.newest <= ti + self.b:  # a record still to come may be the witness
                hi = max(hi, lmin_hi)
            out.append((lo, hi))
        return out


def _compose(f, g):
    """``f ∘ g`` for functions ``X ↦ max(r, min(l, X))`` given as ``(r, l)``."""
    r1, l1 = f
    r2, l2 = g
    inner = l1 if l1 < r2 else r2
    return (r1 if r1 > inner else inner, l1 if l1 < l2 else l2)


# --------------------------------------------------------------------------- pointwise


class PrevStream(_Ordered):
    """``prev(φ)`` of a stream: φ's value at the record before (``undefined`` at the first)."""

    def __init__(self, source: _Ordered, undefined) -> None:
        super().__init__()
        self.source = source
        self.undefined = undefined
        self.records = 0  # records come
        self.given = 0  # values given

    def step(self, ns: int) -> None:
        self.records += 1
        out, queue = self.out, self.source.out
        if self.given == 0:
            out.append(self.undefined)
            self.given = 1
        while queue and self.given < self.records:
            out.append(queue.popleft())
            self.given += 1

    def intervals(self) -> list[Interval]:
        known = [(v, v) for v in self.source.out]
        return (known + self.source.intervals())[: self.records - self.given]

    def at(self, p: int) -> Interval:
        return pending_at(self.source, p)


class Pointwise(_Ordered):
    """A function of one or two values, at least one of them a stream (``None`` in
    ``sources``: an immediate value, given to ``step``); ``interval`` is the same function
    of intervals."""

    def __init__(self, sources: Sequence[_Ordered | None], function: Callable,
                 interval: Callable) -> None:
        super().__init__()
        self.sources = list(sources)
        self.queues = [s.out if s is not None else None for s in sources]
        self.function, self.interval = function, interval
        # per record not given yet, its immediate value (None where there is none)
        self.held: deque = deque()

    def step(self, ns: int, now=None) -> None:
        held, queues, out, function = self.held, self.queues, self.out, self.function
        held.append(now)
        while held and all(q for q in queues if q is not None):
            immediate = held.popleft()
            args = [immediate if q is None else q.popleft() for q in queues]
            out.append(function(*args))

    def waiting(self) -> int:
        return len(self.held)

    def intervals(self) -> list[Interval]:
        pending = [_pending(s) for s in self.sources]
        out = []
        for k, now in enumerate(self.held):
            args = [(now, now) if s is None else p[k]
                    for s, p in zip(self.sources, pending, strict=True)]
            out.append(self.interval(*args))
        return out

    def at(self, p: int) -> Interval:
        now = self.held[p]
        return self.interval(*[(now, now) if s is None else pending_at(s, p)
                               for s in self.sources])


class Ordered(_Ordered):
    """The values of a boolean-semantics stream (:mod:`rasm.properties.streams`: a value that
    comes late, such as a count over a future operand), decided in any order, in record
    order. A value inconclusive at the end of the trace (None) is unknown. ``ranges``: the
    stream is a count (:class:`~rasm.properties.streams.CountStream`) compared with a value
    known at its record, and a value not known yet lies in the count's range."""

    def __init__(self, source, ranges: bool = False) -> None:
        super().__init__()
        self.source = source.out
        self.count = source if ranges else None
        self.next = None  # the record whose value goes out next
        self.newest = -1
        self.waiting: dict[int, object] = {}

    def step(self, i: int) -> None:
        if self.next is None:
            self.next = i
        self.newest = i
        waiting, source = self.waiting, self.source
        while source:
            j, _, _, v = source.popleft()
            waiting[j] = v
        j, out = self.next, self.out
        while j in waiting:
            v = waiting[j]
            if v is None:
                break
            out.append(waiting.pop(j))
            j += 1
        self.next = j

    def intervals(self) -> list[Interval]:
        waiting = dict(self.waiting)
        for j, _, _, v in self.source:
            waiting[j] = v
        out = []
        ranges = self.count.ranges() if self.count is not None else {}
        for j in range(self.next if self.next is not None else 0, self.newest + 1):
            v = waiting.get(j)
            out.append(ranges.get(j, EVERYTHING) if v is None else (v, v))
        return out

    def at(self, p: int) -> Interval:
        j = (self.next if self.next is not None else 0) + p
        v = self.waiting.get(j)
        for k, _, _, value in self.source:  # (decided since the step: none as a rule)
            if k == j:
                v = value
        if v is not None:
            return (v, v)
        return self.count.range_at(j) if self.count is not None else EVERYTHING
