"""Specialising generated code to values known in advance (the generated monitors' quiet path).

:func:`fold` rewrites a block of generated statements for names whose values are known (the
events a record does not carry: false). Every rule is one of Python's own evaluation rules, so
the folded block computes what the block computed, minus the work whose outcome was known:

* a known name reads as its value; ``not``, ``is``/``is not``, ``==``/``!=`` of two known
  values, ``and``/``or`` with a known left operand and ``x if c else y`` with a known ``c``
  are evaluated;
* ``if`` and ``while`` with a known test keep the branch that runs (a false ``while`` never
  runs its body);
* a value assigned to one of the ``tracked`` locals is known until the next assignment to it
  (reset by branches and loops that may assign it);
* an assignment to one of the ``tracked`` locals that nothing reads afterwards is dropped when
  its value is a plain read or comparison (which has no effect and cannot fail).

Anything else is left as it is. A name meant to be known must never be assigned in the block.
"""

from __future__ import annotations

import ast
import functools
import re

__all__ = ["fold"]

# the sentinel global of generated code (``rasm.spec.codegen.UNSET``): no literal is it
_SENTINEL = "UNSET"
_SCOPES = (ast.Lambda, ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp, ast.NamedExpr)


@functools.lru_cache(maxsize=256)
def fold(source: str, known: tuple[tuple[str, object], ...], tracked: str) -> str:
    """``source`` (statements) with the names in ``known`` (name, value) replaced by their
    values and the consequences folded; ``tracked`` is a regular expression matching the local
    variables whose assigned values may be propagated and whose dead assignments dropped.

    Cached: generated code is a pure function of the specification, compiled again and again.
    """
    folder = _Folder(dict(known), re.compile(tracked))
    body = folder.block(ast.parse(source).body, dict(folder.known))
    body = _drop_dead(body, folder.tracked)
    return ast.unparse(ast.fix_missing_locations(ast.Module(body=body, type_ignores=[]))) + "\n"


class _Folder:
    def __init__(self, known: dict[str, object], tracked: re.Pattern) -> None:
        self.known = {name: ast.Constant(value) for name, value in known.items()}
        self.tracked = tracked

    # ------------------------------------------------------------------ statements
    def block(self, statements: list[ast.stmt], env: dict[str, ast.expr]) -> list[ast.stmt]:
        """Fold ``statements`` in order; ``env`` (updated in place) maps names to known values."""
        out: list[ast.stmt] = []
        for statement in statements:
            out += self.statement(statement, env)
        return out

    def statement(self, node: ast.stmt, env: dict[str, ast.expr]) -> list[ast.stmt]:
        if isinstance(node, ast.If):
            test = self.expr(node.test, env)
            if _is_known(test):
                return self.block(node.body if _value(test) else node.orelse, env)
            body = self.block(node.body, dict(env))
            orelse = self.block(node.orelse, dict(env))
            self.forget(env, _stored(node))
            return [ast.If(test, body or [ast.Pass()], orelse)]
        if isinstance(node, (ast.While, ast.For)):
            # the body may run any number of times: what it assigns is unknown in it and after
            self.forget(env, _stored(node))
            inner = dict(env)
            if isinstance(node, ast.While):
                test = self.expr(node.test, inner)
                if _is_known(test) and not _value(test):
                    return self.block(node.orelse, env)
                head: dict = {"test": test}
            else:
                head = {"target": node.target, "iter": self.expr(node.iter, inner)}
            body = self.block(node.body, inner) or [ast.Pass()]
            orelse = self.block(node.orelse, dict(env))
            return [type(node)(**head, body=body, orelse=orelse)]
        if isinstance(node, ast.Assign):
            value = self.expr(node.value, env)
            self.forget(env, _stored(node))
            if _is_known(value):
                for target in node.targets:
                    if isinstance(target, ast.Name) and self.tracked.fullmatch(target.id):
                        env[target.id] = value
            return [ast.Assign(node.targets, value)]
        if isinstance(node, ast.AugAssign):
            value = self.expr(node.value, env)
            self.forget(env, _stored(node))
            return [ast.AugAssign(node.target, node.op, value)]
        if isinstance(node, (ast.Expr, ast.Return)):
            value = None if node.value is None else self.expr(node.value, env)
            return [type(node)(value)]
        if isinstance(node, (ast.Pass, ast.Continue, ast.Break)):
            return [node]
        raise TypeError(f"cannot fold {ast.dump(node)}")

    def forget(self, env: dict[str, ast.expr], names: set[str]) -> None:
        """``names`` may be assigned: their values are no longer known."""
        for name in names:
            if name in self.known:
                raise ValueError(f"{name} is assigned: its value is not known in advance")
            env.pop(name, None)

    # ------------------------------------------------------------------ expressions
    def expr(self, node: ast.expr, env: dict[str, ast.expr]) -> ast.expr:
        if isinstance(node, ast.Name):
            return env.get(node.id, node) if isinstance(node.ctx, ast.Load) else node
        if isinstance(node, ast.UnaryOp):
            operand = self.expr(node.operand, env)
            if isinstance(node.op, ast.Not) and isinstance(operand, ast.Constant):
                return ast.Constant(not operand.value)
            return ast.UnaryOp(node.op, operand)
        if isinstance(node, ast.BoolOp):
            values = [self.expr(v, env) for v in node.values]
            # ``c and rest`` is ``c`` when c is false, else ``rest``; ``or`` the other way round
            stop = isinstance(node.op, ast.Or)
            while len(values) > 1 and isinstance(values[0], ast.Constant):
                if bool(values[0].value) is stop:
                    return values[0]
                values = values[1:]
            return values[0] if len(values) == 1 else ast.BoolOp(node.op, values)
        if isinstance(node, ast.Compare):
            left = self.expr(node.left, env)
            right = [self.expr(c, env) for c in node.comparators]
            if len(right) == 1 and _is_known(left) and _is_known(right[0]):
                decided = _compare(node.ops[0], left, right[0])
                if decided is not None:
                    return ast.Constant(decided)
            return ast.Compare(left, node.ops, right)
        if isinstance(node, ast.IfExp):
            test = self.expr(node.test, env)
            if isinstance(test, ast.Constant):
                return self.expr(node.body if test.value else node.orelse, env)
            return ast.IfExp(test, self.expr(node.body, env), self.expr(node.orelse, env))
        if isinstance(node, _SCOPES):
            raise TypeError(f"cannot fold {ast.dump(node)}")  # names there are another scope's
        # anything else: fold inside it, keep it
        node = type(node)(**{f: getattr(node, f) for f in node._fields})
        for field, value in ast.iter_fields(node):
            if isinstance(value, ast.expr):
                setattr(node, field, self.expr(value, env))
            elif isinstance(value, list):
                setattr(
                    node,
                    field,
                    [self.expr(v, env) if isinstance(v, ast.expr) else v for v in value],
                )
        return node


def _is_known(node: ast.expr) -> bool:
    """A literal True/False/None, or the sentinel: values ``is`` can compare."""
    if isinstance(node, ast.Constant):
        return node.value is True or node.value is False or node.value is None
    return isinstance(node, ast.Name) and node.id == _SENTINEL and isinstance(node.ctx, ast.Load)


def _value(node: ast.expr) -> object:
    # the sentinel is an object without __bool__ or __len__: true
    return node.value if isinstance(node, ast.Constant) else True


def _compare(op: ast.cmpop, left: ast.expr, right: ast.expr) -> bool | None:
    """``left op right`` for two known values, or None when ``op`` is not decided here.

    True, False, None and the sentinel are each equal to themselves only (the sentinel's class
    keeps object's ``==``): ``==`` is ``is`` among them.
    """
    same = _identity(left) is _identity(right)
    if isinstance(op, (ast.Is, ast.Eq)):
        return same
    if isinstance(op, (ast.IsNot, ast.NotEq)):
        return not same
    return None


def _identity(node: ast.expr) -> object:
    return node.value if isinstance(node, ast.Constant) else _SENTINEL


def _stored(node: ast.stmt) -> set[str]:
    """The names ``node`` may assign (generated code assigns in statements only)."""
    if isinstance(node, ast.Assign):
        targets = node.targets
    elif isinstance(node, (ast.AugAssign, ast.For)):
        targets = [node.target]
    else:
        targets = []
    names = {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
    for inner in (*getattr(node, "body", ()), *getattr(node, "orelse", ())):
        names |= _stored(inner)
    return names


def _drop_dead(body: list[ast.stmt], tracked: re.Pattern) -> list[ast.stmt]:
    """Drop assignments of side-effect-free values to tracked locals nobody reads (counting
    reads, so that dropping one that read another may leave that one unread too)."""
    reads: dict[str, int] = {}
    candidates = []
    for node in ast.walk(ast.Module(body=body, type_ignores=[])):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load):
            reads[node.id] = reads.get(node.id, 0) + 1
        elif (
            isinstance(node, ast.Assign)
            and all(isinstance(t, ast.Name) and tracked.fullmatch(t.id) for t in node.targets)
            and _pure(node.value)
        ):
            candidates.append(node)
    dead: set[int] = set()
    progress = True
    while progress:
        progress = False
        for node in candidates:
            if id(node) not in dead and not any(reads.get(t.id) for t in node.targets):
                dead.add(id(node))
                progress = True
                for n in ast.walk(node.value):
                    if isinstance(n, ast.Name):
                        reads[n.id] -= 1
    return _without(body, dead) if dead else body


def _without(body: list[ast.stmt], dead: set[int]) -> list[ast.stmt]:
    out = []
    for statement in body:
        if id(statement) in dead:
            continue
        if isinstance(statement, (ast.If, ast.While, ast.For)):
            statement.body = _without(statement.body, dead) or [ast.Pass()]
            statement.orelse = _without(statement.orelse, dead)
        out.append(statement)
    return out


def _pure(node: ast.expr) -> bool:
    """Reads and identity tests only: evaluating it has no effect and cannot fail."""
    if isinstance(node, (ast.Constant, ast.Name)):
        return True
    if isinstance(node, ast.Compare):
        return all(isinstance(op, (ast.Is, ast.IsNot)) for op in node.ops) and all(
            _pure(v) for v in (node.left, *node.comparators)
        )
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
        return _pure(node.operand)
    if isinstance(node, ast.BoolOp):
        return all(_pure(v) for v in node.values)
    return False
