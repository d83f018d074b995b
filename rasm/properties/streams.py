"""Sub-formulas whose values come late: anything above a future operator.

A stream node's values are ``(index, time, ns, value)`` tuples (``ns``: the record's time in
exact integer nanoseconds, what windows compare) appended to ``out`` as soon as each is
decided — in any order: ``p and eventually[0, 5] q`` is false at once where p is false, while
the records before it wait for q. Its inputs are other streams (read from their ``out``) or
*immediate* values, which the generated code passes to ``step`` at each record. ``step`` runs
once per record, after the steps of the node's inputs, so whatever a record decides reaches the
property in the same step. Values are three-valued (``None``: inconclusive) because streams
are where inconclusive values appear when an offline trace ends (``finish``).
"""

from __future__ import annotations

import math
from collections import deque

from rasm.properties import operators
from rasm.properties.expr import _COMPARE
from rasm.properties.operators import UNKNOWN, SinceWindow, UntilWindow, WindowCore, WindowOr

INF = math.inf

__all__ = [
    "AggregateStream",
    "CountStream",
    "InOrder",
    "JoinStream",
    "PrevStream",
    "SinceStream",
    "Source",
    "Stream",
    "UntilStream",
    "WindowStream",
    "kleene_function",
]


class Source:
    """Anything with an ``out`` deque of decided ``(index, time, ns, value)`` tuples;
    ``ordered``: they come in record order (an inline future window over immediate values)."""

    ordered = False

    def __init__(self, ordered: bool = False) -> None:
        self.out: deque = deque()
        self.ordered = ordered


class Stream:
    """A node reading other streams' values (``None`` in ``inputs``: an immediate value)."""

    ordered = False  # (Source.ordered) its values may come in any order

    def __init__(self, inputs: list[Source | None]) -> None:
        self.out: deque = deque()
        self.queues = [s.out if s is not None else None for s in inputs]

    def step(self, i: int, t, ns: int, *values) -> None:
        raise NotImplementedError

    def finish(self) -> None:
        """The end of the trace: take the inputs' last values, settle what is open."""
        self.step_inputs()

    def step_inputs(self) -> None:
        raise NotImplementedError


class WindowStream(Stream):
    """``once[a,b]`` (``past``) or ``eventually[a,b]`` of a stream (:class:`WindowOr`)."""

    def __init__(self, inputs, past: bool, a: int, b: int | float) -> None:
        super().__init__(inputs)
        self.core = WindowOr(past, a, b)
        self.out = self.core.out

    def step(self, i: int, t, ns: int) -> None:
        core = self.core
        core.record(i, t, ns)
        queue = self.queues[0]
        if queue:
            put = core.put
            while queue:
                j, _, _, v = queue.popleft()
                put(j, v)

    def step_inputs(self) -> None:
        queue, put = self.queues[0], self.core.put
        while queue:
            j, _, _, v = queue.popleft()
            put(j, v)

    def finish(self) -> None:
        self.step_inputs()
        self.core.finish()


class _Pair(Stream):
    """``since``/``until`` of two operands, one of which may be immediate."""

    def __init__(self, inputs, core) -> None:
        super().__init__(inputs)
        self.core = core
        self.out = core.out

    def step(self, i: int, t, ns: int, *values) -> None:
        core = self.core
        core.record(i, t, ns)
        left, right = self.queues
        if left is None:
            core.put_left(i, values[0])
        elif right is None:
            core.put_right(i, values[0])
        self.step_inputs()

    def step_inputs(self) -> None:
        core = self.core
        left, right = self.queues
        while left:
            j, _, _, v = left.popleft()
            core.put_left(j, v)
        while right:
            j, _, _, v = right.popleft()
            core.put_right(j, v)
        core.settle()

    def finish(self) -> None:
        self.step_inputs()
        self.core.finish()


class SinceStream(_Pair):
    """``l since[a,b] r`` with a stream operand (:class:`SinceWindow`)."""

    def __init__(self, inputs, a: int, b: int | float) -> None:
        super().__init__(inputs, SinceWindow(a, b))


class UntilStream(_Pair):
    """``l until[a,b] r`` with a stream operand (:class:`UntilWindow`)."""

    def __init__(self, inputs, a: int, b: int) -> None:
        super().__init__(inputs, UntilWindow(a, b))


class JoinStream(Stream):
    """A binary operator over two streams: ``and``/``or``/``->`` decide as soon as one side
    does; anything else once both sides are known."""

    def __init__(self, inputs, op: str, plain) -> None:
        super().__init__(inputs)
        self.function = kleene_function(op, plain)
        # the value of one side that decides alone, or None
        self.decisive = {"and": (False, False), "or": (True, True), "->": (False, True)}.get(op)
        self.op = op
        self.waiting: dict[int, tuple[int, object]] = {}  # record -> (side, value) known
        self.given: set[int] = set()  # decided by one side; the other's value still to come

    def step(self, i: int, t, ns: int) -> None:
        self.step_inputs()

    def step_inputs(self) -> None:
        left, right = self.queues
        while left:
            self._take(0, left.popleft())
        while right:
            self._take(1, right.popleft())

    def _take(self, side: int, item: tuple) -> None:
        j, t, ns, v = item
        known = self.waiting.pop(j, None)
        if known is None:
            if j in self.given:
                self.given.discard(j)
                return
            decisive = self.decisive
            if decisive is not None and v is decisive[side]:
                # false and …, true or …, false -> …, … -> true
                self.out.append((j, t, ns, v if self.op != "->" else True))
                self.given.add(j)
                return
            self.waiting[j] = (side, v)
            return
        other = known[1]
        value = self.function(other, v) if side == 1 else self.function(v, other)
        self.out.append((j, t, ns, value))


class PrevStream(Stream):
    """``prev(e)`` over a stream: e's value at the record before (``undefined`` at the first
    record), given as soon as that one is known and this record has come."""

    def __init__(self, inputs, undefined) -> None:
        super().__init__(inputs)
        self.undefined = undefined
        self.first = True
        self.records: dict[int, tuple] = {}  # record -> (t, ns) whose value is not known yet
        self.known: dict[int, object] = {}  # e's value at the newest record, once known
        self.newest = -1

    def step(self, i: int, t, ns: int) -> None:
        self.newest = i
        if self.first:
            self.first = False
            self.out.append((i, t, ns, self.undefined))
        else:
            v = self.known.pop(i - 1, UNKNOWN)
            if v is UNKNOWN:
                self.records[i] = (t, ns)
            else:
                self.out.append((i, t, ns, v))
        self.step_inputs()

    def step_inputs(self) -> None:
        queue, records = self.queues[0], self.records
        while queue:
            j, _, _, v = queue.popleft()
            waiting = records.pop(j + 1, None)
            if waiting is not None:
                self.out.append((j + 1, waiting[0], waiting[1], v))
            elif j == self.newest:
                self.known[j] = v


def window_ends(times: list[int], base: int, low: int, high: int, i: int, ns: int, a: int,
                b: int | float) -> tuple[int, int]:
    """The first and last record of record ``i``'s window (the records j <= i with
    ``a <= ns - times[j - base] <= b``), moved on from the previous record's ``low, high``."""
    if b != INF:
        while ns - times[low - base] > b:  # stops at i at the latest
            low += 1
    while high < i and ns - times[high + 1 - base] >= a:
        high += 1
    return low, high


class AggregateStream(Stream):
    """An aggregate over a stream.

    A record's window (the records j <= i with ``a <= t_i - t_j <= b``) is known when the
    record comes: an empty one gives its value at once. The others are given in record order:
    their records enter the aggregate's window in order as their values become known, and a
    record's value is given once its whole window has entered (inconclusive while an
    inconclusive value is in it). Over values that come in record order
    (``count[0, 2](eventually[0, 1] p)``) that is as soon as the window is known; over values
    that come in any order (``count[0, 2](p and eventually[0, 1] q)``) a record may also wait
    for an earlier record's window.
    """

    def __init__(self, inputs, op: str, a: int, b: int | float) -> None:
        super().__init__(inputs)
        self.core = WindowCore(op, a, b)
        self.empty = WindowCore(op, a, b).value()  # the value over no record
        self.a, self.b = a, b
        self.ns: list[int] = []  # ns[k]: the time of record base + k
        self.base = 0
        self.low = self.high = self.entered = None  # windows' ends, next record to enter
        self.records: deque = deque()  # (index, t, ns, low, high) whose value is not given
        self.known: dict[int, object] = {}  # values of records not in the window yet

    def step(self, i: int, t, ns: int) -> None:
        times = self.ns
        if self.low is None:
            self.base = self.low = self.entered = i
            self.high = i - 1
        times.append(ns)
        base = self.base
        low, high = window_ends(times, base, self.low, self.high, i, ns, self.a, self.b)
        self.low, self.high = low, high
        if low > high:
            self.out.append((i, t, ns, self.empty))
        else:
            self.records.append((i, t, ns, low, high))
        self.step_inputs()
        keep = (self.entered if self.b == INF else min(self.entered, low)) - base
        if keep > operators.BATCH and keep * 2 > len(times):
            del times[:keep]
            self.base += keep

    def step_inputs(self) -> None:
        queue, known, entered = self.queues[0], self.known, self.entered
        while queue:
            j, _, _, v = queue.popleft()
            if j >= entered:
                known[j] = v
        records, core, times = self.records, self.core, self.ns
        while records:
            i, t, ns, low, high = records[0]
            j = self.entered
            while j <= high:
                if j < low:  # before this window (and the later ones): not needed
                    known.pop(j, None)
                else:
                    v = known.pop(j, UNKNOWN)
                    if v is UNKNOWN:
                        self.entered = j
                        return  # the window waits for this value
                    core.enter((times[j - self.base], v))
                j += 1
            self.entered = j
            records.popleft()
            self.out.append((i, t, ns, core.at(ns)))


class _Open:
    """A record of a :class:`CountStream` whose value is not given yet: its window, the value
    compared with (UNKNOWN until given), what decides the comparison, its buckets."""

    __slots__ = ("i", "t", "ns", "low", "high", "against", "rule", "keys", "final", "done")

    def __init__(self, i: int, t, ns: int, low: int, high: int) -> None:
        self.i, self.t, self.ns, self.low, self.high = i, t, ns, low, high
        self.against = UNKNOWN
        self.rule: tuple | None = None  # (kt needed, value then, kf needed, value then)
        self.keys: tuple | None = None  # its buckets: (true total, false total), once active
        self.final: tuple | None = None  # (kt, kf, kn) once its whole window has entered
        self.done = False  # its value is given


# ``count op v`` as ``count op' v`` with the count on the left
_MIRROR = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}
_ZERO = (0, 0, 0)


class CountStream(Stream):
    """``count[a,b]`` of a stream, and a comparison of that count with a value known at its
    record (``count[0, 5](eventually[0, 1] p) >= 3``), decided as soon as the count's possible
    range fixes it.

    A record's window (the records j <= i with ``a <= t_i - t_j <= b``) is known when the
    record comes. The operand's values enter in record order (``entered``: the first record
    whose value has not), each adding to running totals of true, false and inconclusive
    values; ``totals[k]`` holds them before record ``base + k``, so what has entered of any
    window is two subtractions. A window of n records of which kt have entered true and kf
    false has a count in [kt, n - kf] (:meth:`ranges`); once the whole window has entered the
    count is given, in record order (inconclusive where a value is).

    After :meth:`compare`, the stream's values are those of the comparison, ``v`` given for
    each record by :meth:`against` after its step. The range fixes it once kt reaches one
    number or kf another (both only grow): an open record waits in one bucket per side, keyed
    by the running total that side must reach, so each value entering looks in one bucket.
    Values that come out of record order wait for those before them (as in
    :class:`AggregateStream`). O(1) amortised work per record, memory bounded by the window
    and the records still open.
    """

    def __init__(self, inputs, a: int, b: int | float) -> None:
        super().__init__(inputs)
        self.a, self.b = a, b
        self.ns: list[int] = []  # ns[k]: the time of record base + k
        self.totals: list[tuple[int, int, int]] = []  # (true, false, None) before base + k
        self.base = self.origin = 0
        self.low = self.high = self.entered = None  # the newest window's ends, next to enter
        self.known: dict[int, object] = {}  # values of records from ``entered`` on
        self.open: deque = deque()  # _Open records whose window has not entered yet
        self.newest: _Open | None = None
        # with a comparison
        self.op: str | None = None
        self.flip = False
        self.inactive: deque = deque()  # open records none of whose window has entered
        self.by_true: dict[int, dict[int, _Open]] = {}
        self.by_false: dict[int, dict[int, _Open]] = {}
        self.rule: tuple = (None, UNKNOWN, None)  # (window size, value, _rule of them)
        self.steps = 0  # since the last _forget

    def compare(self, op: str, position: int) -> None:
        """From now on, the values of ``count op v`` (``position`` 1: ``v op count``)."""
        self.op = op if position == 0 else _MIRROR[op]

    # ----------------------------------------------------------------- records
    def step(self, i: int, t, ns: int) -> None:
        times = self.ns
        if self.low is None:
            self.base = self.origin = self.low = self.entered = i
            self.high = i - 1
            self.totals.append(_ZERO)
        times.append(ns)
        base = self.base
        low, high = window_ends(times, base, self.low, self.high, i, ns, self.a, self.b)
        self.low, self.high = low, high
        record = self.newest = _Open(i, t, ns, low, high)
        if low > high:  # an empty window: a count of 0
            record.final = _ZERO
            if self.op is None:
                self.out.append((i, t, ns, 0))
        else:
            self.open.append(record)
        self.step_inputs()
        self.steps += 1
        if self.steps > operators.BATCH:  # forgotten in batches: O(1) amortised
            self.steps = 0
            self._forget()

    def against(self, i: int, v) -> None:
        """Record ``i``'s value of the other side of the comparison (after its step)."""
        record = self.newest
        record.against = v
        n = record.high - record.low + 1
        rule = self.rule  # the last one: mostly the same value and window size
        if rule[0] != n or rule[1] is not v:
            self.rule = rule = (n, v, _rule(self.op, v, n))
        record.rule = rule[2]
        if record.final is not None:
            self._give(record, record.final)
        elif record.low <= self.entered:
            self._activate(record)
        elif self._judge(record, 0, 0) is not None:  # decided by the window's size alone
            self._decide(record, self._judge(record, 0, 0))
        else:
            self.inactive.append(record)

    def ranges(self) -> dict[int, tuple[int, int]]:
        """The range of the count at each record whose window has not entered yet."""
        out = {}
        for record in self.open:
            kt, kf, _ = self._entered(record)
            out[record.i] = (kt, record.high - record.low + 1 - kf)
        return out

    def range_at(self, j: int) -> tuple[float, float]:
        """``ranges()[j]``, (−inf, inf) where it has none: a binary search of ``open``."""
        open_ = self.open
        low, high = 0, len(open_)
        while low < high:
            middle = (low + high) // 2
            if open_[middle].i < j:
                low = middle + 1
            else:
                high = middle
        if low == len(open_) or open_[low].i != j:
            return (-INF, INF)
        record = open_[low]
        kt, kf, _ = self._entered(record)
        return (kt, record.high - record.low + 1 - kf)

    # ----------------------------------------------------------------- values
    def step_inputs(self) -> None:
        queue, known = self.queues[0], self.known
        while queue:
            j, _, _, v = queue.popleft()
            known[j] = v
        totals, open_, inactive = self.totals, self.open, self.inactive
        entered = self.entered
        while True:
            while open_ and open_[0].high < entered:  # its whole window has entered
                record = open_.popleft()
                if self.op is None:
                    kt, _, kn = self._entered(record)
                    self.out.append((record.i, record.t, record.ns, None if kn else kt))
                elif not record.done:
                    record.final = self._entered(record)
                    if record.rule is not None:  # (else: the comparison's value is to come)
                        self._give(record, record.final)
            if entered not in known:
                return
            v = known.pop(entered)
            tt, tf, tn = totals[-1]
            if v is None:
                tn += 1
            elif v:
                tt += 1
            else:
                tf += 1
            totals.append((tt, tf, tn))
            entered += 1
            self.entered = entered
            if self.op is None:
                continue
            if v is not None:
                bucket = self.by_true.pop(tt, None) if v else self.by_false.pop(tf, None)
                if bucket:  # each of these records has reached its total (its window holds
                    # the value entered: those whose window ends before it have gone above)
                    for record in list(bucket.values()):
                        kt, kf, _ = self._entered(record)
                        self._decide(record, self._judge(record, kt, kf))
            while inactive and inactive[0].low <= entered:
                self._activate(inactive.popleft())

    def _entered(self, record: _Open) -> tuple[int, int, int]:
        """(true, false, None) among the values of ``record``'s window entered so far."""
        end, low = self.entered, record.low
        if end > record.high:
            end = record.high + 1
        if end <= low:
            return _ZERO
        totals, base = self.totals, self.base
        high = totals[end - base]
        if low == self.origin:
            return high
        low_ = totals[low - base]
        return (high[0] - low_[0], high[1] - low_[1], high[2] - low_[2])

    def _activate(self, record: _Open) -> None:
        """Part of ``record``'s window has entered: decide it, or file it in its buckets."""
        if record.done:
            return
        kt, kf, _ = self._entered(record)
        value = self._judge(record, kt, kf)
        if value is not None:
            self._decide(record, value)
            return
        tt, tf, _ = self.totals[-1]
        need_true, _, need_false, _ = record.rule
        keys = (tt + need_true - kt, tf + need_false - kf)
        record.keys = keys
        if keys[0] != INF:
            self.by_true.setdefault(keys[0], {})[record.i] = record
        if keys[1] != INF:
            self.by_false.setdefault(keys[1], {})[record.i] = record

    def _judge(self, record: _Open, kt: int, kf: int):
        """The comparison at ``record`` where the range fixes it, else None."""
        need_true, if_true, need_false, if_false = record.rule
        if kt >= need_true:
            return if_true
        if kf >= need_false:
            return if_false
        return None

    def _decide(self, record: _Open, value) -> None:
        """Give ``record``'s value (None: inconclusive), once."""
        if record.done:
            return
        record.done = True
        keys = record.keys
        if keys is not None:  # out of its buckets
            record.keys = None
            for buckets, key in ((self.by_true, keys[0]), (self.by_false, keys[1])):
                bucket = buckets.get(key)
                if bucket is not None:
                    bucket.pop(record.i, None)
                    if not bucket:
                        del buckets[key]
        self.out.append((record.i, record.t, record.ns, value))

    def _give(self, record: _Open, final: tuple[int, int, int]) -> None:
        """``record``'s whole window has entered: its value, if not given yet."""
        if record.done:
            return
        kt, kf, kn = final
        if kn:  # an inconclusive value in it: what the range fixes, else inconclusive
            self._decide(record, self._judge(record, kt, kf))
        else:
            self._decide(record, _COMPARE[self.op](kt, record.against))

    def _forget(self) -> None:
        """Drop the times and totals no window still open or to come needs."""
        finite = self.b != INF
        keep = min(self.entered, self.high + 1, self.low if finite else self.entered)
        for record in (self.open[0] if self.open else None, self.newest):
            if record is not None and record.final is None:
                keep = min(keep, record.low if finite else record.high + 1)
        keep -= self.base
        if keep > operators.BATCH and keep * 2 > len(self.ns):
            del self.ns[:keep]
            del self.totals[:keep]
            self.base += keep

    def finish(self) -> None:
        self.step_inputs()
        for record in self.open:  # (every value has come: none is left)
            if not record.done:
                self.out.append((record.i, record.t, record.ns, None))
        self.open.clear()


def _rule(op: str | None, v, n: int) -> tuple:
    """How ``count op v`` over a window of ``n`` records is decided from its values entered
    so far, kt true and kf false: (kt needed, the value then, kf needed, the value then); INF:
    never before the whole window has entered."""
    if op is None:
        return (INF, None, INF, None)
    if v.__class__ not in (int, float):  # a number of another kind: compared at the end
        return (INF, None, INF, None)
    if v != v:  # undefined: every comparison is false
        return (0, False, 0, False)
    if op in ("==", "!="):
        # count == m is false once kt > m or n - kf < m
        if v in (INF, -INF) or v != int(v):
            return (0, op == "!=", 0, op == "!=")
        m = int(v)
        return (m + 1, op == "!=", n - m + 1, op == "!=")
    # count op v is (count >= m) or (count < m)
    if v == INF or v == -INF:
        m = v
    elif op in (">=", "<"):
        m = math.ceil(v)
    else:
        m = math.floor(v) + 1
    up = op in (">=", ">")
    # count >= m once kt >= m; count < m once n - kf < m
    return (m if m != -INF else 0, up, n - m + 1 if m != INF else 0, not up)


class InOrder:
    """Hands a property's values on in record order (offline, ``Monitor.run``) though they are
    decided in any order; ``next`` is the record whose value comes next."""

    __slots__ = ("next", "waiting")

    def __init__(self) -> None:
        self.next = 0
        self.waiting: dict[int, object] = {}

    def put(self, j: int, v, append) -> None:
        if j != self.next:
            self.waiting[j] = v
            return
        append(v)
        j += 1
        waiting = self.waiting
        while waiting:
            v = waiting.pop(j, UNKNOWN)
            if v is UNKNOWN:
                break
            append(v)
            j += 1
        self.next = j


# --------------------------------------------------------------------------- Kleene logic


def _and(a, b):
    if a is False or b is False:
        return False
    if a is None or b is None:
        return None
    return bool(a and b)


def _or(a, b):
    if a is True or b is True:
        return True
    if a is None or b is None:
        return None
    return bool(a or b)


def _implies(a, b):
    return _or(_not(a), b)


def _not(a):
    return None if a is None else not a


def kleene_function(op: str, plain):
    """The three-valued version of operator ``op`` whose two-valued version is ``plain``."""
    if op == "and":
        return _and
    if op == "or":
        return _or
    if op == "->":
        return _implies
    if op == "not":
        return _not

    def lifted(*values):
        if None in values:
            return None
        return plain(*values)

    return lifted
