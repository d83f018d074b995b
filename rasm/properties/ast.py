"""The syntax tree of the property language: plain, frozen data.

Every node carries a ``location`` (keyword-only, ignored by ``==``) pointing into the user's
file, so that type errors and explanations name the place. The expression nodes (``Literal`` to
``Call``) are the sub-language shared with the legitimacy rules; ``Time``, ``Prev``
and the temporal nodes exist only in property files.

The node classes are listed in :data:`NODES`; the fields of a node typed ``Expr`` (or
``tuple[Expr, ...]``) hold its sub-expressions, so :func:`children`, :func:`walk` and
:func:`rebuild` work for every node alike. What a node *means* is up to each pass over the tree
(:mod:`rasm.properties.visitor`: one method per node class).

Operators are plain strings:

* ``Unary.op``: ``"-"`` (numeric negation);
* ``Binary.op``: ``"+" "-" "*" "/"`` (arithmetic), ``"==" "!=" "<" "<=" ">" ">="``
  (comparisons), ``"and" "or" "->"`` (boolean; ``->`` is implication);
* ``Call.func``: ``"abs"`` (one argument), ``"min"`` / ``"max"`` (two arguments); any other
  name parses and is rejected by the type checker as an unknown function.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, fields, replace
from itertools import chain
from operator import attrgetter, is_
from typing import Union

from rasm.errors import Location
from rasm.properties.times import format_nanoseconds, nanoseconds

__all__ = [
    "EXPRESSIONS",
    "NODES",
    "TEMPORAL",
    "Aggregate",
    "Binary",
    "Bound",
    "Call",
    "Declaration",
    "Event",
    "Expr",
    "Future",
    "Input",
    "Let",
    "Literal",
    "Name",
    "Not",
    "Past",
    "Prev",
    "Property",
    "Since",
    "Specification",
    "Time",
    "Unary",
    "Until",
    "children",
    "rebuild",
    "walk",
]

UNKNOWN = Location("<text>")
INF = math.inf

ARITHMETIC = ("+", "-", "*", "/")
COMPARISONS = ("==", "!=", "<", "<=", ">", ">=")
BOOLEAN = ("and", "or", "->")


def _loc():
    return field(default=UNKNOWN, compare=False, kw_only=True, repr=False)


# --------------------------------------------------------------------------- expressions


class Expr:
    """A node of a formula's syntax tree (every node class below derives from it); its fields
    typed ``Expr`` or ``tuple[Expr, ...]`` hold its sub-expressions, left to right."""


@dataclass(frozen=True)
class Literal(Expr):
    """A constant: ``int``, ``float``, ``bool`` (``true``/``false``) or ``str``."""

    value: int | float | bool | str
    location: Location = _loc()


@dataclass(frozen=True)
class Name(Expr):
    """A signal (or, in a property file, a ``let``-defined name) read at the current record."""

    name: str
    location: Location = _loc()


@dataclass(frozen=True)
class Unary(Expr):
    """Numeric negation ``-operand`` (``op`` is always ``"-"``)."""

    op: str
    operand: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Not(Expr):
    """Boolean negation ``not operand``."""

    operand: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Binary(Expr):
    """``left op right`` for arithmetic, comparison and ``and``/``or``/``->`` operators."""

    op: str
    left: Expr
    right: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Call(Expr):
    """A function call ``func(args…)``: ``abs(e)``, ``min(a, b)``, ``max(a, b)``."""

    func: str
    args: tuple[Expr, ...]
    location: Location = _loc()


# --------------------------------------------------------------------------- property-only


@dataclass(frozen=True)
class Time(Expr):
    """``time``: the timestamp of the current record, in seconds."""

    location: Location = _loc()


@dataclass(frozen=True)
class Prev(Expr):
    """``prev(operand)``: the operand's value at the previous record (undefined at the first)."""

    operand: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Bound:
    """A time interval ``[low, high]`` in seconds; ``high`` may be ``math.inf``.

    ``low_ns`` and ``high_ns`` are the same bounds in exact integer nanoseconds (``high_ns``
    ``math.inf`` when unbounded): what the monitors compare. The parser takes them from the
    bound's text; when they are not given, they are those of the decimals the seconds stand
    for (``0.1`` is 100000000 ns).
    """

    low: float
    high: float
    location: Location = _loc()
    low_ns: int = field(default=None, kw_only=True)  # type: ignore[assignment]
    high_ns: int | float = field(default=None, kw_only=True)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        # a frozen dataclass sets its derived fields through object.__setattr__
        if self.low_ns is None:
            object.__setattr__(self, "low_ns", _nanoseconds(self.low))
        if self.high_ns is None:
            object.__setattr__(self, "high_ns", _nanoseconds(self.high))

    def __str__(self) -> str:
        def fmt(ns: int | float) -> str:  # exact: 1e6 s is 1000000, not 1e+06
            return "inf" if ns == INF else format_nanoseconds(ns)

        return f"[{fmt(self.low_ns)}, {fmt(self.high_ns)}]"


@dataclass(frozen=True)
class Past(Expr):
    """``once[bound] operand`` or ``historically[bound] operand`` (``op`` names which)."""

    op: str
    bound: Bound
    operand: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Future(Expr):
    """``eventually[bound] operand`` or ``always[bound] operand`` (``op`` names which).

    An unbounded ``always`` (``bound.high`` infinite) is only valid as the outermost operator
    of a property, where it means "at every record"; the loader strips it.
    """

    op: str
    bound: Bound
    operand: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Since(Expr):
    """``left since[bound] right``: right held in the window and left ever since."""

    left: Expr
    right: Expr
    bound: Bound
    location: Location = _loc()


@dataclass(frozen=True)
class Until(Expr):
    """``left until[bound] right``: right will hold in the window and left until then."""

    left: Expr
    right: Expr
    bound: Bound
    location: Location = _loc()


@dataclass(frozen=True)
class Aggregate(Expr):
    """``op[bound](operand)`` with ``op`` in count, sum, avg, min, max, over the past window."""

    op: str
    bound: Bound
    operand: Expr
    location: Location = _loc()


# the sub-language shared with the legitimacy rules, and the nodes only property files have
EXPRESSIONS: tuple[type[Expr], ...] = (Literal, Name, Unary, Not, Binary, Call)
TEMPORAL: tuple[type[Expr], ...] = (Time, Prev, Past, Future, Since, Until, Aggregate)
NODES = EXPRESSIONS + TEMPORAL  # every node class: each pass has a method for each


def _operands(cls: type[Expr]) -> tuple[tuple[str, bool], ...]:
    """The fields of ``cls`` holding sub-expressions, each with whether it holds several
    (the annotations are strings: this module postpones them)."""
    kinds = {"Expr": False, "tuple[Expr, ...]": True}
    return tuple((f.name, kinds[f.type]) for f in fields(cls) if f.type in kinds)


def _reader(operands: tuple[tuple[str, bool], ...]) -> Callable[[Expr], tuple[Expr, ...]]:
    """A fast reader of a node's sub-expressions, given its class's operand fields."""
    names = [name for name, _ in operands]
    if not operands:
        return lambda node: ()
    if operands == ((names[0], True),):
        return attrgetter(names[0])  # a tuple already
    if not any(several for _, several in operands):
        if len(names) == 1:
            name = names[0]
            return lambda node: (getattr(node, name),)
        return attrgetter(*names)  # a tuple of them
    return lambda node: tuple(chain.from_iterable(
        getattr(node, name) if several else (getattr(node, name),) for name, several in operands
    ))


_OPERANDS = {cls: _operands(cls) for cls in NODES}
_CHILDREN = {cls: _reader(operands) for cls, operands in _OPERANDS.items()}


def children(node: Expr) -> tuple[Expr, ...]:
    """The direct sub-expressions of ``node``, left to right."""
    return _CHILDREN[node.__class__](node)


def walk(node: Expr) -> Iterator[Expr]:
    """``node`` and every node below it, parents before children, left to right (without
    recursing: formulas may nest deeper than Python's recursion limit allows)."""
    stack = [node]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(reversed(_CHILDREN[node.__class__](node)))


def rebuild(node: Expr, new: Sequence[Expr]) -> Expr:
    """``node`` with its sub-expressions replaced by ``new`` (as many, in the same order);
    ``node`` itself where they are its own."""
    operands = _OPERANDS[node.__class__]
    if all(map(is_, new, children(node))):  # (a leaf: nothing to replace)
        return node
    rest = iter(new)
    changes: dict[str, object] = {}
    for name, several in operands:
        if several:
            changes[name] = tuple(next(rest) for _ in getattr(node, name))
        else:
            changes[name] = next(rest)
    return replace(node, **changes)


def _nanoseconds(seconds: float) -> int | float:
    return INF if seconds == INF else nanoseconds(seconds)


# --------------------------------------------------------------------------- declarations


@dataclass(frozen=True)
class Input:
    """``input name: type [= default]``; ``type`` is float, int, bool or str."""

    name: str
    type: str
    default: int | float | bool | str | None = None
    location: Location = _loc()


@dataclass(frozen=True)
class Event:
    """``event name``: true only on the records that set it, false elsewhere."""

    name: str
    location: Location = _loc()


@dataclass(frozen=True)
class Let:
    """``let name = expr``: a derived signal; later uses of ``name`` stand for ``expr``."""

    name: str
    expr: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Property:
    """``property name: formula`` (an outermost unbounded ``always`` already stripped)."""

    name: str
    formula: Expr
    location: Location = _loc()


Declaration = Union[Input, Event, Let, Property]  # noqa: UP007


@dataclass(frozen=True)
class Specification:
    """A checked property file: declarations, and properties with ``let`` names expanded.

    ``signals`` maps every signal the properties read to its type (declared or inferred;
    ``"any"`` when nothing fixes it); ``events`` is the set of event names.
    """

    source: str
    inputs: tuple[Input, ...]
    events: tuple[Event, ...]
    lets: tuple[Let, ...]
    properties: tuple[Property, ...]
    signals: dict[str, str] = field(default_factory=dict, compare=False)
