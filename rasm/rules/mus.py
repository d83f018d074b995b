"""Minimal conflicting sets with z3: a MARCO-style enumeration with unsat-core shrinking.

Two notions of conflict share the enumeration: without plan fields (:class:`ConflictFinder`,
below) and with them (:class:`NoPlanFinder`: a set conflicts when some context admits no plan
that obeys all its rules, SPEC section 7).

The question: which *minimal* sets of rules have ``when`` conditions that can hold
together while their ``require`` conditions then cannot all hold? Writing ``B_i = W_i and R_i``,
a set S conflicts iff the ``W_i`` of S are jointly satisfiable and the ``B_i`` of S are not. Any
proper subset of such an S keeps satisfiable ``W``s, so S is a minimal conflict exactly when it is
a minimal unsatisfiable subset (MUS) of the ``B``s whose ``W``s are satisfiable together.

MARCO (Liffiton et al., 2016) explores the power set through a *map* solver whose models are the
seeds not yet explained. Here the map also carries the domain variables with ``s_i -> W_i``, so
it only ever proposes sets of rules that can apply together: MUSes of rules that never apply
together (rules for different modes, say), of which there can be quadratically many, are never
visited. A satisfiable seed is grown to a maximal satisfiable set and its subsets are blocked; an
unsatisfiable one is shrunk (deletion, refined by unsat cores) to a MUS whose supersets are
blocked. Every iteration blocks its seed, so the loop ends, and it ends with every conflict found.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import z3

from rasm.errors import RulesError

#: Longest a single z3 check may take. Linear rules take milliseconds; only nonlinear integer
#: arithmetic (undecidable in general) can reach it, and then the answer is an error, not a guess.
SOLVER_TIMEOUT_MS = 30_000


class SolverGaveUp(RulesError):
    """z3 answered ``unknown`` (its ``reason``: a time limit, an incomplete theory). The caller
    names the rules it was deciding; see :func:`rasm.rules.verify.gave_up`."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"z3 could not decide the rules ({reason})")
        self.reason = reason


def new_solver() -> z3.Solver:
    """A z3 solver with rasm's time limit per check."""
    solver = z3.Solver()
    solver.set("timeout", SOLVER_TIMEOUT_MS)
    return solver


def check(solver: z3.Solver, assumptions: Sequence[z3.BoolRef] = ()) -> bool:
    """``solver.check`` as a boolean; z3 giving up (``unknown``) is an error, never a guess.

    Calls z3's C API directly: z3py's ``check`` re-validates every assumption in Python, which
    cost more than the solving itself on rule sets with hundreds of assumption literals.
    """
    count = len(assumptions)
    array = (z3.Ast * count)()
    for index, literal in enumerate(assumptions):
        array[index] = literal.as_ast()
    answer = z3.CheckSatResult(
        z3.Z3_solver_check_assumptions(solver.ctx.ref(), solver.solver, count, array)
    )
    if answer == z3.unknown:
        raise SolverGaveUp(solver.reason_unknown())
    return answer == z3.sat


def core_ids(solver: z3.Solver) -> set[int]:
    """The ids of the last unsat core's literals (z3 shares terms: compare ids, not text,
    which z3's pretty printer makes slow)."""
    return {literal.get_id() for literal in solver.unsat_core()}


class _Marco:
    """MARCO over the rules ``0 .. count - 1``: subclasses say whether a set conflicts.

    ``map`` is the map solver (constrained by the subclass so that it proposes only sets of
    rules that can apply together); :meth:`conflicting` answers for one set, :meth:`grow` makes
    a set that does not conflict maximal.
    """

    def __init__(self, count: int, domain: Sequence[z3.BoolRef]) -> None:
        self.count = count
        self.map = new_solver()
        self.map.add(*domain)
        self.picks = [z3.Bool(f"__pick_{i}") for i in range(count)]
        self.checks = 0  # solver calls, for the benchmark's curiosity

    def conflicting(self, subset: Sequence[int]) -> list[int] | None:
        """None when the rules of ``subset`` do not conflict; else a conflicting part of it."""
        raise NotImplementedError

    def grow(self, subset: list[int]) -> set[int]:
        """A maximal superset of ``subset`` (which does not conflict) that does not conflict."""
        grown = set(subset)
        for i in range(self.count):
            if i not in grown and self.conflicting(sorted(grown | {i})) is None:
                grown.add(i)
        return grown

    def conflicts(self, limit: int | None = None) -> list[list[int]]:
        """All minimal conflicts (index lists, ascending), or the first ``limit`` of them."""
        found: list[list[int]] = []
        while check(self.map):
            model = self.map.model()
            seed = [i for i in range(self.count) if z3.is_true(model.eval(self.picks[i], True))]
            part = self.conflicting(seed)
            if part is None:
                grown = self.grow(seed)
                outside = [self.picks[i] for i in range(self.count) if i not in grown]
                if not outside:
                    break  # everything holds together: no conflict anywhere
                self.map.add(z3.Or(*outside))
            else:
                mus = self.shrink(part)
                found.append(mus)
                self.map.add(z3.Or(*[z3.Not(self.picks[i]) for i in mus]))
                if limit is not None and len(found) >= limit:
                    break
        return sorted(found)

    def shrink(self, subset: list[int]) -> list[int]:
        """A minimal conflicting subset of the conflicting ``subset`` (deletion + cores)."""
        needed: list[int] = []  # proven necessary: removing any one makes the rest consistent
        rest = list(subset)
        while rest:
            candidate, rest = rest[0], rest[1:]
            part = self.conflicting(needed + rest)
            if part is None:
                needed.append(candidate)
            else:
                # A smaller core keeps every proven-necessary element (else it would be a subset
                # of a consistent set), so only the untested rest shrinks.
                kept = set(part)
                rest = [i for i in rest if i in kept]
        return sorted(needed)


class ConflictFinder(_Marco):
    """Enumerate the minimal conflicts among indexed rules when every variable is context.

    ``domain`` constrains the variables to their declared domains; ``whens[i]`` and
    ``bodies[i]`` (``W_i and R_i``) are z3 booleans over them. A set conflicts when its ``W``s
    hold together somewhere and its ``B``s nowhere.
    """

    def __init__(
        self,
        domain: Sequence[z3.BoolRef],
        whens: Sequence[z3.BoolRef],
        bodies: Sequence[z3.BoolRef],
    ) -> None:
        super().__init__(len(bodies), domain)
        self.bodies = list(bodies)
        self.checker = new_solver()
        self.checker.add(*domain)
        self.selectors = [z3.Bool(f"__body_{i}") for i in range(self.count)]
        for selector, body in zip(self.selectors, bodies, strict=True):
            self.checker.add(z3.Implies(selector, body))
        for pick, when in zip(self.picks, whens, strict=True):
            self.map.add(z3.Implies(pick, when))

    def satisfiable(self, subset: Sequence[int]) -> bool:
        """Whether the ``bodies`` of ``subset`` hold together somewhere in the domain."""
        self.checks += 1
        return check(self.checker, [self.selectors[i] for i in subset])

    def conflicting(self, subset: Sequence[int]) -> list[int] | None:
        if self.satisfiable(subset):
            return None
        core = core_ids(self.checker)
        return [i for i in subset if self.selectors[i].get_id() in core]

    def grow(self, subset: list[int]) -> set[int]:
        grown = set(subset)
        grown |= self.holding()
        for i in range(self.count):
            if i in grown:
                continue
            if self.satisfiable(sorted(grown | {i})):
                grown.add(i)
                grown |= self.holding()
        return grown

    def holding(self) -> set[int]:
        """The rules whose bodies hold in the last satisfiable check's model (free additions)."""
        model = self.checker.model()
        return {
            i for i in range(self.count) if z3.is_true(model.eval(self.bodies[i], True))
        }


class NoPlanFinder(_Marco):
    """Enumerate the minimal sets of rules under which some context admits no plan.

    ``context`` are the context variables' terms; ``domain`` constrains every variable to its
    declared domain; ``holds[i]`` is rule i (``W_i -> R_i``) over context and plan; ``no_plan``
    turns a formula over both into "no plan makes it true" over the context (see
    :meth:`rasm.rules.smt.Encoder.no_plan`); ``applicable[i]`` says, over the context alone,
    that some plan makes ``W_i`` hold. The map proposes only sets whose rules each apply to some
    plan in one context: a rule that applies to no plan there holds for every plan, so it is in
    no minimal conflict witnessed there.
    """

    def __init__(
        self,
        context: Sequence[z3.ExprRef],
        domain: Sequence[z3.BoolRef],
        holds: Sequence[z3.BoolRef],
        applicable: Sequence[z3.BoolRef],
        no_plan: Callable[[z3.BoolRef], z3.BoolRef],
    ) -> None:
        super().__init__(len(holds), domain)
        self.context = list(context)
        self.domain = list(domain)
        self.holds = list(holds)
        self.no_plan = no_plan
        for pick, when in zip(self.picks, applicable, strict=True):
            self.map.add(z3.Implies(pick, when))
        # the plans at one context, for unsat cores: which rules leave no plan there
        self.plans = new_solver()
        self.plans.add(*domain)
        self.selectors = [z3.Bool(f"__holds_{i}") for i in range(self.count)]
        for selector, rule in zip(self.selectors, holds, strict=True):
            self.plans.add(z3.Implies(selector, rule))

    def witness(self, subset: Sequence[int]) -> z3.ModelRef | None:
        """A model whose context admits no plan obeying every rule of ``subset``, or None."""
        self.checks += 1
        solver = new_solver()
        solver.add(*self.domain)
        solver.add(self.no_plan(z3.And(*[self.holds[i] for i in subset])))
        return solver.model() if check(solver) else None

    def grow(self, subset: list[int]) -> set[int]:
        """A maximal superset of ``subset`` that does not conflict: everything at once, less
        one rule of each conflict found on the way (each such rule is tried again at the end);
        a question per rule costs too much when each is an exists-forall one."""
        grown = set(subset)
        candidates = [i for i in range(self.count) if i not in grown]
        dropped: list[int] = []
        while candidates:
            part = self.conflicting(sorted(grown.union(candidates)))
            if part is None:
                grown.update(candidates)
                break
            # ``grown`` alone does not conflict, so the conflicting part has a candidate
            blamed = [i for i in part if i in candidates] or candidates
            candidates.remove(blamed[-1])
            dropped.append(blamed[-1])
        for i in dropped:
            if self.witness(sorted(grown | {i})) is None:
                grown.add(i)
        return grown

    def conflicting(self, subset: Sequence[int]) -> list[int] | None:
        model = self.witness(subset)
        if model is None:
            return None
        self.plans.push()
        try:
            self.plans.add(*[term == model.eval(term, True) for term in self.context])
            if check(self.plans, [self.selectors[i] for i in subset]):
                return list(subset)  # no smaller part to offer: the deletion will find one
            core = core_ids(self.plans)
        finally:
            self.plans.pop()
        return [i for i in subset if self.selectors[i].get_id() in core]
