"""The properties a run checks, compiled into monitors: the platform's own (the loop's stage
order, timeliness, ...) as the app sets them, then the app's files, each property name defined
once.

An app tunes the platform's properties in app.yaml (``platform_properties:``): a property's
limits — the bound of a window or the number it is compared with — or ``off``. The limits are
named in :data:`LIMITS` by the operator they belong to; their defaults are the numbers written
in ``properties/*.rv`` (``stage_budget``'s: the app's ``loop.stage_budget``). The properties
without limits (stage order, only legitimate plans executed, rejected plans stay rejected) are
the platform's guarantees: always checked.

The platform's files are named ``rasm:properties/<file>`` wherever a property's place is shown,
rather than where rasm happens to be installed.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from pathlib import Path

from rasm.errors import PlatformError, SourceError, SourceErrors, read_utf8
from rasm.platform.manifest import AppManifest, manifest_location
from rasm.properties.ast import Aggregate, Binary, Bound, Expr, Future, Literal, Past, Specification
from rasm.properties.loader import load_specification
from rasm.properties.monitor import Monitor
from rasm.resources import data_dir

__all__ = ["LIMITS", "compile_app_properties", "platform_specifications", "setting_problems",
           "shown_source"]

# property -> its limits: the setting's name -> the operator the limit belongs to (a temporal
# operator or an aggregate: its window's upper bound; a comparison: the number on its right)
LIMITS: dict[str, dict[str, str]] = {
    "timely_response": {"within": "eventually"},
    "prompt_planning": {"within": "eventually"},
    "stage_budget": {"max_duration": "<="},
    "no_oscillation": {"max_actions": "<=", "window": "count"},
    "loop_alive": {"within": "once"},
}

Settings = Mapping[str, Mapping[str, float] | None]


def shown_source(path: Path) -> str:
    """How a property file is named in reports and messages: ``rasm:properties/<file>`` for the
    platform's, else its path."""
    platform = data_dir("properties")
    if path.parent.resolve() == platform.resolve():
        return f"rasm:properties/{path.name}"
    return str(path)


def platform_specifications(
    settings: Settings = {}, *, stage_budget: float | None = None  # noqa: B006 - read only
) -> list[Specification]:
    """The platform's property files as ``settings`` set them (property -> its limits, or None:
    off); a file whose properties are all off is left out. ``stage_budget``: the default of
    ``stage_budget``'s limit (the app's loop.stage_budget)."""
    specs = []
    for path in sorted(data_dir("properties").glob("*.rv")):
        spec = load_specification(read_utf8(path), source=shown_source(path))
        kept = []
        for prop in spec.properties:
            if prop.name in settings and settings[prop.name] is None:
                continue  # off
            limits = dict(settings.get(prop.name) or {})
            if prop.name == "stage_budget" and stage_budget is not None:
                limits.setdefault("max_duration", stage_budget)
            formula = prop.formula
            for name, value in limits.items():
                formula = _with_limit(prop.name, formula, LIMITS[prop.name][name], value)
            kept.append(dataclasses.replace(prop, formula=formula))
        if kept:
            specs.append(dataclasses.replace(spec, properties=tuple(kept)))
    return specs


def compile_app_properties(m: AppManifest) -> list[Monitor]:
    """One monitor per property file: the platform's (as the app sets them), then the app's
    (``properties:``).

    Verdicts are reported by property name, so a name defined in two files would merge two
    properties silently: that raises :class:`~rasm.errors.PlatformError` naming both files. A
    veto property turned off would veto nothing: refused at its place in app.yaml.
    """
    problems = setting_problems(m)
    if problems:
        raise SourceErrors(problems)
    specs = platform_specifications(m.platform_properties, stage_budget=m.stage_budget)
    specs += [load_specification(read_utf8(p), source=str(p)) for p in m.properties]
    # with robustness: the checker writes each property's into knowledge (SPEC §12); with the
    # interval of the newest early verdict of each property in a step, whose lower bound it
    # writes until the value is final ("newest": at a cost independent of the time bounds)
    monitors = [Monitor(spec, robustness=True, intervals="newest") for spec in specs]
    defined: dict[str, str] = {}
    for spec in specs:
        for prop in spec.properties:
            if prop.name in defined:
                raise PlatformError(
                    f"property {prop.name!r} of {spec.source} is already defined in "
                    f"{defined[prop.name]}: rename one of them"
                )
            defined[prop.name] = spec.source
    return monitors


def setting_problems(m: AppManifest) -> list[SourceError]:
    """What is wrong with the app's ``platform_properties`` beyond their shape: a veto property
    turned off would veto nothing (each at its place in app.yaml)."""
    return [
        SourceError(
            f"platform property '{name}' is off but vetoes actions "
            "(trustworthiness.veto_properties): a property that is not checked cannot vouch "
            "for an action",
            manifest_location(m, ["platform_properties", name]),
        )
        for name, limits in m.platform_properties.items()
        if limits is None and name in m.veto_properties
    ]


def _with_limit(name: str, formula: Expr, operator: str, value: float) -> Expr:
    """``formula`` with its one ``operator``'s limit set to ``value``."""
    found: list[Expr] = []

    def limit(node: Expr) -> Expr | None:
        if isinstance(node, (Past, Future, Aggregate)) and node.op == operator:
            found.append(node)
            bound = node.bound
            return dataclasses.replace(node, bound=Bound(
                bound.low, float(value), location=bound.location, low_ns=bound.low_ns
            ))
        if isinstance(node, Binary) and node.op == operator and isinstance(node.right, Literal):
            found.append(node)
            kind = type(node.right.value)
            return dataclasses.replace(node, right=Literal(kind(value),
                                                           location=node.right.location))
        return None

    tuned = _rewrite(formula, limit)
    if len(found) != 1:  # the table above and properties/*.rv disagree: a bug of rasm's
        raise PlatformError(f"platform property {name}: {len(found)} places for its "
                            f"'{operator}' limit, not one")
    return tuned


def _rewrite(node: Expr, change: Callable[[Expr], Expr | None]) -> Expr:
    """``node`` with every sub-formula that ``change`` rewrites (not None) replaced."""
    new = change(node)
    if new is not None:
        return new
    fields = {}
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if f.name in ("operand", "left", "right"):
            fields[f.name] = _rewrite(value, change)
        elif f.name == "args":
            fields[f.name] = tuple(_rewrite(arg, change) for arg in value)
    return dataclasses.replace(node, **fields) if fields else node
