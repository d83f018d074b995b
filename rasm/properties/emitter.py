"""What every semantics' code generator shares: names, constants, closure variables, lines.

A code generator is a :class:`~rasm.properties.visitor.Transformer` over a property's formula
that gives each node a :data:`Value` and writes the lines computing it. The boolean semantics
is :class:`rasm.properties.formula_code.FormulaGenerator`; another semantics (robustness: a
number per node) is another generator on this same base, and the boolean one stays as it is.

A generator's state is its own (the property being compiled, its lines, what its operators
left for their parents); the names it gives constants and closure variables come from the
program's :class:`Names`, which every generator writing into the program shares.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from rasm.properties.ast import INF, Expr
from rasm.properties.expr import HELPERS
from rasm.properties.lines import Line
from rasm.properties.operators import FutureOr
from rasm.properties.streams import Source, Stream
from rasm.properties.units import HELPERS as TIME_HELPERS
from rasm.properties.units import in_nanoseconds, in_seconds

__all__ = ["Emitter", "Later", "Names", "Now", "PropertyCode", "Value", "signal_variable"]


@dataclass(frozen=True)
class Now:
    """A value known at its own record: the source of the Python expression that computes it
    in the step function."""

    source: str


@dataclass(frozen=True)
class Later:
    """Values that come late (a future operator is below): each record's, as soon as it is
    decided, in any order (in record order where ``stream.ordered``), as ``(index, time,
    nanoseconds, value)`` in ``stream.out``."""

    stream: Source | Stream | FutureOr


Value = Now | Later


@dataclass(frozen=True)
class PropertyCode:
    """One property compiled: its lines at each record and at the end of the trace, then the
    lines that hand on its verdicts (``verdicts``: after ``body`` at each record, and after
    ``finish`` at the end where it is ``late``; a program may put its own lines between).

    ``late``: its verdicts come off a stream (``finish`` settles what is open at the end);
    ``owed`` names what holds, online, the records owed a verdict (a dict index -> time, or a
    deque of (index, time) where verdicts come in record order); ``order`` the
    :class:`~rasm.properties.streams.InOrder` that puts its verdicts back in record order
    offline (None: they come so)."""

    body: tuple[Line, ...]
    finish: tuple[Line, ...]
    late: bool
    owed: str | None = None
    order: str | None = None
    verdicts: tuple[Line, ...] = ()


def signal_variable(name: str) -> str:
    """The generated code's variable holding signal ``name``'s current value."""
    return f"g_{name}"


def late_positions(parts: Sequence[Value]) -> list[int]:
    """Which of ``parts`` come late."""
    return [k for k, part in enumerate(parts) if isinstance(part, Later)]


class Names:
    """The names one generated program defines: the constants it reads, its closure variables
    with their initial values, and which of them each property owns (its reset renews them).

    One per program, given to every generator that writes into it, so that two semantics'
    generators compiling the same properties never pick the same name.
    """

    def __init__(self) -> None:
        self._constants: dict[str, object] = {"deque": deque, "INF": INF, "NAN": math.nan}
        self._constants.update({**HELPERS, **TIME_HELPERS})
        self._state: dict[str, object] = {}
        self._owned: list[list[str]] = []
        self._count = 0

    @property
    def constants(self) -> dict[str, object]:
        """The objects the generated code reads, by name."""
        return self._constants

    @property
    def state(self) -> dict[str, object]:
        """The generated code's closure variables, with their initial values."""
        return self._state

    @property
    def owned(self) -> list[list[str]]:
        """Per property: the names of its constants and closure variables, which a reset
        renews."""
        return self._owned

    def fresh(self, prefix: str) -> str:
        """A name no other constant or variable has."""
        self._count += 1
        return f"{prefix}{self._count}"

    def constant(self, owner: int, prefix: str, value: object) -> str:
        """A new constant holding ``value``, of property ``owner``: its name."""
        name = self.fresh(prefix)
        self._constants[name] = value
        self.owned_by(owner).append(name)
        return name

    def variable(self, owner: int | None, prefix: str, initial: object) -> str:
        """A new closure variable starting at ``initial``: its name. Property ``owner``'s
        reset puts it back to ``initial`` (None: no reset does)."""
        name = self.fresh(prefix)
        self._state[name] = initial
        if owner is not None:
            self.owned_by(owner).append(name)
        return name

    def owned_by(self, number: int) -> list[str]:
        """The names property ``number`` owns so far."""
        while len(self._owned) <= number:
            self._owned.append([])
        return self._owned[number]


class Emitter:
    """A code generator's base: the lines of the property being compiled, and its names
    (from the program's :class:`Names`)."""

    def __init__(self, names: Names) -> None:
        self._names = names
        self._number = -1  # the property being compiled
        self._lines: list[Line] = []  # its lines at each record
        self._finish: list[Line] = []  # and at the end of the trace

    def _begin(self, number: int) -> None:
        """Start compiling property ``number``."""
        self._number = number
        self._names.owned_by(number)  # (a property may own nothing: it has its list)
        self._lines, self._finish = [], []

    def fresh(self, prefix: str) -> str:
        """A name no other constant or variable has."""
        return self._names.fresh(prefix)

    def constant(self, prefix: str, value: object) -> str:
        """A new constant of the property being compiled, holding ``value``: its name."""
        return self._names.constant(self._number, prefix, value)

    def variable(self, prefix: str, initial: object) -> str:
        """A new closure variable of the property being compiled: its name."""
        return self._names.variable(self._number, prefix, initial)

    def _in_units(self, operands: Sequence[Expr], parts: list[Value], exact: bool) -> list[Value]:
        """The values ``parts`` of ``operands`` as their parent computes with them: in
        nanoseconds where it is ``exact`` (time arithmetic, a comparison with a time), in
        seconds elsewhere. Values that come late are in seconds already."""
        convert = in_nanoseconds if exact else in_seconds
        out: list[Value] = []
        for child, part in zip(operands, parts, strict=True):
            if isinstance(part, Now):
                source = convert(child, part.source)
                if source is not part.source:
                    part = Now(source)
            out.append(part)
        return out
