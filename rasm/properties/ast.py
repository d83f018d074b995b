"""The syntax tree of the property language: plain, frozen data.

Every node carries a ``location`` (keyword-only, ignored by ``==``) pointing into the user's
file, so that type errors and explanations name the place. The expression nodes (``Literal`` to
``Call``) are the sub-language shared with the legitimacy rules; ``Time``, ``Prev``
and the temporal nodes exist only in property files.

Operators are plain strings:

* ``Unary.op``: ``"-"`` (numeric negation);
* ``Binary.op``: ``"+" "-" "*" "/"`` (arithmetic), ``"==" "!=" "<" "<=" ">" ">="``
  (comparisons), ``"and" "or" "->"`` (boolean; ``->`` is implication);
* ``Call.func``: ``"abs"`` (one argument), ``"min"`` / ``"max"`` (two arguments); any other
  name parses and is rejected by the type checker as an unknown function.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Union

from rasm.errors import Location
from rasm.properties.times import format_nanoseconds, nanoseconds

__all__ = [
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
]

UNKNOWN = Location("<text>")
INF = math.inf

ARITHMETIC = ("+", "-", "*", "/")
COMPARISONS = ("==", "!=", "<", "<=", ">", ">=")
BOOLEAN = ("and", "or", "->")


def _loc():
    return field(default=UNKNOWN, compare=False, kw_only=True, repr=False)


# --------------------------------------------------------------------------- expressions


@dataclass(frozen=True)
class Literal:
    """A constant: ``int``, ``float``, ``bool`` (``true``/``false``) or ``str``."""

    value: int | float | bool | str
    location: Location = _loc()


@dataclass(frozen=True)
class Name:
    """A signal (or, in a property file, a ``let``-defined name) read at the current record."""

    name: str
    location: Location = _loc()


@dataclass(frozen=True)
class Unary:
    """Numeric negation ``-operand`` (``op`` is always ``"-"``)."""

    op: str
    operand: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Not:
    """Boolean negation ``not operand``."""

    operand: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Binary:
    """``left op right`` for arithmetic, comparison and ``and``/``or``/``->`` operators."""

    op: str
    left: Expr
    right: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Call:
    """A function call ``func(args…)``: ``abs(e)``, ``min(a, b)``, ``max(a, b)``."""

    func: str
    args: tuple[Expr, ...]
    location: Location = _loc()


# --------------------------------------------------------------------------- property-only


@dataclass(frozen=True)
class Time:
    """``time``: the timestamp of the current record, in seconds."""

    location: Location = _loc()


@dataclass(frozen=True)
class Prev:
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
class Past:
    """``once[bound] operand`` or ``historically[bound] operand`` (``op`` names which)."""

    op: str
    bound: Bound
    operand: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Future:
    """``eventually[bound] operand`` or ``always[bound] operand`` (``op`` names which).

    An unbounded ``always`` (``bound.high`` infinite) is only valid as the outermost operator
    of a property, where it means "at every record"; the loader strips it.
    """

    op: str
    bound: Bound
    operand: Expr
    location: Location = _loc()


@dataclass(frozen=True)
class Since:
    """``left since[bound] right``: right held in the window and left ever since."""

    left: Expr
    right: Expr
    bound: Bound
    location: Location = _loc()


@dataclass(frozen=True)
class Until:
    """``left until[bound] right``: right will hold in the window and left until then."""

    left: Expr
    right: Expr
    bound: Bound
    location: Location = _loc()


@dataclass(frozen=True)
class Aggregate:
    """``op[bound](operand)`` with ``op`` in count, sum, avg, min, max, over the past window."""

    op: str
    bound: Bound
    operand: Expr
    location: Location = _loc()


Expr = Union[  # noqa: UP007 - a runtime alias, used with isinstance by callers
    Literal, Name, Unary, Not, Binary, Call, Time, Prev, Past, Future, Since, Until, Aggregate
]


def children(node: Expr) -> tuple[Expr, ...]:
    """The direct sub-expressions of ``node``, left to right."""
    if isinstance(node, (Unary, Not, Prev, Past, Future, Aggregate)):
        return (node.operand,)
    if isinstance(node, (Binary, Since, Until)):
        return (node.left, node.right)
    if isinstance(node, Call):
        return node.args
    return ()


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
