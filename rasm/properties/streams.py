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
from rasm.properties.operators import UNKNOWN, SinceWindow, UntilWindow, WindowCore, WindowOr

INF = math.inf

__all__ = [
    "AggregateStream",
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
        base, low, high = self.base, self.low, self.high
        if self.b != INF:
            while ns - times[low - base] > self.b:  # stops at i at the latest
                low += 1
        while high < i and ns - times[high + 1 - base] >= self.a:
            high += 1
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
