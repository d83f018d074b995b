"""Read a rules file into :class:`~rasm.rules.model.Rules`, checking everything.

Every problem names the file, line and column where it is: YAML syntax, the file's shape,
variable domains, duplicate rule names, expression syntax (the property language's own parser,
pointed at the place in this file where the expression starts), unknown variables and type
errors. All independent problems are collected and raised together.
"""

from __future__ import annotations

import keyword
import math
from dataclasses import replace
from pathlib import Path, PurePath
from typing import Any

from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.scalarstring import (
    DoubleQuotedScalarString,
    FoldedScalarString,
    LiteralScalarString,
    SingleQuotedScalarString,
)

from rasm.errors import Location, SourceError, SourceErrors, mark, not_utf8
from rasm.properties import parse_expression
from rasm.rules.model import TYPES, Rule, Rules, Variable
from rasm.rules.typing import check_rule_expression
from rasm.yamltext import YamlSource, load_yaml

_TYPE_ALIASES = {"float": "real", "integer": "int", "boolean": "bool"}
_VARIABLE_KEYS = {"type", "min", "max", "values", "plan", "description"}
_RULE_KEYS = {"name", "when", "require", "description"}
_TOP_KEYS = {"variables", "rules"}
# Names the expression language gives a meaning of its own: a variable cannot take them.
_RESERVED = {
    "true", "false", "and", "or", "not", "abs", "min", "max", "prev", "time", "inf", "count",
    "sum", "avg", "once", "historically", "eventually", "always", "since", "until", "input",
    "event", "let", "property",
}


def load_rules(path: str | Path) -> Rules:
    """Read and validate the rules file at ``path`` (SourceError/SourceErrors on bad input)."""
    if isinstance(path, str) and "\n" in path:
        raise TypeError("load_rules() takes a path; for the text of a rules file use parse_rules")
    if not isinstance(path, str | PurePath):
        raise TypeError(f"load_rules() takes the path of a rules file, not {type(path).__name__}")
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SourceError(f"cannot read rules file: {exc}", Location(str(path))) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise not_utf8(str(path), exc) from None
    return parse_rules(text, source=str(path))


def parse_rules(text: str, *, source: str = "<rules>") -> Rules:
    """Validate the rules file ``text``; ``source`` names it in error messages."""
    if not isinstance(text, str):
        raise TypeError(
            f"parse_rules() takes the text of a rules file, not {type(text).__name__}"
            + (" (for a file: load_rules(path))" if isinstance(text, PurePath) else "")
        )
    return _Loader(text, source).load()


class _Loader:
    def __init__(self, text: str, source: str) -> None:
        self.text = text
        self.source = source
        self.lines = text.splitlines()
        self.errors: list[SourceError] = []
        self.broken: set[str] = set()  # variables declared with a refused declaration
        self.src: YamlSource | None = None

    # ------------------------------------------------------------------ helpers

    def error(self, message: str, location: Location, width: int = 1) -> None:
        """Record a problem at ``location``, its line marked under ``width`` characters."""
        excerpt = mark(self.text, location.line, location.col, width)
        self.errors.append(SourceError(message, location, excerpt))

    def where(self, parent: Any, key: Any, *, value: bool = True) -> Location:
        """Where ``parent[key]`` is written (its value, or its key)."""
        assert self.src is not None
        if isinstance(parent, CommentedSeq):
            return self.src.item(parent, key)
        return self.src.value(parent, key) if value else self.src.key(parent, key)

    def raise_errors(self) -> None:
        if len(self.errors) == 1:
            raise self.errors[0]
        if self.errors:
            raise SourceErrors(self.errors)

    # ------------------------------------------------------------------ reading

    def load(self) -> Rules:
        self.src = load_yaml(self.text, self.source, preserve_quotes=True)
        data = self.src.data
        if not isinstance(data, CommentedMap):
            found = "an empty file" if data is None else f"a {_kind(data)}"
            self.error(
                f"a rules file is a mapping with 'variables' and 'rules', not {found}",
                self.src.start(),
            )
            self.raise_errors()
        for key in data:
            if key not in _TOP_KEYS:
                self.error(
                    f"unknown key {key!r} (a rules file has 'variables' and 'rules')",
                    self.where(data, key, value=False), len(str(key)),
                )
        variables = self.variables(data)
        rules = self.rules(data, variables)
        self.raise_errors()
        return Rules(variables=variables, rules=tuple(rules), source=self.source)

    def variables(self, data: CommentedMap) -> dict[str, Variable]:
        section = data.get("variables")
        if section is None:
            return {}
        if not isinstance(section, CommentedMap):
            self.error(
                f"'variables' must be a mapping of name to domain, not a {_kind(section)}",
                self.where(data, "variables"),
            )
            return {}
        result: dict[str, Variable] = {}
        for name, spec in section.items():
            location = self.where(section, name, value=False)
            if not isinstance(name, str) or not name.isidentifier() or keyword.iskeyword(name):
                self.error(f"variable name {name!r} is not an identifier", location)
                continue
            if name in _RESERVED:
                self.error(
                    f"variable name {name!r} is reserved by the expression language",
                    location, len(name),
                )
                continue
            variable = self.variable(name, spec, section, location)
            if variable is not None:
                result[name] = variable
            else:
                self.broken.add(name)
        return result

    def variable(
        self, name: str, spec: Any, section: CommentedMap, location: Location
    ) -> Variable | None:
        if not isinstance(spec, CommentedMap):
            self.error(
                f"variable {name!r}: expected a mapping like {{type: real, min: 0, max: 1}}, "
                f"not a {_kind(spec)}",
                self.where(section, name),
            )
            return None
        ok = True
        for key in spec:
            if key not in _VARIABLE_KEYS:
                self.error(
                    f"variable {name!r}: unknown key {key!r} (use type, min, max, values, plan)",
                    self.where(spec, key, value=False), len(str(key)),
                )
                ok = False
        plan = spec.get("plan", False)
        if not isinstance(plan, bool):
            self.error(
                f"variable {name!r}: 'plan' is true (a plan field, chosen by the planner) or "
                f"false (context), not {plan!r}",
                self.where(spec, "plan"), len(str(plan)),
            )
            ok = False
        if "type" not in spec:
            self.error(
                f"variable {name!r}: missing 'type' (one of {', '.join(TYPES)})",
                self.where(section, name),
            )
            return None
        type_ = spec["type"]
        type_ = _TYPE_ALIASES.get(type_, type_) if isinstance(type_, str) else type_
        if type_ not in TYPES:
            self.error(
                f"variable {name!r}: unknown type {spec['type']!r} (use one of {', '.join(TYPES)})",
                self.where(spec, "type"), len(str(spec["type"])),
            )
            return None
        if type_ in ("real", "int"):
            numeric = self.numeric(name, type_, spec, location) if ok else None
            return replace(numeric, plan=plan) if numeric is not None else None
        for key in ("min", "max"):
            if key in spec:
                self.error(
                    f"variable {name!r}: '{key}' applies only to real and int variables",
                    self.where(spec, key, value=False), len(key),
                )
                ok = False
        if type_ == "bool":
            if "values" in spec:
                self.error(
                    f"variable {name!r}: 'values' applies only to enum variables",
                    self.where(spec, "values", value=False), len("values"),
                )
                ok = False
            return Variable(name, "bool", plan=plan, location=location) if ok else None
        values = self.enum_values(name, spec)
        if values is None or not ok:
            return None
        return Variable(name, "enum", values=values, plan=plan, location=location)

    def numeric(
        self, name: str, type_: str, spec: CommentedMap, location: Location
    ) -> Variable | None:
        if "values" in spec:
            self.error(
                f"variable {name!r}: 'values' applies only to enum variables",
                self.where(spec, "values", value=False), len("values"),
            )
            return None
        bounds: dict[str, int | float | None] = {"min": None, "max": None}
        ok = True
        for key in ("min", "max"):
            if key not in spec:
                continue
            value = spec[key]
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
                value
            ):
                self.error(
                    f"variable {name!r}: '{key}' must be a finite number, not {value!r}",
                    self.where(spec, key), len(str(value)),
                )
                ok = False
            elif type_ == "int" and not isinstance(value, int):
                self.error(
                    f"variable {name!r}: '{key}' of an int variable must be an integer, "
                    f"not {value!r}",
                    self.where(spec, key), len(str(value)),
                )
                ok = False
            else:
                bounds[key] = int(value) if isinstance(value, int) else float(value)
        low, high = bounds["min"], bounds["max"]
        if ok and low is not None and high is not None and low > high:
            self.error(
                f"variable {name!r}: empty domain, min {low!r} is greater than max {high!r}",
                self.where(spec, "min"),
            )
            ok = False
        return Variable(name, type_, minimum=low, maximum=high, location=location) if ok else None

    def enum_values(self, name: str, spec: CommentedMap) -> tuple[str, ...] | None:
        values = spec.get("values")
        if not isinstance(values, CommentedSeq) or not values:
            where = self.where(spec, "values") if "values" in spec else self.where(spec, "type")
            self.error(
                f"variable {name!r}: an enum needs 'values', a non-empty list like [dock, idle]",
                where,
            )
            return None
        result: list[str] = []
        ok = True
        for index, value in enumerate(values):
            at = self.where(values, index)
            if not isinstance(value, str) or not value:
                self.error(
                    f"variable {name!r}: enum value {value!r} must be a non-empty string "
                    f"(quote it: '{value}')",
                    at, len(str(value)),
                )
                ok = False
            elif value in result:
                self.error(f"variable {name!r}: duplicate enum value {value!r}", at, len(value))
                ok = False
            else:
                result.append(value)
        return tuple(result) if ok else None

    def rules(self, data: CommentedMap, variables: dict[str, Variable]) -> list[Rule]:
        if "rules" not in data:
            self.error("missing 'rules': a list of {name, when, require}", self.src.start())
            return []
        section = data["rules"]
        if section is None:
            return []
        if not isinstance(section, CommentedSeq):
            self.error(
                f"'rules' must be a list of {{name, when, require}}, not a {_kind(section)}",
                self.where(data, "rules"),
            )
            return []
        result: list[Rule] = []
        seen: dict[str, Location] = {}
        for index, item in enumerate(section):
            rule = self.rule(index, item, section, variables, seen)
            if rule is not None:
                result.append(rule)
        return result

    def rule(
        self,
        index: int,
        item: Any,
        section: CommentedSeq,
        variables: dict[str, Variable],
        seen: dict[str, Location],
    ) -> Rule | None:
        at = self.where(section, index)
        if not isinstance(item, CommentedMap):
            self.error(f"rule #{index + 1}: expected a mapping with name and require, "
                       f"not a {_kind(item)}", at)
            return None
        ok = True
        for key in item:
            if key not in _RULE_KEYS:
                self.error(
                    f"rule #{index + 1}: unknown key {key!r} "
                    "(use name, when, require, description)",
                    self.where(item, key, value=False), len(str(key)),
                )
                ok = False
        name = item.get("name")
        if "name" not in item:
            self.error(f"rule #{index + 1}: missing 'name'", at)
            ok = False
        elif not isinstance(name, str) or not name.strip():
            self.error(f"rule #{index + 1}: 'name' must be a non-empty string",
                       self.where(item, "name"))
            ok = False
        else:
            name_at = self.where(item, "name")
            if name in seen:
                self.error(f"duplicate rule name {name!r} (first defined at {seen[name]})",
                           name_at, len(name))
                ok = False
            else:
                seen[name] = name_at
        label = f"rule {name!r}" if isinstance(name, str) else f"rule #{index + 1}"
        if "require" not in item:
            self.error(f"{label}: missing 'require' (the condition the rule imposes)", at)
            ok = False
        reads: set[str] = set()
        exprs: dict[str, tuple[Any, str]] = {}
        for key in ("when", "require"):
            if key not in item:
                continue
            parsed = self.expression(label, key, item, variables)
            if parsed is None:
                ok = False
            else:
                exprs[key] = parsed[0], parsed[1]
                reads |= parsed[2]
        description = item.get("description", "")
        if not ok:
            return None
        when, when_text = exprs.get("when", (None, "true"))
        require, require_text = exprs["require"]
        return Rule(
            name=name,
            require=require,
            when=when,
            require_text=require_text,
            when_text=when_text,
            description=str(description or ""),
            location=at,
            reads=frozenset(reads),
        )

    def expression(
        self, label: str, key: str, item: CommentedMap, variables: dict[str, Variable]
    ) -> tuple[Any, str, set[str]] | None:
        value = item[key]
        at = self.where(item, key)
        if isinstance(value, bool):
            value = "true" if value else "false"
        elif isinstance(value, int | float) or not isinstance(value, str):
            self.error(
                f"{label}: '{key}' must be a condition like velocity <= 0.5, not {value!r}",
                at, len(str(value)),
            )
            return None
        text = str(value).strip()
        if not text:
            self.error(f"{label}: '{key}' is empty", at)
            return None
        source_text, line, col = self.expression_source(value, at)
        try:
            expr = parse_expression(source_text, source=self.source, line=line, col=col)
        except SourceErrors as exc:
            self.errors.extend(exc.errors)
            return None
        except SourceError as exc:
            self.errors.append(exc)
            return None
        try:
            reads = check_rule_expression(
                expr, variables, self.source, self.text, what=key, broken=frozenset(self.broken)
            )
        except SourceErrors as exc:
            self.errors.extend(exc.errors)
            return None
        return expr, " ".join(text.split()), reads

    def expression_source(self, value: Any, at: Location) -> tuple[str, int, int]:
        """The text to parse and the 1-based line and column where it starts in the file
        (``at``: where the value is written).

        A block scalar (``|`` or ``>``) is parsed from the file's own lines, indentation and
        all, so that positions on its second and later lines are right too.
        """
        if isinstance(value, DoubleQuotedScalarString | SingleQuotedScalarString):
            return str(value), at.line, at.col + 1  # skip the opening quote
        if isinstance(value, LiteralScalarString | FoldedScalarString):
            # the content starts on the line after the indicator (index at.line, 0-based)
            first = next((n for n in range(at.line, len(self.lines)) if self.lines[n].strip()),
                         None)
            if first is not None:
                indent = len(self.lines[first]) - len(self.lines[first].lstrip())
                last = first
                for number in range(first + 1, len(self.lines)):
                    content = self.lines[number]
                    if content.strip() and len(content) - len(content.lstrip()) < indent:
                        break
                    last = number
                return "\n".join(self.lines[first : last + 1]), first + 1, 1
        return str(value), at.line, at.col


def _kind(value: Any) -> str:
    if isinstance(value, dict):
        return "mapping"
    if isinstance(value, list):
        return "list"
    if isinstance(value, str):
        return "string"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int | float):
        return "number"
    return type(value).__name__
