"""The type checker: every node gets one of float, int, bool, str.

Signals get their types from declarations (the caller's ``declared`` mapping) or, failing that,
from how they are used: a name under ``and``/``not``/a temporal operator is a bool, one under
``+``/``<`` is a number (reported as ``float``), one compared with a string is a str. Using one
name two ways is an error reported at the second use, naming the first.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from rasm.errors import Location, SourceError
from rasm.properties.ast import (
    ARITHMETIC,
    Aggregate,
    Binary,
    Call,
    Expr,
    Future,
    Literal,
    Name,
    Not,
    Past,
    Prev,
    Since,
    Time,
    Unary,
    Until,
)
from rasm.properties.visitor import Visitor

__all__ = ["Typing", "infer_types", "TypeScope"]

TYPES = ("float", "int", "bool", "str")
NUMBER = ("float", "int")
_WORD = {"float": "a number", "int": "a number", "bool": "a boolean", "str": "a string"}
FUNCTIONS = {"abs": 1, "min": 2, "max": 2}


@dataclass(frozen=True)
class Typing:
    """The result of :func:`infer_types`: the expression's type and every signal's type.

    A signal whose use fixes no type (``x == y`` with neither declared) has type ``"any"``.
    """

    type: str
    signals: dict[str, str] = field(default_factory=dict)


class TypeScope(Visitor[str]):
    """Signal types shared by several expressions (all properties of one file); a pass whose
    methods type a node given the type it must have."""

    def __init__(self, declared: Mapping[str, str]) -> None:
        for name, kind in declared.items():
            if kind not in TYPES:
                raise ValueError(f"unknown type {kind!r} for {name!r}")
        self.types: dict[str, str] = dict(declared)
        self.first_use: dict[str, Location] = {}
        self.seen: dict[str, Location] = {}

    # ----------------------------------------------------------------- public
    def check(self, expr: Expr, expected: str | None = None) -> str:
        """Type ``expr`` (twice: uses further right may fix names used on the left)."""
        self.visit(expr, expected)
        return self.visit(expr, expected)

    def signals(self) -> dict[str, str]:
        return {name: self.types.get(name, "any") for name in self.seen}

    # ----------------------------------------------------------------- core
    def _fix(self, node: Name, kind: str) -> str:
        known = self.types.get(node.name)
        if known is None:
            self.types[node.name] = "float" if kind in NUMBER else kind
            self.first_use[node.name] = node.location
            return self.types[node.name]
        if _compatible(known, kind):
            return known
        where = self.first_use.get(node.name)
        origin = f"its use at {where}" if where is not None else "its declaration"
        raise SourceError(
            f"signal {node.name!r} is used as {_WORD[kind]} here but is {_WORD[known]} "
            f"({origin})",
            node.location,
        )

    def _expect(self, node: Expr, kind: str, expected: str | None, what: str) -> str:
        if expected is not None and not _compatible(kind, expected):
            raise SourceError(
                f"{what} is {_WORD[kind]}, but {_WORD[expected]} is needed here", node.location
            )
        return kind

    # ----------------------------------------------------------------- the nodes
    # each method types its node given the type it must have (``expected``, None: any)

    def name(self, node: Name, expected: str | None) -> str:
        self.seen.setdefault(node.name, node.location)
        if expected is not None:
            return self._fix(node, expected)
        return self.types.get(node.name, "any")

    def literal(self, node: Literal, expected: str | None) -> str:
        kind = _literal_type(node.value)
        return self._expect(node, kind, expected, f"{node.value!r}")

    def time(self, node: Time, expected: str | None) -> str:
        return self._expect(node, "float", expected, "time")

    def prev(self, node: Prev, expected: str | None) -> str:
        return self.visit(node.operand, expected)

    def not_(self, node: Not, expected: str | None) -> str:
        self.visit(node.operand, "bool")
        return self._expect(node, "bool", expected, "'not …'")

    def unary(self, node: Unary, expected: str | None) -> str:
        kind = self._number(node.operand, "'-'")
        return self._expect(node, kind, expected, "'-…'")

    def past(self, node: Past | Future, expected: str | None) -> str:
        self.visit(node.operand, "bool")
        return self._expect(node, "bool", expected, f"'{node.op} …'")

    future = past

    def since(self, node: Since | Until, expected: str | None) -> str:
        self.visit(node.left, "bool")
        self.visit(node.right, "bool")
        return self._expect(node, "bool", expected, "'since'/'until'")

    until = since

    def aggregate(self, node: Aggregate, expected: str | None) -> str:
        if node.op == "count":
            self.visit(node.operand, "bool")
            kind = "int"
        else:
            kind = self._number(node.operand, node.op)
            if node.op == "avg":
                kind = "float"
        return self._expect(node, kind, expected, f"'{node.op}[…](…)'")

    def _number(self, node: Expr, what: str) -> str:
        if isinstance(node, Name):
            self.seen.setdefault(node.name, node.location)
            return self._fix(node, "float")
        kind = self.visit(node, None)
        if kind == "any":
            return "float"
        if kind not in NUMBER:
            raise SourceError(f"{what} needs a number, not {_WORD[kind]}", node.location)
        return kind

    def binary(self, node: Binary, expected: str | None) -> str:
        op = node.op
        if op in ("and", "or", "->"):
            self.visit(node.left, "bool")
            self.visit(node.right, "bool")
            return self._expect(node, "bool", expected, f"'{op}'")
        if op in ARITHMETIC:
            left = self._number(node.left, f"arithmetic '{op}'")
            right = self._number(node.right, f"arithmetic '{op}'")
            kind = "int" if left == right == "int" and op != "/" else "float"
            return self._expect(node, kind, expected, f"'{op}'")
        # comparisons
        if op in ("<", "<=", ">", ">="):
            self._number(node.left, f"comparison '{op}'")
            self._number(node.right, f"comparison '{op}'")
            return self._expect(node, "bool", expected, f"'{op}'")
        left = self.visit(node.left, None)
        right = self.visit(node.right, None)
        if left == "any" and right != "any":
            left = self.visit(node.left, right)
        elif right == "any" and left != "any":
            right = self.visit(node.right, left)
        if left != "any" and right != "any" and not _compatible(left, right):
            raise SourceError(
                f"cannot compare {_WORD[left]} with {_WORD[right]} ('{op}')", node.location
            )
        return self._expect(node, "bool", expected, f"'{op}'")

    def call(self, node: Call, expected: str | None) -> str:
        arity = FUNCTIONS.get(node.func)
        if arity is None:
            known = ", ".join(sorted(FUNCTIONS))
            raise SourceError(
                f"unknown function {node.func!r}; the functions are {known}", node.location
            )
        if len(node.args) != arity:
            raise SourceError(
                f"{node.func} takes {arity} argument{'s' if arity > 1 else ''}, "
                f"not {len(node.args)}",
                node.location,
            )
        kinds = [self._number(arg, f"{node.func}()") for arg in node.args]
        kind = "int" if all(k == "int" for k in kinds) else "float"
        return self._expect(node, kind, expected, f"{node.func}(…)")


def _literal_type(value: object) -> str:
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "int"
    if isinstance(value, float):
        return "float"
    return "str"


def _compatible(a: str, b: str) -> bool:
    return a == b or (a in NUMBER and b in NUMBER) or "any" in (a, b)


def infer_types(expr: Expr, declared: Mapping[str, str], *, expected: str | None = None) -> Typing:
    """Type-check ``expr`` given the ``declared`` signal types (float | int | bool | str).

    Returns the expression's type and the type of every signal it reads. Raises
    :class:`~rasm.errors.SourceError` at the offending node for a signal used both as a number
    and as a boolean, an unknown function, a string compared with a number, arithmetic on
    strings or booleans. ``expected`` (e.g. ``"bool"``) also checks the expression's own type.
    """
    scope = TypeScope(declared)
    kind = scope.check(expr, expected)
    return Typing(kind, scope.signals())
