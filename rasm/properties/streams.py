"""Sub-formulas whose values arrive late: anything above a future operator.

A stream node's values are ``(index, time, ns, value)`` tuples (``ns``: the record's time in
exact integer nanoseconds, what windows compare) appended to ``out`` in index order, as soon as
they are decided. Its inputs are other streams (read from their ``out``) or
*immediate* values, which the generated code passes to :meth:`Stream.step` at each record.
Values are three-valued (``None``: inconclusive) because streams are where inconclusive values
appear when an offline trace ends.
"""

from __future__ import annotations

from collections import deque

from rasm.properties.operators import Kleene, WindowCore

__all__ = [
    "AggregateStream",
    "PointwiseStream",
    "PrevStream",
    "Source",
    "Stream",
    "TemporalStream",
    "kleene_function",
]


class Source:
    """Anything with an ``out`` deque of decided ``(index, time, ns, value)`` tuples."""

    def __init__(self) -> None:
        self.out: deque = deque()


class Stream:
    """Aligns its inputs by record and hands each complete record to :meth:`consume`."""

    def __init__(self, inputs: list[Source | Stream | None]) -> None:
        self.out: deque = deque()
        self.buffers = [s.out if s is not None else deque() for s in inputs]
        self.immediate = [self.buffers[k] for k, s in enumerate(inputs) if s is None]

    def step(self, i: int, t, ns: int, *values) -> None:
        for buffer, value in zip(self.immediate, values, strict=True):
            buffer.append((i, t, ns, value))
        self.drain()

    def drain(self) -> None:
        buffers = self.buffers
        if len(buffers) == 1:
            only = buffers[0]
            while only:
                i, t, ns, v = only.popleft()
                self.consume(i, t, ns, (v,))
            return
        while all(buffers):
            items = [b.popleft() for b in buffers]
            i, t, ns, _ = items[0]
            self.consume(i, t, ns, tuple(item[3] for item in items))

    def consume(self, i: int, t, ns: int, values: tuple) -> None:
        raise NotImplementedError

    def finish(self) -> None:
        """Process what the inputs decided while finishing; settle open windows."""
        self.drain()


class PointwiseStream(Stream):
    """A non-temporal operator applied record by record (three-valued)."""

    def __init__(self, inputs, function) -> None:
        super().__init__(inputs)
        self.function = function

    def consume(self, i, t, ns, values) -> None:
        self.out.append((i, t, ns, self.function(*values)))


class PrevStream(Stream):
    """``prev(e)`` over a stream: the previous record's value (``undefined`` at the first)."""

    def __init__(self, inputs, undefined) -> None:
        super().__init__(inputs)
        self.previous = undefined

    def consume(self, i, t, ns, values) -> None:
        self.out.append((i, t, ns, self.previous))
        self.previous = values[0]


class TemporalStream(Stream):
    """A boolean temporal operator (past or future) through :class:`Kleene`.

    A future operator also watches the records go by: its inputs may come late, but a window
    is over as soon as the first record whose value has not arrived yet lies beyond it.
    """

    def __init__(self, inputs, core) -> None:
        super().__init__(inputs)
        self.kleene = Kleene(core)
        self.out = self.kleene.out
        self.waiting: deque | None = deque() if self.kleene.future else None

    def step(self, i: int, t, ns: int, *values) -> None:
        waiting = self.waiting
        if waiting is None:
            Stream.step(self, i, t, ns, *values)
            return
        waiting.append((i, ns))
        Stream.step(self, i, t, ns, *values)
        if waiting:
            self.kleene.close(waiting[0][1])

    def consume(self, i, t, ns, values) -> None:
        waiting = self.waiting
        if waiting is not None:
            while waiting and waiting[0][0] <= i:
                waiting.popleft()
        self.kleene.push(i, t, ns, *values)

    def finish(self) -> None:
        self.drain()
        self.kleene.flush()


class AggregateStream(Stream):
    """An aggregate over a stream (inconclusive while an inconclusive value is in its window)."""

    def __init__(self, inputs, op: str, a: int, b: int | float) -> None:
        super().__init__(inputs)
        self.core = WindowCore(op, a, b)

    def consume(self, i, t, ns, values) -> None:
        self.out.append((i, t, ns, self.core.push(ns, values[0])))


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

