"""A brute-force oracle for rule sets over small finite domains (int ranges, enums, bools).

It enumerates every point of the declared domains and judges each definition of
``rasm.rules.verify`` literally, with the property language's own ``evaluate``: slow, obvious,
and independent of z3. With plan fields it also groups the points by context (the values of
the other variables) and asks of each context whether some plan obeys the rules.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

from rasm.properties import evaluate
from rasm.rules.model import Rules


def points(rules: Rules) -> list[dict]:
    """Every assignment of the declared (finite) domains."""
    names, domains = [], []
    for name, variable in rules.variables.items():
        names.append(name)
        if variable.type == "int":
            domains.append(range(int(variable.minimum), int(variable.maximum) + 1))
        elif variable.type == "enum":
            domains.append(variable.values)
        elif variable.type == "bool":
            domains.append((False, True))
        else:
            raise ValueError("the oracle needs finite domains")
    return [dict(zip(names, values, strict=True)) for values in itertools.product(*domains)]


def truth(expr, point) -> bool:
    return expr is None or evaluate(expr, point) is True


@dataclass
class Oracle:
    """Every finding of ``rasm verify-rules``, judged point by point."""

    rules: Rules
    plan: frozenset[str] = frozenset()  # besides the variables the file marks ``plan: true``
    dead: set[str] = field(default_factory=set)
    unsatisfiable: set[str] = field(default_factory=set)
    conflicts: set[frozenset[str]] = field(default_factory=set)
    redundant: set[str] = field(default_factory=set)

    def __post_init__(self) -> None:
        pts = points(self.rules)
        rules = self.rules.rules
        self.plan = frozenset(self.plan) | set(self.rules.plan_fields)
        # the points of each context: same values of every variable that is not a plan field
        contexts: dict[tuple, list[int]] = {}
        for index, point in enumerate(pts):
            key = tuple(v for n, v in point.items() if n not in self.plan)
            contexts.setdefault(key, []).append(index)
        self.contexts = list(contexts.values())
        self.when = {r.name: [truth(r.when, p) for p in pts] for r in rules}
        self.require = {r.name: [truth(r.require, p) for p in pts] for r in rules}
        self.holds = {
            n: [not w or q for w, q in zip(self.when[n], self.require[n], strict=True)]
            for n in self.when
        }
        self.n = len(pts)
        for rule in rules:
            name = rule.name
            if not any(self.when[name]):
                self.dead.add(name)
            elif self.plan:
                if self.no_plan_somewhere([name]):
                    self.unsatisfiable.add(name)
            elif not any(w and q for w, q in zip(self.when[name], self.require[name],
                                                strict=True)):
                self.unsatisfiable.add(name)
        candidates = [r.name for r in rules
                      if r.name not in self.dead and r.name not in self.unsatisfiable]
        self.conflicts = self._conflicts(candidates)
        # every other rule may help imply one (an unsatisfiable rule too: it holds wherever its
        # 'when' does not); dead and unsatisfiable rules are not reported as redundant
        everyone = [r.name for r in rules]
        self.redundant = {n for n in candidates if self._redundant(n, everyone)}

    def no_plan_at(self, names, context: list[int]) -> bool:
        """No plan of this context obeys every rule of ``names``."""
        return not any(all(self.holds[n][i] for n in names) for i in context)

    def no_plan_somewhere(self, names) -> bool:
        """Some context admits no plan obeying every rule of ``names``."""
        return any(self.no_plan_at(names, context) for context in self.contexts)

    def conflicting(self, names) -> bool:
        """The definition of a conflicting set (not yet minimal) in force for these rules."""
        if self.plan:
            return self.no_plan_somewhere(names)
        return self.whens_meet(names) and not self.bodies_meet(names)

    def whens_meet(self, names) -> bool:
        return any(all(self.when[n][i] for n in names) for i in range(self.n))

    def bodies_meet(self, names) -> bool:
        return any(all(self.when[n][i] and self.require[n][i] for n in names)
                   for i in range(self.n))

    def _conflicts(self, candidates) -> set[frozenset[str]]:
        found = set()
        for size in range(2, len(candidates) + 1):
            for subset in itertools.combinations(candidates, size):
                if not self.conflicting(subset):
                    continue
                if self.plan:
                    minimal = not any(self.no_plan_somewhere([n for n in subset if n != drop])
                                      for drop in subset)
                else:
                    minimal = all(self.bodies_meet([n for n in subset if n != drop])
                                  for drop in subset)
                if minimal:
                    found.add(frozenset(subset))
        return found

    def implies(self, support, name) -> bool:
        """Every point where all of ``support`` hold is one where ``name`` holds."""
        return all(self.holds[name][i] for i in range(self.n)
                   if all(self.holds[s][i] for s in support))

    def consistent_with_when(self, support, name) -> bool:
        return any(self.when[name][i] and all(self.holds[s][i] for s in support)
                   for i in range(self.n))

    def _redundant(self, name, candidates) -> bool:
        others = [n for n in candidates if n != name]
        for i in range(self.n):
            if self.when[name][i]:
                support = [s for s in others if self.holds[s][i]]
                if self.implies(support, name):
                    return True
        return False
