"""``legitimate.repair: nearest``: after a rejection, the plan nearest to the rejected one that
every rule set of the app accepts in the current context (z3, :mod:`rasm.rules.repair`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from rasm.errors import SourceError, SourceErrors
from rasm.platform.components import Plan
from rasm.platform.manifest import AppManifest, manifest_location

if TYPE_CHECKING:
    from rasm.rules import RuleSet

__all__ = ["PlanRepair", "check_repair_weights"]


def check_repair_weights(m: AppManifest, rule_sets: Sequence[RuleSet]) -> None:
    """A repair weight for a name no rule reads is a typo: refused at its place."""
    variables = {name for rule_set in rule_sets for name in rule_set.rules.variables}
    unknown = [name for name in m.repair_weights if name not in variables]
    if unknown:
        raise SourceErrors([
            SourceError(
                f"repair weight for {name!r}, which is no rule variable "
                f"({', '.join(sorted(variables)) or 'the app has no rules'})",
                manifest_location(m, ["legitimate", "weights", name]),
            )
            for name in unknown
        ])


class PlanRepair:
    """Finds the nearest legitimate plan for the Plan stage (its ``repair`` callable)."""

    def __init__(self, m: AppManifest, rule_sets: Sequence[RuleSet]) -> None:
        self.manifest = m
        self.rule_sets = list(rule_sets)

    def repair(self, plan: Plan, context: dict[str, Any]) -> Plan | None:
        """The plan nearest to ``plan`` that the rules (all the app's rule sets, as one)
        accept in ``context``; None if z3 finds none in time."""
        from rasm.rules import Rules
        from rasm.rules.repair import REPAIR_TIMEOUT_MS, nearest_plan
        from rasm.rules.report import format_value

        sets = [rule_set.rules for rule_set in self.rule_sets]
        if not sets:
            return None
        variables: dict[str, Any] = {}
        for rules in sets:
            for name, variable in rules.variables.items():
                variables.setdefault(name, variable)
        merged = Rules(variables, tuple(r for rules in sets for r in rules.rules), "rules")
        # z3 runs inside the plan stage: it may take half the stage's budget at most
        budget_ms = max(1, int(min(REPAIR_TIMEOUT_MS, self.manifest.stage_budget * 500)))
        repair = nearest_plan(
            merged, plan.values, context, self.manifest.repair_weights, timeout_ms=budget_ms
        )
        if repair is None or not repair.changed:
            return None
        if not all(rs.evaluate(repair.values, context).accepted for rs in self.rule_sets):
            return None
        changes = ", ".join(
            f"{name} {format_value(plan.values[name])} -> {format_value(repair.values[name])}"
            for name in repair.changed
        )
        why = f"the nearest legitimate plan to {plan.id}: {changes}"
        return Plan(repair.values, explanation=why)
