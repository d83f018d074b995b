"""Event data from the guards: one value per region the guards' comparisons make (z3).

When the environment gives no domain for a data key a guard reads (``event.data['speed'] > 0.5``,
``event.level == 'high'``), trying every value is impossible and trying a few at random is
unsound. The comparisons in the guards on that event split the key's values into regions in
which every guard has the same truth value; one value per region is enough. Each comparison
that reads event data is an atom; z3 enumerates every combination of the atoms' truth values
that some data satisfies (context variables the comparisons read take their current values) and
gives a model of each.

A comparison z3 cannot express (a function call, a membership test) is left out: its data keys
still get a value from the other atoms, or ``None``.
"""

from __future__ import annotations

import ast
from collections.abc import Mapping
from fractions import Fraction
from typing import Any

import z3

__all__ = ["MAX_REGIONS", "split_data"]

MAX_REGIONS = 256  # combinations tried per event and context; more is reported as a cap


def _data_key(node: ast.AST) -> str | None:
    """The key of ``event.data['k']``, ``event.data.get('k')`` or ``event.k``, else None."""
    if isinstance(node, ast.Subscript):
        value, key = node.value, node.slice
    elif (
        isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
        and node.func.attr == "get" and node.args
    ):
        value, key = node.func.value, node.args[0]
    elif (
        isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
        and node.value.id == "event" and node.attr not in ("data", "name")
    ):
        return node.attr
    else:
        return None
    if (
        isinstance(value, ast.Attribute) and value.attr == "data"
        and isinstance(value.value, ast.Name) and value.value.id == "event"
        and isinstance(key, ast.Constant) and isinstance(key.value, str)
    ):
        return key.value
    return None


class _Untranslatable(Exception):
    pass


class _Translator:
    """Guards' comparisons over event data as z3 terms."""

    def __init__(self, keys: set[str], context: Mapping[str, Any], fixed: Mapping[str, Any]):
        self.keys = keys
        self.context = context
        self.fixed = fixed
        self.sorts: dict[str, str] = {}  # key -> "int" | "real" | "str" | "bool"
        self.vars: dict[str, Any] = {}
        self.none_flags: dict[str, Any] = {}

    # -- types, from the constants each key is compared with
    def infer(self, tree: ast.AST) -> None:
        for node in ast.walk(tree):
            if isinstance(node, ast.Compare):
                operands = [node.left, *node.comparators]
                keys = [k for k in map(_data_key, operands) if k in self.keys]
                kinds = {self._kind(op) for op in operands if _data_key(op) is None}
                for key in keys:
                    for kind in kinds - {None}:
                        self.sorts[key] = _join(self.sorts.get(key), kind)
            elif isinstance(node, ast.BoolOp | ast.UnaryOp):
                operands = node.values if isinstance(node, ast.BoolOp) else [node.operand]
                for op in operands:
                    key = _data_key(op)
                    if key in self.keys and not isinstance(op, ast.Compare):
                        self.sorts.setdefault(key, "bool")
            elif isinstance(node, ast.BinOp):
                for op in (node.left, node.right):
                    key = _data_key(op)
                    if key in self.keys:
                        kind = "real" if isinstance(node.op, ast.Div) else "int"
                        self.sorts[key] = _join(self.sorts.get(key), kind)

    def _kind(self, node: ast.AST) -> str | None:
        value = self._constant(node)
        if value is _NO:
            return None
        if isinstance(value, bool):
            return "bool"
        if isinstance(value, int):
            return "int"
        if isinstance(value, float):
            return "real"
        if isinstance(value, str):
            return "str"
        return None

    def _constant(self, node: ast.AST) -> Any:
        if isinstance(node, ast.Constant):
            return node.value
        if isinstance(node, ast.Name) and node.id in self.context:
            return self.context[node.id]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            inner = self._constant(node.operand)
            if isinstance(inner, int | float) and not isinstance(inner, bool):
                return -inner
        return _NO

    def var(self, key: str) -> Any:
        if key not in self.vars:
            sort = self.sorts.get(key, "real")
            make = {"int": z3.Int, "real": z3.Real, "str": z3.String, "bool": z3.Bool}[sort]
            self.vars[key] = make(f"data_{key}")
            self.sorts[key] = sort
        return self.vars[key]

    # -- terms
    def term(self, node: ast.AST) -> Any:
        key = _data_key(node)
        if key is not None:
            if key in self.fixed:
                return _literal(self.fixed[key])
            if key in self.keys:
                return self.var(key)
            raise _Untranslatable
        value = self._constant(node)
        if value is not _NO:
            return _literal(value)
        arithmetic = ast.Add | ast.Sub | ast.Mult | ast.Div
        if isinstance(node, ast.BinOp) and isinstance(node.op, arithmetic):
            left, right = self.term(node.left), self.term(node.right)
            if isinstance(node.op, ast.Add):
                return left + right
            if isinstance(node.op, ast.Sub):
                return left - right
            if isinstance(node.op, ast.Mult):
                return left * right
            return z3.ToReal(left) / right if z3.is_int(left) and z3.is_int(right) else left / right
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            return -self.term(node.operand)
        raise _Untranslatable

    def atom(self, node: ast.AST) -> Any:
        """A comparison (or a bare data key in a boolean place) as a z3 boolean."""
        if isinstance(node, ast.Compare):
            terms = [node.left, *node.comparators]
            parts = []
            for op, left, right in zip(node.ops, terms, terms[1:], strict=False):
                if isinstance(op, ast.Is | ast.IsNot) and _is_none(right):
                    key = _data_key(left)
                    if key not in self.keys:
                        raise _Untranslatable
                    flag = self.none_flags.setdefault(key, z3.Bool(f"none_{key}"))
                    parts.append(flag if isinstance(op, ast.Is) else z3.Not(flag))
                    continue
                a, b = self.term(left), self.term(right)
                a, b = _coerce(a, b)
                compare = {
                    ast.Eq: lambda x, y: x == y, ast.NotEq: lambda x, y: x != y,
                    ast.Lt: lambda x, y: x < y, ast.LtE: lambda x, y: x <= y,
                    ast.Gt: lambda x, y: x > y, ast.GtE: lambda x, y: x >= y,
                }.get(type(op))
                if compare is None:
                    raise _Untranslatable
                parts.append(compare(a, b))
            return z3.And(*parts) if len(parts) > 1 else parts[0]
        key = _data_key(node)
        if key in self.keys and self.sorts.get(key) == "bool":
            return self.var(key)
        raise _Untranslatable


_NO = object()


def _is_none(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and node.value is None


def _join(old: str | None, new: str) -> str:
    if old is None or old == new:
        return new
    if {old, new} == {"int", "real"}:
        return "real"
    return old


def _literal(value: Any) -> Any:
    if isinstance(value, bool):
        return z3.BoolVal(value)
    if isinstance(value, int):
        return z3.IntVal(value)
    if isinstance(value, float):
        return z3.RealVal(Fraction(value))
    if isinstance(value, str):
        return z3.StringVal(value)
    raise _Untranslatable


def _coerce(a: Any, b: Any) -> tuple[Any, Any]:
    if z3.is_int(a) and z3.is_real(b):
        return z3.ToReal(a), b
    if z3.is_real(a) and z3.is_int(b):
        return a, z3.ToReal(b)
    if a.sort() != b.sort():
        raise _Untranslatable
    return a, b


def _atoms(tree: ast.AST, translator: _Translator) -> list[Any]:
    atoms = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare) or (
            _data_key(node) is not None and translator.sorts.get(_data_key(node)) == "bool"
        ):
            try:
                atoms.append(translator.atom(node))
            except (_Untranslatable, z3.Z3Exception):
                continue
    return atoms


def _value(model: Any, var: Any, sort: str) -> Any:
    found = model.eval(var, model_completion=True)
    if sort == "bool":
        return z3.is_true(found)
    if sort == "int":
        return found.as_long()
    if sort == "str":
        return found.as_string()
    fraction = Fraction(found.numerator_as_long(), found.denominator_as_long())
    return int(fraction) if fraction.denominator == 1 else float(fraction)


def split_data(
    guards: list[str], keys: set[str], context: Mapping[str, Any], fixed: Mapping[str, Any]
) -> tuple[list[dict[str, Any]], bool]:
    """One data dict per region of ``keys`` that the comparisons of ``guards`` make, the keys
    of ``fixed`` given; ``context`` gives the variables the comparisons read. Returns the dicts
    and whether :data:`MAX_REGIONS` cut the enumeration short."""
    if not keys:
        return [dict(fixed)], False
    trees = []
    for guard in guards:
        try:
            trees.append(ast.parse(guard.strip(), mode="eval"))
        except SyntaxError:
            continue
    translator = _Translator(keys, context, fixed)
    for tree in trees:
        translator.infer(tree)
    atoms = [atom for tree in trees for atom in _atoms(tree, translator)]
    unique: list[Any] = []
    for atom in atoms:
        if not any(atom.eq(seen) for seen in unique):
            unique.append(atom)
    solver = z3.Solver()
    solver.set("timeout", 2000)
    regions: list[dict[str, Any]] = []
    capped = False
    while True:
        if solver.check() != z3.sat:
            break
        model = solver.model()
        data = dict(fixed)
        for key in sorted(keys):
            flag = translator.none_flags.get(key)
            if flag is not None and z3.is_true(model.eval(flag, model_completion=True)):
                data[key] = None
            elif key in translator.vars:
                data[key] = _value(model, translator.vars[key], translator.sorts[key])
            else:
                data[key] = None
        regions.append(data)
        if len(regions) >= MAX_REGIONS:
            capped = True
            break
        if not unique and not translator.none_flags:
            break
        # the same truth values of the atoms again would be the same region
        signs = [
            atom if z3.is_true(model.eval(atom, model_completion=True)) else z3.Not(atom)
            for atom in [*unique, *translator.none_flags.values()]
        ]
        solver.add(z3.Not(z3.And(*signs)))
    return regions, capped
