"""Minimal conflicting sets with z3: a MARCO-style enumeration with unsat-core shrinking.

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

from collections.abc import Sequence

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


class ConflictFinder:
    """Enumerate the minimal conflicts among indexed rules.

    ``domain`` constrains the variables to their declared domains; ``whens[i]`` and
    ``bodies[i]`` (``W_i and R_i``) are z3 booleans over them.
    """

    def __init__(
        self,
        domain: Sequence[z3.BoolRef],
        whens: Sequence[z3.BoolRef],
        bodies: Sequence[z3.BoolRef],
    ) -> None:
        self.count = len(bodies)
        self.bodies = list(bodies)
        self.checker = new_solver()
        self.checker.add(*domain)
        self.selectors = [z3.Bool(f"__body_{i}") for i in range(self.count)]
        for selector, body in zip(self.selectors, bodies, strict=True):
            self.checker.add(z3.Implies(selector, body))
        self.map = new_solver()
        self.map.add(*domain)
        self.picks = [z3.Bool(f"__pick_{i}") for i in range(self.count)]
        for pick, when in zip(self.picks, whens, strict=True):
            self.map.add(z3.Implies(pick, when))
        self.checks = 0  # solver calls, for the benchmark's curiosity

    def satisfiable(self, subset: Sequence[int]) -> bool:
        """Whether the ``bodies`` of ``subset`` hold together somewhere in the domain."""
        self.checks += 1
        return check(self.checker, [self.selectors[i] for i in subset])

    def conflicts(self, limit: int | None = None) -> list[list[int]]:
        """All minimal conflicts (index lists, ascending), or the first ``limit`` of them."""
        found: list[list[int]] = []
        while check(self.map):
            model = self.map.model()
            seed = [i for i in range(self.count) if z3.is_true(model.eval(self.picks[i], True))]
            if self.satisfiable(seed):
                grown = self.grow(seed)
                outside = [self.picks[i] for i in range(self.count) if i not in grown]
                if not outside:
                    break  # everything holds together: no conflict anywhere
                self.map.add(z3.Or(*outside))
            else:
                mus = self.shrink(self.core(seed))
                found.append(mus)
                self.map.add(z3.Or(*[z3.Not(self.picks[i]) for i in mus]))
                if limit is not None and len(found) >= limit:
                    break
        return sorted(found)

    def core(self, subset: Sequence[int]) -> list[int]:
        """The unsat core of the last (unsatisfiable) check, as indices in ``subset`` order."""
        core = core_ids(self.checker)
        return [i for i in subset if self.selectors[i].get_id() in core]

    def shrink(self, subset: list[int]) -> list[int]:
        """A minimal unsatisfiable subset of the unsatisfiable ``subset`` (deletion + cores)."""
        needed: list[int] = []  # proven necessary: removing any one makes the rest satisfiable
        rest = list(subset)
        while rest:
            candidate, rest = rest[0], rest[1:]
            trial = needed + rest
            if self.satisfiable(trial):
                needed.append(candidate)
            else:
                # A smaller core keeps every proven-necessary element (else it would be a subset
                # of a satisfiable set), so only the untested rest shrinks.
                kept = set(self.core(trial))
                rest = [i for i in rest if i in kept]
        return sorted(needed)

    def grow(self, subset: list[int]) -> set[int]:
        """A maximal satisfiable superset of the satisfiable ``subset``."""
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
