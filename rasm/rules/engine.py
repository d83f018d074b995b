"""The Legitimate stage's rule engine: rules compiled once, plans judged without z3.

``CompiledRules.evaluate(plan, context)`` is on the loop's hot path. It never raises on a plan:
a missing value, a value of the wrong type or outside its declared domain, or an expression that
cannot be evaluated makes the rules that read it *broken* (fail closed), each with a reason.

``RuleSet`` holds the rules in force and swaps in a new set only after :func:`verify` proved it
consistent; otherwise the old set stays and the refusal carries the report saying why.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rasm.errors import RasmError, RulesError
from rasm.properties import compile_expression
from rasm.rules.loader import load_rules, parse_rules
from rasm.rules.model import Rules, Variable, require_rules
from rasm.rules.report import Report, format_value
from rasm.rules.verify import is_consistent


@dataclass(frozen=True)
class Decision:
    """The verdict on one plan: accepted, or the names of the rules it broke (file order)."""

    accepted: bool
    broken: tuple[str, ...] = ()
    reasons: dict[str, str] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return self.accepted

    def explanation(self) -> str:
        """One line per broken rule: ``name: reason``."""
        return "; ".join(f"{name}: {self.reasons.get(name, 'broken')}" for name in self.broken)


ACCEPTED = Decision(True)

_Check = tuple[str, Variable]


@dataclass(frozen=True)
class _Compiled:
    name: str
    when_vars: tuple[_Check, ...]
    require_vars: tuple[_Check, ...]
    when: Callable[[Mapping[str, object]], object] | None
    require: Callable[[Mapping[str, object]], object]
    text: str


class CompiledRules:
    """A rule set compiled for fast evaluation (``compile_expression`` of each expression)."""

    def __init__(self, rules: Rules) -> None:
        self.rules = require_rules(rules, "CompiledRules()")
        compiled = []
        for rule in rules.rules:
            when_reads = _names(rule.when)
            when_vars = tuple((n, rules.variables[n]) for n in sorted(when_reads))
            require_vars = tuple(
                (n, rules.variables[n]) for n in sorted(rule.reads - when_reads)
            )
            compiled.append(
                _Compiled(
                    name=rule.name,
                    when_vars=when_vars,
                    require_vars=require_vars,
                    when=None if rule.when is None else compile_expression(rule.when),
                    require=compile_expression(rule.require),
                    text=rule.require_text,
                )
            )
        self._compiled = tuple(compiled)

    def evaluate(
        self, plan: Mapping[str, Any], context: Mapping[str, Any] | None = None
    ) -> Decision:
        """Judge ``plan`` in ``context`` (plan values win over context values of the same name)."""
        if not isinstance(plan, Mapping) or not isinstance(context, Mapping | None):
            raise TypeError(
                "evaluate(plan, context) takes dicts of values by variable name, e.g. "
                f"evaluate({{'velocity': 0.3}}, {{'mode': 'dock'}}), not "
                f"{type(plan if not isinstance(plan, Mapping) else context).__name__}"
            )
        env = {**context, **plan} if context else plan
        broken: list[str] = []
        reasons: dict[str, str] = {}
        for rule in self._compiled:
            reason = _missing_or_bad(rule.when_vars, env)
            if reason is None:
                try:
                    applies = rule.when is None or rule.when(env) is True
                    if applies:
                        reason = _missing_or_bad(rule.require_vars, env)
                        if reason is None and rule.require(env) is not True:
                            reason = f"requires {rule.text}"
                except (RasmError, ArithmeticError, TypeError, ValueError) as exc:
                    reason = f"cannot be evaluated: {exc}"
            if reason is not None:
                broken.append(rule.name)
                reasons[rule.name] = reason
        if not broken:
            return ACCEPTED
        return Decision(False, tuple(broken), reasons)


def _missing_or_bad(checks: tuple[_Check, ...], env: Mapping[str, Any]) -> str | None:
    for name, variable in checks:
        try:
            value = env[name]
        except KeyError:
            return f"no value for {name}"
        if not variable.contains(value):
            return f"{name} = {format_value(value)} is not a value of {variable.describe()}"
    return None


def _names(expr: Any) -> set[str]:
    from rasm.properties import Name
    from rasm.properties.ast import children

    if expr is None:
        return set()
    found: set[str] = set()
    stack = [expr]
    while stack:
        node = stack.pop()
        if isinstance(node, Name):
            found.add(node.name)
        stack.extend(children(node))
    return found


@dataclass(frozen=True)
class SwapResult:
    """What became of a proposed rule set: ``accepted`` or not, and the report or error why."""

    accepted: bool
    reason: str
    report: Report | None = None

    def __bool__(self) -> bool:
        return self.accepted


# (path, bytes, plan fields) -> the file's rules and their consistency report (RuleSet.load)
_CHECKED: dict[tuple[str, bytes, frozenset[str]], tuple[Rules, Report | None]] = {}
_CHECKED_LOCK = threading.Lock()


class RuleSet:
    """The rules in force at the Legitimate stage, replaceable only by consistent rules.

    Evaluation reads one reference to the compiled rules, so a concurrent swap is seen either
    entirely or not at all. A rule set given to the constructor must be consistent too, unless
    ``require_consistent=False`` (tests and tools that judge plans of a known-broken set).
    ``plan_fields`` (an app's ``components.plan.produces``) are plan fields of this set and of
    every set swapped in, besides the variables their files mark ``plan: true``.
    """

    def __init__(
        self,
        rules: Rules,
        *,
        require_consistent: bool = True,
        plan_fields: Iterable[str] = (),
    ) -> None:
        self.plan_fields = frozenset(plan_fields)
        rules = require_rules(rules, "RuleSet() (or RuleSet.load(path) for a file)")
        rules = rules.with_plan_fields(self.plan_fields)
        self.report: Report | None = None
        if require_consistent:
            report = is_consistent(rules)
            if not report.consistent:
                raise RulesError(f"{rules.source}: inconsistent rules: {report.reason()}")
            self.report = report
        self._active = CompiledRules(rules)
        self._lock = threading.Lock()

    @classmethod
    def load(cls, path: str | Path, *, plan_fields: Iterable[str] = ()) -> RuleSet:
        """The consistent rule set of the file at ``path`` (``plan_fields`` as for the
        constructor).

        A file already loaded and proved consistent in this process (same path, same bytes,
        same plan fields) is not parsed and proved again: every platform built from one app
        shares the work.
        """
        fields = frozenset(plan_fields)
        try:
            key: tuple[str, bytes, frozenset[str]] | None = (
                str(path), Path(path).read_bytes(), fields
            )
        except (OSError, TypeError, ValueError):  # load_rules says what is wrong with it
            key = None
        with _CHECKED_LOCK:
            found = _CHECKED.get(key) if key is not None else None
        if found is not None:
            rule_set = cls(found[0], require_consistent=False, plan_fields=fields)
            rule_set.report = found[1]
            return rule_set
        rule_set = cls(load_rules(path), plan_fields=fields)
        if key is not None:
            with _CHECKED_LOCK:
                _CHECKED[key] = (rule_set.rules, rule_set.report)
        return rule_set

    @property
    def rules(self) -> Rules:
        """The rules in force."""
        return self._active.rules

    def evaluate(
        self, plan: Mapping[str, Any], context: Mapping[str, Any] | None = None
    ) -> Decision:
        """Judge a concrete plan with the rules in force (never raises on bad plan values)."""
        return self._active.evaluate(plan, context)

    def swap(self, rules: Rules) -> SwapResult:
        """Replace the rules in force by ``rules`` if they are consistent; else keep the old."""
        require_rules(rules, "swap() (or swap_text(text), swap_file(path))")
        rules = rules.with_plan_fields(self.plan_fields)
        with self._lock:
            try:
                report = is_consistent(rules)
            except RasmError as exc:
                return SwapResult(False, f"rules kept: cannot verify the new set: {exc}")
            if not report.consistent:
                return SwapResult(
                    False, f"rules kept: the new set is inconsistent: {report.reason()}", report
                )
            compiled = CompiledRules(rules)
            self._active = compiled
            self.report = report
            return SwapResult(True, f"rules replaced by {rules.source}", report)

    def swap_text(self, text: str, *, source: str = "<rules>") -> SwapResult:
        """:meth:`swap` from the text of a rules file; bad input is a refusal, not an error."""
        try:
            rules = parse_rules(text, source=source)
        except RasmError as exc:
            return SwapResult(False, f"rules kept: the new set does not load: {exc}")
        return self.swap(rules)

    def swap_file(self, path: str | Path) -> SwapResult:
        """:meth:`swap` from a rules file; bad input is a refusal, not an error."""
        try:
            rules = load_rules(path)
        except RasmError as exc:
            return SwapResult(False, f"rules kept: the new set does not load: {exc}")
        return self.swap(rules)
