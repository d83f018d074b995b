"""Guards of property statecharts decided from a meta-event's name and one value.

Most guards of a property statechart compare one piece of the meta-event with constants:
``event.state == 'idle'``, ``event.state in STAGES``, ``event.event.name == 'accepted'``. For
those, whether the guard holds follows from the meta-event's *discriminant* (the state's name for
``state entered``/``state exited``, the event's name for ``event consumed``/``event sent``/``delayed
event sent``/``transition processed``, :data:`NO_EVENT` for an eventless transition, which guards
test with ``event.event is None``) without building the meta-event or evaluating the guard.
:func:`guard_predicate`
recognises such guards and returns an exact predicate over the discriminant; anything else (other
attributes, calls, comparisons with mutable or non-string values) gets ``None``: only evaluating
the guard can tell.

A predicate is exact because it applies the same operators to the same values: a ``str``
discriminant and constants that are strings, or tuples and frozensets of strings, written in the
guard or read from the property's context (whose value is then *watched*: a predicate is valid only
while each watched context name is bound to the very object it was built with).
"""

from __future__ import annotations

import ast
import operator
from collections.abc import Callable
from typing import Any

__all__ = ["DISCRIMINANT", "MISSING", "NO_EVENT", "Predicate", "guard_predicate"]

#: meta-event name -> the guard expression that reads its discriminant (see module docstring)
DISCRIMINANT: dict[str, str] = {
    "state entered": "event.state",
    "state exited": "event.state",
    "event consumed": "event.event.name",
    "event sent": "event.event.name",
    "delayed event sent": "event.event.name",
    "transition processed": "event.event.name",
}

#: watched context name that must stay unbound (``event`` would shadow the meta-event)
MISSING: Any = object()


class _NoEvent:
    def __repr__(self) -> str:
        return "NO_EVENT"


#: the discriminant of a ``transition processed`` meta-event for an eventless transition
#: (``event.event`` is None: ``event.event is None`` holds, reading ``event.event.name`` raises)
NO_EVENT: Any = _NoEvent()

#: a predicate's answer for a value: True, False, or None when evaluating the guard would raise
Predicate = Callable[[Any], "bool | None"]
_OPS: dict[type, Callable[[Any, Any], bool]] = {
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
    ast.In: lambda a, b: a in b,
    ast.NotIn: lambda a, b: a not in b,
}
_VALUE = object()  # marks the discriminant in a compiled tree


class _Unknown(Exception):
    """The guard is not of a form decided by the discriminant alone."""


class _Raises(Exception):
    """Evaluating the guard for this value would raise (``event.event.name`` of no event)."""


def _is_strings(value: Any) -> bool:
    return type(value) is str or (
        type(value) in (tuple, frozenset) and all(type(v) is str for v in value)
    )


def _reads(node: ast.AST, path: tuple[str, ...]) -> bool:
    """Whether ``node`` is the attribute chain ``event.<path...>``."""
    for attribute in reversed(path):
        if not isinstance(node, ast.Attribute) or node.attr != attribute:
            return False
        node = node.value
    return isinstance(node, ast.Name) and node.id == "event"


def _operand(node: ast.AST, path: tuple[str, ...], context: dict, watch: dict) -> Any:
    if _reads(node, path):
        return _VALUE
    if isinstance(node, ast.Constant) and type(node.value) is str:
        return node.value
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        items = [_operand(e, path, context, watch) for e in node.elts]
        if any(i is _VALUE or type(i) is not str for i in items):
            raise _Unknown
        # a literal list or set is built afresh at each evaluation: same members, same result
        return tuple(items) if isinstance(node, (ast.Tuple, ast.List)) else frozenset(items)
    if isinstance(node, ast.Name) and node.id in context:
        value = context[node.id]
        if not _is_strings(value):
            raise _Unknown
        watch[node.id] = value
        return value
    raise _Unknown


def _compile(node: ast.AST, path: tuple[str, ...], context: dict, watch: dict) -> Any:
    """A tree of (op, operands) over constants and _VALUE; raises _Unknown."""
    if (
        isinstance(node, ast.Compare)
        and len(node.ops) == 1
        and isinstance(node.ops[0], (ast.Is, ast.IsNot))
        and path[-1:] == ("name",)
        and _reads(node.left, path[:-1])
        and isinstance(node.comparators[0], ast.Constant)
        and node.comparators[0].value is None
    ):  # `event.event is None`: whether there is an event at all
        return (_is_no_event, [isinstance(node.ops[0], ast.Is)])
    if isinstance(node, ast.BoolOp):
        parts = [_compile(v, path, context, watch) for v in node.values]
        return (all if isinstance(node.op, ast.And) else any, parts)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
        return (operator.not_, [_compile(node.operand, path, context, watch)])
    if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _OPS:
        left = _operand(node.left, path, context, watch)
        right = _operand(node.comparators[0], path, context, watch)
        if (left is _VALUE) == (right is _VALUE):
            raise _Unknown  # constants only, or the value against itself: not worth a rule
        if right is _VALUE and type(node.ops[0]) in (ast.In, ast.NotIn):
            raise _Unknown  # `'x' in event.state`: substring of the value, left to eval
        return (_OPS[type(node.ops[0])], [left, right])
    raise _Unknown


def _is_no_event(value: Any, when_none: bool) -> bool:
    return (value is NO_EVENT) is when_none


def _evaluate(tree: Any, value: Any) -> bool:
    # `and`/`or` stop at the first operand that decides, as Python's do: a later operand that
    # would raise is then never reached, in the guard as here
    func, parts = tree
    if func is all or func is any:
        return func(_evaluate(p, value) for p in parts)
    if func is operator.not_:
        return not _evaluate(parts[0], value)
    if func is _is_no_event:
        return _is_no_event(value, parts[0])
    if value is NO_EVENT:
        raise _Raises  # the guard reads the name of no event
    left, right = (value if p is _VALUE else p for p in parts)
    return bool(func(left, right))


def _predicate(compiled: Any) -> Predicate:
    def decide(value: Any) -> bool | None:
        try:
            return _evaluate(compiled, value)
        except _Raises:
            return None

    return decide


def guard_predicate(guard: str, meta_name: str, context: dict) -> tuple[Predicate, dict] | None:
    """An exact predicate over the discriminant of ``meta_name`` for ``guard``, and the context
    names it read (name -> the object it was built with, or :data:`MISSING`); None when the guard
    is not decided by the discriminant alone."""
    expression = DISCRIMINANT.get(meta_name)
    if expression is None:
        return None
    try:
        tree = ast.parse(guard.strip(), mode="eval").body
    except SyntaxError:
        return None  # the real evaluation reports it
    path = tuple(expression.split(".")[1:])
    watch: dict[str, Any] = {}
    try:
        compiled = _compile(tree, path, context, watch)
    except _Unknown:
        return None
    # guards look names up in the context first: one named `event` would hide the meta-event
    watch["event"] = context.get("event", MISSING)
    if watch["event"] is not MISSING:
        return None
    return _predicate(compiled), watch
