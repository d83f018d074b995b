"""Static checks of a rule expression against the declared variables.

The expression language is shared with the property files (:mod:`rasm.properties`); rules use its
non-temporal part over four types: ``real`` and ``int`` (numbers; ``int`` mixes into ``real``),
``bool``, and ``enum`` values, which are written as strings (``mode == "dock"``). This module
finds unknown variables, enum values outside a declaration, arithmetic or ordering on enums and
booleans, comparisons across types and temporal operators, each at its line and column.
"""

from __future__ import annotations

import difflib

from rasm.errors import Location, SourceError, SourceErrors, mark
from rasm.properties import ast
from rasm.properties.visitor import Visitor
from rasm.rules.model import Variable

_NUMERIC = ("int", "real")


class _Checker(Visitor[str | None]):
    """A rule expression's pass: each method types its node and notes what is wrong."""

    def __init__(
        self,
        variables: dict[str, Variable],
        source: str,
        text: str,
        strict_enums: bool = True,
        broken: frozenset[str] = frozenset(),
    ) -> None:
        self.variables = variables
        self.broken = broken
        self.strict_enums = strict_enums
        self.source = source
        self.text = text
        self.errors: list[SourceError] = []
        self.reads: set[str] = set()

    def fail(self, message: str, node: ast.Expr, width: int = 1) -> None:
        loc = getattr(node, "location", None) or Location(self.source)
        excerpt = mark(self.text, loc.line, loc.col, width) if loc.file == self.source else None
        self.errors.append(SourceError(message, loc, excerpt))

    # ----------------------------------------------------------------- the nodes
    # each method gives its node's type: int, real, bool, or enum (strings); None after an error

    def literal(self, node: ast.Literal) -> str | None:
        value = node.value
        if isinstance(value, bool):
            return "bool"
        if isinstance(value, int):
            return "int"
        if isinstance(value, float):
            return "real"
        return "enum"

    def unary(self, node: ast.Unary) -> str | None:
        operand = self.visit(node.operand)
        if operand is not None and operand not in _NUMERIC:
            self.fail(f"arithmetic on {_a(operand)}: '-' needs a number", node)
            return None
        return operand

    def not_(self, node: ast.Not) -> str | None:
        operand = self.visit(node.operand)
        if operand is not None and operand != "bool":
            self.fail(f"'not' needs a condition, not {_a(operand)}", node, 3)
        return "bool"

    def time(self, node: ast.Time) -> None:
        self.fail("time reads a trace: a rule judges one plan, so it cannot use it", node)

    def prev(self, node: ast.Prev) -> None:
        self.fail("prev() reads a trace: a rule judges one plan, so it cannot use it", node)

    def past(self, node: ast.Expr) -> None:
        self.fail("temporal operators are not allowed in a rule (it judges one plan)", node)

    future = since = until = aggregate = past

    def name(self, node: ast.Name) -> str | None:
        variable = self.variables.get(node.name)
        if variable is None:
            if node.name in self.broken:  # declared, its declaration already reported
                return None
            self.fail(self.unknown(node.name), node, len(node.name))
            return None
        self.reads.add(node.name)
        return variable.type

    def unknown(self, name: str) -> str:
        owners = [v.name for v in self.variables.values() if name in v.values]
        if owners:
            return (f"unknown variable {name!r}: enum values are written as strings, "
                    f'e.g. {owners[0]} == "{name}"')
        close = difflib.get_close_matches(name, list(self.variables), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        declared = ", ".join(self.variables) or "none"
        return f"unknown variable {name!r}{hint}; declared variables: {declared}"

    def binary(self, node: ast.Binary) -> str | None:
        left, right = self.visit(node.left), self.visit(node.right)
        op = node.op
        if left is None or right is None:
            return "bool" if op in ast.COMPARISONS + ast.BOOLEAN else None
        sides = ((left, node.left), (right, node.right))
        if op in ast.ARITHMETIC:
            for side, operand in sides:
                if side not in _NUMERIC:  # point at the operand that is not a number
                    self.fail(f"arithmetic on {_a(side)}: '{op}' needs numbers", operand)
                    return None
            return "real" if op == "/" or "real" in (left, right) else "int"
        if op in ast.BOOLEAN:
            for side in (left, right):
                if side != "bool":
                    self.fail(f"'{op}' needs conditions on both sides, not {_a(side)}", node,
                              len(op))
            return "bool"
        if op in ("==", "!="):
            if (left in _NUMERIC) != (right in _NUMERIC) or (
                left not in _NUMERIC and left != right
            ):
                self.fail(f"cannot compare {_a(left)} with {_a(right)}", node, len(op))
            elif left == "enum" and self.strict_enums:
                self.enum_values(node)
            return "bool"
        for side, operand in sides:
            if side not in _NUMERIC:
                self.fail(f"'{op}' orders numbers only, not {_a(side)}", operand)
                break
        return "bool"

    def enum_values(self, node: ast.Binary) -> None:
        """``mode == "fly"`` when fly is not a declared value of mode: an error, not false."""
        for var_side, lit_side in ((node.left, node.right), (node.right, node.left)):
            if isinstance(var_side, ast.Name) and isinstance(lit_side, ast.Literal):
                variable = self.variables.get(var_side.name)
                if variable is not None and lit_side.value not in variable.values:
                    self.fail(
                        f"{lit_side.value!r} is not a value of {variable.name} "
                        f"({variable.describe()})",
                        lit_side,
                        len(str(lit_side.value)) + 2,
                    )

    def call(self, node: ast.Call) -> str | None:
        arity = {"abs": 1, "min": 2, "max": 2}.get(node.func)
        if node.func == "prev":
            self.fail("prev() reads a trace: a rule judges one plan, so it cannot use it", node)
            return None
        if arity is None:
            self.fail(f"unknown function {node.func!r} (use abs, min or max)", node,
                      len(node.func))
            return None
        if len(node.args) != arity:
            self.fail(f"{node.func}() takes {arity} argument{'s' if arity > 1 else ''}, "
                      f"not {len(node.args)}", node, len(node.func))
            return None
        types = [self.visit(arg) for arg in node.args]
        if None in types:
            return None
        for t in types:
            if t not in _NUMERIC:
                self.fail(f"{node.func}() needs numbers, not {_a(t)}", node, len(node.func))
                return None
        return "int" if all(t == "int" for t in types) else "real"


def _a(type_: str) -> str:
    return {"int": "a number", "real": "a number", "bool": "a condition",
            "enum": "an enum value"}.get(type_, type_)


def check_rule_expression(
    expr: ast.Expr,
    variables: dict[str, Variable],
    source: str,
    text: str,
    *,
    what: str,
    strict_enums: bool = True,
    broken: frozenset[str] = frozenset(),
) -> set[str]:
    """Check ``expr`` (the rule's ``what``: when/require); return the variables it reads.

    Raises :class:`SourceErrors` with every problem found, each at its line and column.
    ``strict_enums=False`` lets an enum be compared with a string outside its values (a
    property may name a mode the rules do not know: the comparison is then simply false).
    ``broken`` names variables whose declaration was refused (and reported): their uses are
    not reported again as unknown.
    """
    checker = _Checker(variables, source, text, strict_enums, broken)
    result = checker.visit(expr)
    if result is not None and result != "bool" and not checker.errors:
        checker.fail(f"'{what}' must be a condition (true or false), not {_a(result)}", expr)
    if checker.errors:
        raise SourceErrors(checker.errors)
    return checker.reads
