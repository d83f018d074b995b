"""Cutting the conflict search into small independent pieces.

Two cuts, both exact (they change how fast conflicts are found, never which):

* **components**: rules that share no variable can neither conflict nor imply each other, so
  each connected group is searched alone;
* **guard contexts**: many rules are guarded by discrete conditions (``mode == "dock"``,
  ``armed``) that no ``require`` reads. Let G be such enum/bool variables whose every use in a
  ``when`` is a top-level conjunct reading only G. Each ``when`` is then ``D(G) and N(rest)``.
  For a context c (values for G), a set M of rules whose ``D`` hold at c conflicts iff its
  ``N and require`` are jointly unsatisfiable over the other variables, minimally, with its
  ``N`` jointly satisfiable: G no longer matters, since c satisfies every ``D`` of M and G
  appears nowhere else. Every conflict lives in the context of its witness, so searching each
  distinct set of active rules, split again into components over the remaining variables,
  finds all conflicts; within a context the rules of other modes are simply absent, so the
  search never enumerates their combinations.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

from rasm.properties import ast, evaluate
from rasm.rules.model import Rule, Variable

#: At most this many guard contexts are enumerated; beyond, the search runs uncut.
MAX_CONTEXTS = 1024


def components(indices: Sequence[int], reads: Callable[[int], Iterable[str]]) -> list[list[int]]:
    """``indices`` grouped by shared variables (connected components), each in input order."""
    parent = {i: i for i in indices}

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    owner: dict[str, int] = {}
    for index in indices:
        for name in reads(index):
            if name in owner:
                parent[find(index)] = find(owner[name])
            else:
                owner[name] = index
    groups: dict[int, list[int]] = {}
    for index in indices:
        groups.setdefault(find(index), []).append(index)
    return list(groups.values())


def conjuncts(expr: ast.Expr | None) -> list[ast.Expr]:
    """The top-level ``and`` operands of ``expr`` (none for a missing ``when``)."""
    if expr is None:
        return []
    if isinstance(expr, ast.Binary) and expr.op == "and":
        return conjuncts(expr.left) + conjuncts(expr.right)
    return [expr]


def names(expr: ast.Expr) -> set[str]:
    """The variables ``expr`` reads."""
    found = {expr.name} if isinstance(expr, ast.Name) else set()
    for child in ast.children(expr):
        found |= names(child)
    return found


@dataclass(frozen=True)
class GuardSplit:
    """The guard variables, each rule's residual ``when`` conjuncts, and the active sets."""

    guards: tuple[str, ...]
    rest: dict[int, list[ast.Expr]]
    active_sets: list[list[int]]


def guard_split(
    rules: Sequence[Rule], variables: dict[str, Variable], candidates: Sequence[int]
) -> GuardSplit | None:
    """Split ``candidates`` (indices into ``rules``) by their discrete guards, if worthwhile."""
    in_requires = set().union(*(names(rules[i].require) for i in candidates))
    guards = {n for n, v in variables.items() if v.type in ("enum", "bool")} - in_requires
    parts = {i: [(c, names(c)) for c in conjuncts(rules[i].when)] for i in candidates}
    changed = True
    while changed:  # a conjunct mixing a guard with another variable disqualifies the guard
        changed = False
        for conj_list in parts.values():
            for _, read in conj_list:
                if read & guards and read - guards:
                    guards -= read
                    changed = True
    used = sorted({n for conj_list in parts.values() for _, r in conj_list for n in r} & guards)
    if not used:
        return None
    domains = [_values(variables[n]) for n in used]
    if math.prod(len(d) for d in domains) > MAX_CONTEXTS:
        return None
    guard_of: dict[int, list[ast.Expr]] = {i: [] for i in parts}
    rest: dict[int, list[ast.Expr]] = {i: [] for i in parts}
    for i, conj_list in parts.items():
        for conj, read in conj_list:
            (guard_of if read and read <= guards else rest)[i].append(conj)
    seen: set[tuple[int, ...]] = set()
    active_sets: list[list[int]] = []
    for values in itertools.product(*domains):
        context = dict(zip(used, values, strict=True))
        active = tuple(i for i in candidates
                       if all(evaluate(c, context) is True for c in guard_of[i]))
        if len(active) >= 2 and active not in seen:
            seen.add(active)
            active_sets.append(list(active))
    # a context whose active set is inside another's adds nothing: drop the contained ones
    active_sets.sort(key=len, reverse=True)
    kept: list[list[int]] = []
    for active in active_sets:
        as_set = set(active)
        if not any(as_set <= set(other) for other in kept):
            kept.append(active)
    return GuardSplit(tuple(used), rest, kept)


def _values(variable: Variable) -> tuple:
    return (False, True) if variable.type == "bool" else variable.values
