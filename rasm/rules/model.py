"""The rule set as plain data: declared variables (with their domains) and rules.

Nothing here checks, solves or evaluates anything; :mod:`rasm.rules.loader` builds these objects
from a file, :mod:`rasm.rules.verify` reasons about them with z3 and :mod:`rasm.rules.engine`
evaluates them on concrete plans.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import Any

from rasm.errors import Location

#: The variable types of a rules file.
TYPES = ("real", "int", "enum", "bool")


@dataclass(frozen=True)
class Variable:
    """A plan or context variable a rule may read, with its declared domain.

    ``minimum``/``maximum`` bound ``real`` and ``int`` variables (``None``: unbounded);
    ``values`` lists the values of an ``enum`` (strings, in declaration order). ``plan`` marks
    a plan field, chosen by the planner; every other variable is context.
    """

    name: str
    type: str
    minimum: int | float | None = None
    maximum: int | float | None = None
    values: tuple[str, ...] = ()
    plan: bool = False
    location: Location = field(default=Location("<rules>"), compare=False)

    def contains(self, value: Any) -> bool:
        """Whether ``value`` is a value of this variable's type inside its declared domain."""
        if self.type == "bool":
            return isinstance(value, bool)
        if self.type == "enum":
            return isinstance(value, str) and value in self.values
        # bool is an int subclass in Python, but a flag is not a number in a plan.
        if isinstance(value, bool) or not isinstance(value, int | float):
            return False
        if self.type == "int" and not (isinstance(value, int) or float(value).is_integer()):
            return False
        if value != value:  # NaN satisfies no comparison: never inside a domain
            return False
        if self.minimum is not None and value < self.minimum:
            return False
        return not (self.maximum is not None and value > self.maximum)

    def describe(self) -> str:
        """The domain in words, for messages: ``real in [0, 1.0]``, ``enum {dock, idle}``."""
        if self.type == "enum":
            return "enum {" + ", ".join(self.values) + "}"
        if self.type == "bool":
            return "bool"
        low = "-inf" if self.minimum is None else repr(self.minimum)
        high = "inf" if self.maximum is None else repr(self.maximum)
        return f"{self.type} in [{low}, {high}]"


@dataclass(frozen=True)
class Rule:
    """One legitimacy rule: whenever ``when`` holds, ``require`` must hold.

    ``when`` is ``None`` when the file leaves it out (it then always holds). The expressions are
    the property language's AST (:mod:`rasm.properties.ast`); ``when_text``/``require_text``
    keep the source text for reports.
    """

    name: str
    require: Any
    when: Any = None
    require_text: str = ""
    when_text: str = "true"
    description: str = ""
    location: Location = field(default=Location("<rules>"), compare=False)
    reads: frozenset[str] = frozenset()


@dataclass(frozen=True)
class Rules:
    """A validated rule set: variables by name (in declaration order) and rules in file order."""

    variables: dict[str, Variable]
    rules: tuple[Rule, ...]
    source: str = "<rules>"

    @property
    def names(self) -> list[str]:
        """The rule names in file order."""
        return [rule.name for rule in self.rules]

    @property
    def plan_fields(self) -> list[str]:
        """The variables the planner chooses (``plan: true``, or named by the app), in
        declaration order; empty when every variable is context."""
        return [name for name, variable in self.variables.items() if variable.plan]

    def with_plan_fields(self, names: Iterable[str]) -> Rules:
        """These rules with the declared variables among ``names`` marked as plan fields too
        (an app's ``components.plan.produces``); names that are no variable are ignored."""
        wanted = {name for name in names if name in self.variables}
        if all(self.variables[name].plan for name in wanted):
            return self
        variables = {
            name: replace(variable, plan=True) if name in wanted else variable
            for name, variable in self.variables.items()
        }
        return replace(self, variables=variables)

    def rule(self, name: str) -> Rule:
        """The rule called ``name`` (KeyError if there is none)."""
        for rule in self.rules:
            if rule.name == name:
                return rule
        raise KeyError(name)


def require_rules(value: Any, caller: str) -> Rules:
    """``value`` if it is a :class:`Rules`; else a TypeError saying how to get one."""
    if isinstance(value, Rules):
        return value
    raise TypeError(
        f"{caller} takes Rules: load them with rasm.rules.load_rules(path) or "
        f"parse_rules(text), not a {type(value).__name__}"
    )
