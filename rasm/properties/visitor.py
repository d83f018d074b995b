"""Passes over a formula's syntax tree: one method per node class, dispatched by class.

In the manner of lark's ``Transformer``: a pass is a class with one method for each node class
of :data:`rasm.properties.ast.NODES`, named after it in lower case (``Literal`` → ``literal``,
``Binary`` → ``binary``; ``Not`` → ``not_``, as ``not`` is a keyword). Adding an operator
means adding its node class and one method to every pass; adding a semantics means adding
passes, and no existing pass changes. ``tests/properties/test_passes.py`` checks that every
pass has a method for every node class (a pass where several classes mean the same names one
function under each of their names: ``literal = name = time = _leaf``).

Two ways to walk, as lark has:

* :class:`Visitor` — top-down: ``visit(node, *args)`` calls the node's method with
  ``(node, *args)``, and the method visits the sub-expressions it needs, with the arguments it
  chooses (the type a sub-expression must have, the record it is judged at);
* :class:`Transformer` — bottom-up: ``visit(node)`` visits the sub-expressions first, left to
  right, and calls the node's method with ``(node, *their results)``.

A query that picks out one kind of node (the signals a formula reads, the antecedents of its
implications) is no pass: it walks the tree (:func:`rasm.properties.ast.walk`).
"""

from __future__ import annotations

import keyword
from collections.abc import Callable
from typing import Any, ClassVar, Generic, TypeVar

from rasm.properties.ast import NODES, Expr, children

__all__ = ["Transformer", "Visitor", "method_name"]

R = TypeVar("R")


def method_name(node_class: type[Expr]) -> str:
    """The name of the method that handles ``node_class`` in a pass."""
    name = node_class.__name__.lower()
    return name + "_" if keyword.iskeyword(name) else name


class Visitor(Generic[R]):
    """A pass, top-down: ``visit(node, *args)`` is ``self.<node's method>(node, *args)``."""

    # node class -> the function handling it, built once per pass class
    _methods: ClassVar[dict[type, Callable[..., Any]]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._methods = {
            node: getattr(cls, method_name(node))
            for node in NODES
            if callable(getattr(cls, method_name(node), None))
        }

    def visit(self, node: Expr, *args: Any) -> R:
        """The result of this pass for ``node``."""
        try:
            method = self._methods[node.__class__]
        except KeyError:
            raise self._unhandled(node) from None
        return method(self, node, *args)

    def _unhandled(self, node: Expr) -> TypeError:
        return TypeError(f"{type(self).__name__} has no method for {type(node).__name__} nodes")


class Transformer(Visitor[R]):
    """A pass, bottom-up: ``visit(node)`` is ``self.<node's method>(node, *results)``, where
    ``results`` are the pass's results for the node's sub-expressions, left to right."""

    def visit(self, node: Expr) -> R:  # type: ignore[override]
        """The result of this pass for ``node``, its sub-expressions' results first."""
        try:
            method = self._methods[node.__class__]
        except KeyError:
            raise self._unhandled(node) from None
        return method(self, node, *map(self.visit, children(node)))
