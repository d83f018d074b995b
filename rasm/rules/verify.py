"""``rasm verify-rules``: prove, before deployment, that a rule set makes sense.

Definitions (over the declared domains; a rule *holds* at a point unless its ``when`` holds and
its ``require`` does not):

* **dead**: the rule's ``when`` holds nowhere;
* **unsatisfiable**: its ``when`` holds somewhere, but nowhere together with its ``require``;
* **conflict**: a minimal set of two or more rules whose ``when`` conditions hold together
  somewhere, while nowhere do all their ``when`` and ``require`` conditions hold together
  (:mod:`rasm.rules.mus`); it never contains a dead or unsatisfiable rule;
* **redundant**: a rule implied by other rules that can hold where it applies: some set K of
  the other rules implies it, and K holds together with the rule's ``when`` somewhere. (An
  inconsistent set implies anything: without the second condition every rule that applies
  where a conflict does would be "redundant".) Dead and unsatisfiable rules are not reported
  as redundant; unsatisfiable rules still take part in implying others.

With plan fields (variables the planner chooses: ``plan: true`` in the file, or the app's
``components.plan.produces``), the other variables are the *context*, and a rule set is judged
by what it leaves the planner (SPEC section 7):

* **unsatisfiable**: in some context the rule alone admits no plan (its witness is that context);
* **conflict**: a minimal set of two or more rules such that some context admits no plan that
  obeys all of them (its witness is that context: every plan there breaks one of them);
* dead and redundant as above (a point is a context and a plan).

Rules that share no variable cannot conflict or imply each other (except through an empty
domain, which the loader rejects), so each group of rules linked by shared variables is solved
on its own: that keeps large, loosely coupled rule sets near linear.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import z3

from rasm.errors import RulesError, SourceError
from rasm.properties import ast
from rasm.rules.model import Rule, Rules, Variable, require_rules
from rasm.rules.mus import (
    SOLVER_TIMEOUT_MS,
    ConflictFinder,
    NoPlanFinder,
    SolverGaveUp,
    check,
    core_ids,
    new_solver,
)
from rasm.rules.report import Conflict, Report
from rasm.rules.smt import Encoder, encode_rules
from rasm.rules.split import components, guard_split, names

#: Solver calls spent making one redundant rule's "implied by" set minimal, at most.
IMPLIED_BY_BUDGET = 8
#: Rounds of the counterexample-guided redundancy search per rule, at most. Only rules that
#: apply where a conflict does reach it; past the budget the rule is reported as not redundant
#: (never the reverse: every reported redundancy comes with a checked ``implied_by``).
REDUNDANCY_ROUNDS = 6


def verify(rules: Rules, *, redundancy: bool = True) -> Report:
    """Check ``rules`` for dead, unsatisfiable, conflicting and (optionally) redundant rules.

    When z3 cannot decide (``unknown``), :class:`~rasm.errors.SourceError` at the rule it was
    deciding: no report is better than a guessed one."""
    return _Verifier(require_rules(rules, "verify()")).run(redundancy=redundancy)


def is_consistent(rules: Rules) -> Report:
    """The report of :func:`verify` without the redundancy analysis (what a swap needs)."""
    return verify(rules, redundancy=False)


def _nonlinear(expr: ast.Expr) -> list[set[str]]:
    """The variables of each product or quotient of variables in ``expr`` (what makes
    arithmetic nonlinear: ``x * y``, ``2 / x``; not ``2 * x`` or ``x / 2``)."""
    found = []
    if isinstance(expr, ast.Binary) and expr.op in ("*", "/"):
        left, right = names(expr.left), names(expr.right)
        if right and (left or expr.op == "/"):
            found.append(left | right)
    for child in ast.children(expr):
        found += _nonlinear(child)
    return found


def likely_cause(exprs: Iterable[ast.Expr], variables: dict[str, Variable]) -> str:
    """Why z3 may have given up on ``exprs``, in words, from what they compute."""
    terms = [term for expr in exprs for term in _nonlinear(expr)]
    kinds = {variables[n].type for term in terms for n in term if n in variables}
    if "int" in kinds:
        return ("a product or quotient of int variables (nonlinear integer arithmetic, which no "
                "solver decides in general) is the likely cause")
    if terms:
        return ("products or quotients of variables (nonlinear real arithmetic) can take z3 "
                f"past its limit of {SOLVER_TIMEOUT_MS / 1000:g} s per question")
    return f"z3's limit is {SOLVER_TIMEOUT_MS / 1000:g} s per question"


class Undecided(SourceError, RulesError):
    """z3 could not decide a question about the rules: an error in the rules file at the rule
    it was about (a :class:`~rasm.errors.SourceError`), and a
    :class:`~rasm.errors.RulesError` for code that catches the rules layer's errors."""


def gave_up(exc: SolverGaveUp, rules: Sequence[Rule], everything: Rules) -> Undecided:
    """The error for z3 answering ``unknown`` about ``rules`` (all of them when empty), placed
    at the first, with the likely cause read from the rules themselves."""
    rules = list(rules) or list(everything.rules)
    if len(rules) == 1:
        what = f"rule '{rules[0].name}'"
    else:
        shown = ", ".join(f"'{r.name}'" for r in rules[:4])
        what = f"rules {shown}{', ...' if len(rules) > 4 else ''} together"
    exprs = [e for rule in rules for e in (rule.when, rule.require) if e is not None]
    cause = likely_cause(exprs, everything.variables)
    return Undecided(f"z3 could not decide {what} ({exc.reason}): {cause}", rules[0].location)


class _Verifier:
    def __init__(self, rules: Rules) -> None:
        self.rules = rules
        self.encoder: Encoder
        self.encoder, self.formulas = encode_rules(rules)
        self.names = rules.names
        self.plan = set(rules.plan_fields)  # empty: every variable is context
        self.deciding: list[int] = []  # the rules z3 is asked about (for when it gives up)

    def run(self, *, redundancy: bool) -> Report:
        try:
            return self.report(redundancy=redundancy)
        except SolverGaveUp as exc:
            raise gave_up(exc, [self.rules.rules[i] for i in self.deciding], self.rules) from None

    def report(self, *, redundancy: bool) -> Report:
        report = Report(source=self.rules.source, rule_count=len(self.rules.rules),
                        plan_fields=self.rules.plan_fields)
        dead, unsat = set(), set()
        for index, rule in enumerate(self.rules.rules):
            self.deciding = [index]
            when, require = self.formulas[index]
            solver = self.solver(rule.reads)
            if not check(solver, [when]):
                dead.add(index)
                continue
            if self.plan:
                witness = self.no_plan_context([index])
                if witness is not None:
                    unsat.add(index)
                    report.unsatisfiable_contexts[rule.name] = witness
                continue
            witness = self.encoder.decode(solver.model(), self.ordered(rule.reads))
            if not check(solver, [z3.And(when, require)]):
                unsat.add(index)
                report.unsatisfiable_contexts[rule.name] = witness
        in_conflict: set[int] = set()
        for group in self.groups():
            candidates = [i for i in group if i not in dead and i not in unsat]
            self.deciding = candidates
            for conflict in self.conflicts(candidates):
                report.conflicts.append(conflict[1])
                in_conflict.update(conflict[0])
        report.conflicts.sort(key=lambda c: [self.names.index(n) for n in c.rules])
        report.dead = [self.names[i] for i in sorted(dead)]
        report.unsatisfiable = [self.names[i] for i in sorted(unsat)]
        report.unsatisfiable_contexts = {
            n: report.unsatisfiable_contexts[n] for n in report.unsatisfiable
        }
        if redundancy:
            for group in self.groups():
                # an unsatisfiable rule still holds wherever its 'when' does not: it can take
                # part in implying another rule, though it is not reported as redundant itself
                members = [i for i in group if i not in dead]
                self.deciding = members
                judged = [i for i in members if i not in unsat]
                for index, implied_by in self.redundant(members, judged, in_conflict):
                    report.redundant.append(self.names[index])
                    report.implied_by[self.names[index]] = [self.names[i] for i in implied_by]
            order = {n: i for i, n in enumerate(self.names)}
            report.redundant.sort(key=order.__getitem__)
            report.implied_by = {n: report.implied_by[n] for n in report.redundant}
        return report

    # ------------------------------------------------------------------ pieces

    def ordered(self, names: Sequence[str] | set[str] | frozenset[str]) -> list[str]:
        """``names`` in declaration order (witnesses read like the file)."""
        return [n for n in self.rules.variables if n in names]

    def solver(self, names: set[str] | frozenset[str]) -> z3.Solver:
        solver = new_solver()
        solver.add(*self.encoder.domain(self.ordered(names)))
        return solver

    def groups(self) -> list[list[int]]:
        """Rule indices grouped by shared variables (connected components), in file order."""
        return components(range(len(self.names)), lambda i: self.rules.rules[i].reads)

    def reads(self, indices: Sequence[int]) -> set[str]:
        return set().union(*(self.rules.rules[i].reads for i in indices)) if indices else set()

    def no_plan_context(self, members: Sequence[int]) -> dict[str, object] | None:
        """A context (values of the context variables ``members`` read) that admits no plan
        obeying every rule of ``members``, or None when every context admits one."""
        reads = self.reads(members)
        solver = self.solver(reads)
        holds = z3.And(*[z3.Implies(*self.formulas[i]) for i in members])
        solver.add(self.encoder.no_plan(holds, self.ordered(reads & self.plan)))
        if not check(solver):
            return None
        return self.encoder.decode(solver.model(), self.ordered(reads - self.plan))

    @staticmethod
    def plan_read(formula: z3.BoolRef, plan: list[str]) -> list[str]:
        """The names in ``plan`` that ``formula`` reads."""
        read = {str(term) for term in z3.z3util.get_vars(formula)} if plan else set()
        return [n for n in plan if n in read]

    def conflicts(self, candidates: list[int]) -> list[tuple[list[int], Conflict]]:
        if len(candidates) < 2:
            return []
        # with plan fields, only context variables can cut the search into contexts: the
        # planner picks the values of a plan field, it does not find them
        variables = {n: v for n, v in self.rules.variables.items() if n not in self.plan}
        split = guard_split(self.rules.rules, variables, candidates)
        if split is None:
            found = self.search(candidates, {i: self.formulas[i][0] for i in candidates})
        else:
            found = set()
            rest = {i: z3.And(*[self.encoder.condition(c) for c in split.rest[i]])
                    for i in candidates}
            reads = {i: set().union(names(self.rules.rules[i].require),
                                    *(names(c) for c in split.rest[i])) for i in candidates}
            for active in split.active_sets:
                for part in components(active, reads.__getitem__):
                    found |= self.search(part, rest)
        return [(sorted(m), self.conflict(sorted(m))) for m in found]

    def search(self, part: list[int], whens: dict[int, z3.BoolRef]) -> set[frozenset[int]]:
        """The minimal conflicts among ``part``, each rule's ``when`` given by ``whens``."""
        if len(part) < 2:
            return set()
        reads = self.ordered(self.reads(part))
        domain = self.encoder.domain(reads)
        finder: ConflictFinder | NoPlanFinder
        if self.plan:
            plan = [n for n in reads if n in self.plan]
            finder = NoPlanFinder(
                context=[self.encoder.terms[n] for n in reads if n not in self.plan],
                domain=domain,
                holds=[z3.Implies(whens[i], self.formulas[i][1]) for i in part],
                applicable=[self.encoder.somewhere(whens[i], self.plan_read(whens[i], plan),
                                                   str(i)) for i in part],
                no_plan=lambda body: self.encoder.no_plan(body, plan),
            )
        else:
            bodies = [z3.And(whens[i], self.formulas[i][1]) for i in part]
            finder = ConflictFinder(domain, [whens[i] for i in part], bodies)
        return {frozenset(part[i] for i in local) for local in finder.conflicts()}

    def conflict(self, members: list[int]) -> Conflict:
        """The conflict's witness: without plan fields a point where all its ``when``s hold (so
        some rule breaks); with them a context where no plan obeys them all."""
        rules = tuple(self.names[i] for i in members)
        if self.plan:
            context = self.no_plan_context(members)
            assert context is not None, "a conflict without a witness"
            return Conflict(rules=rules, context=context, broken=rules)
        reads = self.reads(members)
        solver = self.solver(reads)
        solver.add(*[self.formulas[i][0] for i in members])
        check(solver)
        model = solver.model()
        broken = tuple(
            self.names[i] for i in members
            if not z3.is_true(model.eval(self.formulas[i][1], True))
        )
        return Conflict(
            rules=rules,
            context=self.encoder.decode(model, self.ordered(reads)),
            broken=broken,
        )

    def redundant(
        self, members: list[int], judged: list[int], in_conflict: set[int]
    ) -> list[tuple[int, list[int]]]:
        """Each rule of ``judged`` genuinely implied by other ``members``, with a small set
        that implies it.

        "Implied by the others" alone would flag every rule that applies where a conflict does
        (no point there is admitted anyway). So a rule r counts as redundant when some set K of
        other rules implies it *and K can hold where r applies*. Such a K exists iff some point
        q where r's ``when`` holds has K_q (the rules holding at q) implying r: an exists-forall
        question, answered by counterexample-guided search (each failed q yields a point p
        where K_q holds and r breaks; later q must make some rule broken at p hold).
        """
        if len(members) < 1:
            return []
        reads = self.reads(members)
        solver = self.solver(reads)
        keep = {i: z3.Bool(f"__keep_{i}") for i in members}
        broken = {i: z3.Bool(f"__broken_{i}") for i in members}
        holds = {i: z3.Implies(*self.formulas[i]) for i in members}
        for i in members:
            when, require = self.formulas[i]
            solver.add(z3.Implies(keep[i], holds[i]))
            solver.add(z3.Implies(broken[i], z3.And(when, z3.Not(require))))
        # Rules whose discrete guards never hold together with r's cannot help imply r (r holds
        # wherever its guard is false), so each rule is judged against its partners only.
        split = guard_split(self.rules.rules, self.rules.variables, members)
        partners: dict[int, set[int]] = {i: set(members) for i in members}
        if split is not None:
            partners = {i: set() for i in members}
            for active in split.active_sets:
                for i in active:
                    partners[i].update(active)
        self.chooser = self.solver(reads)
        for j in members:
            self.chooser.add(z3.Implies(keep[j], holds[j]))
        result = []
        for i in judged:
            others = [j for j in members if j != i and j in partners[i]]
            if check(solver, [broken[i]] + [keep[j] for j in others]):
                continue  # not implied even by all the others together
            core = core_ids(solver)
            used = [j for j in others if keep[j].get_id() in core]
            # Fast paths, each a K for the definition: the (minimised) core itself, then the
            # rules outside every conflict (a conflict where r applies implies anything).
            used = self.minimise(solver, broken[i], keep, used)
            if check(solver, [self.formulas[i][0]] + [keep[j] for j in used]):
                result.append((i, used))
                continue
            calm = [j for j in others if j not in in_conflict]
            if not check(solver, [broken[i]] + [keep[j] for j in calm]):
                core = core_ids(solver)
                used = [j for j in calm if keep[j].get_id() in core]
                if check(solver, [self.formulas[i][0]] + [keep[j] for j in calm]):
                    result.append((i, self.minimise(solver, broken[i], keep, used)))
                    continue
            found = self.supported(solver, i, others, keep, broken, holds, reads)
            if found is not None:
                result.append((i, found))
        return result

    def supported(
        self,
        solver: z3.Solver,
        i: int,
        others: list[int],
        keep: dict[int, z3.BoolRef],
        broken: dict[int, z3.BoolRef],
        holds: dict[int, z3.BoolRef],
        reads: set[str],
    ) -> list[int] | None:
        """A set of ``others`` that implies rule ``i`` and holds somewhere ``i`` applies.

        Counterexample-guided: pick a point q where i applies and a maximal set K of others
        holds (dropping rules named by unsat cores until satisfiable); if K implies i, done;
        else the check's model p (K holds, i breaks) rules out every K' that holds at p: the
        next q must make some rule broken at p hold, so no K comes twice and the search ends.
        """
        chooser = self.chooser
        chooser.push()  # the group's chooser: domains and keep_j -> holds_j, built once
        try:
            return self.search_support(chooser, solver, i, others, keep, broken, holds)
        finally:
            chooser.pop()

    def search_support(
        self,
        chooser: z3.Solver,
        solver: z3.Solver,
        i: int,
        others: list[int],
        keep: dict[int, z3.BoolRef],
        broken: dict[int, z3.BoolRef],
        holds: dict[int, z3.BoolRef],
    ) -> list[int] | None:
        chooser.add(self.formulas[i][0])
        for _ in range(REDUNDANCY_ROUNDS):
            kept = list(others)
            while not check(chooser, [keep[j] for j in kept]):
                core = core_ids(chooser)
                dropped = [j for j in kept if keep[j].get_id() in core]
                if not dropped:
                    return None  # the blocking clauses alone exclude every q: none left
                kept.remove(dropped[-1])
            # K_q: every other rule holding at q: the kept ones, and any dropped one that holds
            q = chooser.model()
            kept_set = set(kept)
            kept += [j for j in others
                     if j not in kept_set and z3.is_true(q.eval(holds[j], True))]
            if not check(solver, [broken[i]] + [keep[j] for j in kept]):
                core = core_ids(solver)
                return self.minimise(solver, broken[i], keep,
                                     [j for j in kept if keep[j].get_id() in core])
            p = solver.model()  # all of K_q holds at p: only rules outside it can be broken
            kept_set = set(kept)
            refuted = [holds[j] for j in others
                       if j not in kept_set and not z3.is_true(p.eval(holds[j], True))]
            if not refuted:
                return None  # every other rule holds at p, where i breaks: nothing implies i
            chooser.add(z3.Or(*refuted))
        return None

    def minimise(
        self, solver: z3.Solver, broken: z3.BoolRef, keep: dict[int, z3.BoolRef], used: list[int]
    ) -> list[int]:
        """Drop rules from ``used`` while the rest still imply the rule (within a budget)."""
        needed: list[int] = []
        rest = list(used)
        budget = IMPLIED_BY_BUDGET
        while rest and budget > 0:
            budget -= 1
            candidate, rest = rest[0], rest[1:]
            if check(solver, [broken] + [keep[j] for j in needed + rest]):
                needed.append(candidate)
            else:
                core = core_ids(solver)
                rest = [j for j in rest if keep[j].get_id() in core]
        return sorted(needed + rest)
