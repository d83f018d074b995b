"""What ``rasm verify-rules`` found, and its two renderings (text for people, JSON for tools)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Conflict:
    """A minimal set of rules that can apply together but cannot all be obeyed.

    ``context`` is a witness: values of the variables these rules read, where every ``when``
    holds; ``broken`` names the rules whose ``require`` fails there (at least one always does).
    """

    rules: tuple[str, ...]
    context: dict[str, Any]
    broken: tuple[str, ...]


@dataclass(frozen=True)
class Violation:
    """A plan the rules admit that violates a property (``verify-rules --against``)."""

    property: str
    expression: str
    witness: dict[str, Any] | None  # None: every admitted plan satisfies the property
    skipped: str | None = None  # why the property could not be judged on one plan


@dataclass
class Report:
    """The consistency report of ``rasm verify-rules``.

    ``unsatisfiable_contexts`` maps each unsatisfiable rule to a context where no plan is
    legitimate (without plan fields: a point where its ``when`` holds); ``implied_by`` maps each
    redundant rule to rules that together imply it (minimal when the search budget allowed).
    """

    source: str
    rule_count: int
    plan_fields: list[str] = field(default_factory=list)  # empty: every variable is context
    unsatisfiable: list[str] = field(default_factory=list)
    conflicts: list[Conflict] = field(default_factory=list)
    redundant: list[str] = field(default_factory=list)
    dead: list[str] = field(default_factory=list)
    unsatisfiable_contexts: dict[str, dict[str, Any]] = field(default_factory=dict)
    implied_by: dict[str, list[str]] = field(default_factory=dict)
    against: list[Violation] | None = None
    # an app's fallback actions (as one plan) and z3's proof that they are legitimate in every
    # context the rules admit (``rasm verify-rules APP``)
    fallback: dict[str, Any] | None = None
    fallback_proof: Any = None  # a rasm.rules.fixed_plan.FixedPlanProof

    @property
    def consistent(self) -> bool:
        """False iff some rule is unsatisfiable or some rules conflict."""
        return not self.unsatisfiable and not self.conflicts

    @property
    def admits_violations(self) -> bool:
        """Whether some checked property can be violated by a plan the rules admit."""
        return any(v.witness is not None for v in self.against or ())

    @property
    def fallback_refused(self) -> bool:
        """Whether the app's fallback actions are not proved legitimate in every context."""
        return self.fallback_proof is not None and not self.fallback_proof.legitimate

    def reason(self) -> str:
        """One line saying why the rules are inconsistent ('' when they are consistent)."""
        parts = [f"rule {name!r} is unsatisfiable" for name in self.unsatisfiable]
        parts += ["rules " + ", ".join(repr(n) for n in c.rules) + " conflict"
                  for c in self.conflicts]
        return "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of ``--format json`` (plus ``against`` when properties were checked)."""
        data: dict[str, Any] = {
            "consistent": self.consistent,
            "unsatisfiable": list(self.unsatisfiable),
            "conflicts": [list(c.rules) for c in self.conflicts],
            "redundant": list(self.redundant),
            "dead": list(self.dead),
            "witnesses": {
                "unsatisfiable": {n: dict(c) for n, c in self.unsatisfiable_contexts.items()},
                "conflicts": [
                    {"rules": list(c.rules), "context": dict(c.context), "broken": list(c.broken)}
                    for c in self.conflicts
                ],
                "redundant": {n: {"implied_by": list(r)} for n, r in self.implied_by.items()},
            },
        }
        if self.against is not None:
            data["against"] = [
                {"property": v.property, "expression": v.expression,
                 "admitted_violation": v.witness is not None, "witness": v.witness}
                | ({"skipped": v.skipped} if v.skipped else {})
                for v in self.against
            ]
        if self.fallback is not None and self.fallback_proof is not None:
            proof = self.fallback_proof
            data["fallback"] = {
                "actions": dict(self.fallback),
                "legitimate": proof.legitimate,
                "context": dict(proof.context) if not proof.legitimate else None,
                "broken": list(proof.broken),
                "reason": proof.explanation(),
            }
        return data


def format_json(report: Report) -> str:
    """``--format json``: one JSON object and a newline."""
    return json.dumps(report.to_dict(), sort_keys=False) + "\n"


def format_value(value: Any) -> str:
    """A value as the expression language writes it (enums quoted, booleans lower case)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value)


def format_context(context: dict[str, Any]) -> str:
    """``mode == "dock", velocity == 0.2`` (or ``any values`` for an empty context)."""
    if not context:
        return "any values"
    return ", ".join(f"{name} == {format_value(value)}" for name, value in context.items())


def counted(count: int, noun: str) -> str:
    """``1 conflict``, ``2 conflicts``: a count with its noun in the right number."""
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def format_text(report: Report) -> str:
    """The human report: one paragraph per finding, a verdict line last."""
    lines: list[str] = []
    planned = bool(report.plan_fields)
    if planned:
        lines.append("plan fields (chosen by the planner): " + ", ".join(report.plan_fields)
                     + "; every other variable is context")
    for name in report.unsatisfiable:
        context = report.unsatisfiable_contexts.get(name, {})
        if planned:
            lines.append(f"unsatisfiable: {name}: "
                         + ("no plan obeys it" if not context else
                            "in some context no plan obeys it"))
            if context:
                lines.append(f"    e.g. {format_context(context)}")
            continue
        lines.append(f"unsatisfiable: {name}: no value in the declared domains meets its "
                     "'require' when its 'when' holds")
        lines.append(f"    e.g. {format_context(context)}")
    for conflict in report.conflicts:
        if planned:
            lines.append("conflict: " + ", ".join(conflict.rules) + ": "
                         + ("no plan obeys them all" if not conflict.context else
                            "in some context no plan obeys them all"))
            if conflict.context:
                lines.append(f"    e.g. {format_context(conflict.context)}: every plan breaks "
                             "one of them")
            continue
        lines.append("conflict: " + ", ".join(conflict.rules)
                     + ": can apply together but cannot all be obeyed")
        lines.append(f"    e.g. {format_context(conflict.context)} breaks "
                     + ", ".join(conflict.broken))
    for name in report.redundant:
        by = report.implied_by.get(name, [])
        lines.append(f"redundant: {name}: implied by "
                     + (", ".join(by) if by else "the declared domains alone"))
    for name in report.dead:
        lines.append(f"dead: {name}: its 'when' can never hold")
    for violation in report.against or ():
        if violation.skipped:
            lines.append(f"property {violation.property}: not checked: {violation.skipped}")
        elif violation.witness is None:
            lines.append(f"property {violation.property}: every plan the rules admit satisfies it")
        else:
            lines.append(f"property {violation.property}: the rules admit a plan that violates "
                         f"{violation.expression}")
            lines.append(f"    e.g. {format_context(violation.witness)}")
    if report.fallback is not None and report.fallback_proof is not None:
        if report.fallback_proof.legitimate:
            lines.append("fallback: legitimate in every context the rules admit: "
                         + format_context(report.fallback))
        else:
            lines.append("fallback: NOT legitimate in every context: "
                         + report.fallback_proof.explanation())
    verdict = "consistent" if report.consistent else "inconsistent"
    lines.append(f"{report.source}: {counted(report.rule_count, 'rule')}, {verdict}: "
                 f"{len(report.unsatisfiable)} unsatisfiable, "
                 f"{counted(len(report.conflicts), 'conflict')}, "
                 f"{len(report.redundant)} redundant, {len(report.dead)} dead")
    return "\n".join(lines) + "\n"
