"""``rasm verify-rules --against PROPS.rv``: can a plan the rules admit violate a property?

Only invariants can be judged on a single plan: properties of the form ``always (E)`` (or a
bare ``E``, which a property file also judges at every record) where ``E`` has no temporal
operator, no ``prev``/``time`` and reads only rule variables (``let`` names are expanded
first). For each, z3 looks for a point of the declared domains where every rule holds and ``E``
does not; such a point is the witness. Other properties are listed as skipped, with the reason.
"""

from __future__ import annotations

from pathlib import Path

import z3

from rasm.errors import Location, SourceError, SourceErrors
from rasm.properties import ast
from rasm.properties.parser import parse_declarations
from rasm.properties.visitor import Transformer
from rasm.rules.model import Rules
from rasm.rules.mus import SolverGaveUp, check, new_solver
from rasm.rules.report import Violation
from rasm.rules.smt import Encoder
from rasm.rules.typing import check_rule_expression
from rasm.rules.verify import Undecided, likely_cause


def check_against(rules: Rules, path: str | Path) -> list[Violation]:
    """One :class:`Violation` per property of the file at ``path`` (``witness`` None: safe)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SourceError(f"cannot read property file: {exc}", Location(str(path))) from None
    return check_properties(rules, text, source=str(path))


def check_properties(rules: Rules, text: str, *, source: str = "<properties>") -> list[Violation]:
    """:func:`check_against` on the text of a property file."""
    declarations = parse_declarations(text, source=source)
    lets: dict[str, ast.Expr] = {}
    encoder = Encoder(rules.variables)
    admitted = new_solver()
    admitted.add(*encoder.domain())
    for rule in rules.rules:
        admitted.add(z3.Implies(*encoder.rule(rule)))
    result: list[Violation] = []
    for item in declarations:
        if isinstance(item, ast.Let):
            lets[item.name] = _expand(item.expr, lets)
        elif isinstance(item, ast.Property):
            result.append(_judge(item, lets, rules, encoder, admitted, text, source))
    return result


def _judge(
    prop: ast.Property,
    lets: dict[str, ast.Expr],
    rules: Rules,
    encoder: Encoder,
    admitted: z3.Solver,
    text: str,
    source: str,
) -> Violation:
    formula = prop.formula
    # A property is judged at every record, so `always (E)` and a bare non-temporal `E` are
    # the same invariant (the property loader may already have stripped the outer always).
    if (isinstance(formula, ast.Future) and formula.op == "always"
            and formula.bound.low == 0 and formula.bound.high == ast.INF):
        formula = formula.operand
    body = _expand(formula, lets)
    if _temporal(body):
        return Violation(prop.name, "", None,
                         skipped="not an invariant always (E) with E non-temporal: "
                                 "a plan is one point, not a trace")
    unknown = sorted(_names(body) - set(rules.variables))
    if unknown:
        return Violation(prop.name, "", None,
                         skipped="reads non-rule variables: " + ", ".join(unknown))
    try:
        check_rule_expression(body, rules.variables, source, text, what="property",
                              strict_enums=False)
    except SourceErrors as exc:
        return Violation(prop.name, "", None, skipped="; ".join(e.message for e in exc.errors))
    expression = _show(body)
    violated = z3.Not(encoder.condition(body))
    try:
        holds = not check(admitted, [violated])
    except SolverGaveUp as exc:  # no verdict is better than a guessed one
        exprs = [body, *(e for r in rules.rules for e in (r.when, r.require) if e is not None)]
        raise Undecided(
            f"z3 could not decide property '{prop.name}' against the rules ({exc.reason}): "
            f"{likely_cause(exprs, rules.variables)}",
            prop.location,
        ) from None
    if holds:
        return Violation(prop.name, expression, None)
    model = admitted.model()
    return Violation(prop.name, expression, encoder.decode(model, list(rules.variables)))


def _expand(expr: ast.Expr, lets: dict[str, ast.Expr]) -> ast.Expr:
    """``expr`` with every ``let`` name replaced by its (already expanded) definition."""
    if isinstance(expr, ast.Name):
        return lets.get(expr.name, expr)
    return ast.rebuild(expr, [_expand(child, lets) for child in ast.children(expr)])


def _temporal(expr: ast.Expr) -> bool:
    return any(isinstance(node, ast.TEMPORAL) for node in ast.walk(expr))


def _names(expr: ast.Expr) -> set[str]:
    return {node.name for node in ast.walk(expr) if isinstance(node, ast.Name)}


class _Show(Transformer[str]):
    """An expression as text (fully parenthesised where it matters)."""

    def literal(self, expr: ast.Literal) -> str:
        value = expr.value
        if isinstance(value, bool):
            return "true" if value else "false"
        return f'"{value}"' if isinstance(value, str) else repr(value)

    def name(self, expr: ast.Name) -> str:
        return expr.name

    def not_(self, expr: ast.Not, operand: str) -> str:
        return f"not {_wrap(expr.operand, operand)}"

    def unary(self, expr: ast.Unary, operand: str) -> str:
        return f"-{_wrap(expr.operand, operand)}"

    def binary(self, expr: ast.Binary, left: str, right: str) -> str:
        return f"{_wrap(expr.left, left)} {expr.op} {_wrap(expr.right, right)}"

    def call(self, expr: ast.Call, *args: str) -> str:
        return f"{expr.func}(" + ", ".join(args) + ")"

    def _temporal(self, expr: ast.Expr, *operands: str) -> str:
        return "?"  # (never shown: a property with one is skipped before)

    time = prev = past = future = since = until = aggregate = _temporal


def _show(expr: ast.Expr) -> str:
    return _Show().visit(expr)


def _wrap(expr: ast.Expr, text: str) -> str:
    return f"({text})" if isinstance(expr, ast.Binary) else text
