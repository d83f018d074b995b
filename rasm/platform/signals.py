"""The static signal check: every name a property or rule reads is one the app provides.

A property reads signals from the adaptation trace, a rule reads a plan's fields and knowledge.
A name nothing writes is a mistake nothing else catches: the property waits for it forever and
is never judged, the rule misses its value and rejects every plan. So ``rasm lint`` and ``rasm
run`` refuse such an app, at the place of the read, suggesting the closest provided name.

What an app provides (:func:`provided`):

* to properties (the trace): its probes' signals, what its service and action effectors'
  answers put in knowledge (``response``, ``feedback``), the loop's own keys, the Monitor's derived
  signals (``components.monitor.produces``), the Plan's fields (``components.plan.produces``:
  the ``planned`` record carries them), ``robustness_<property>`` for every property checked
  (the Trustworthiness Checker writes it, SPEC §12) and, with a twin, ``twin_residual``;
  inside a property file, ``let`` names and inputs declared with a default need no provider;
* to rules: knowledge (probe signals, the Monitor's derived signals, the twin's outputs, the
  properties' robustness) and plan fields (``components.plan.produces`` and the effectors'
  ``fields``: the Trustworthiness Manager judges the action's payload over the plan).

Types are checked too: a value of a type the reader cannot take is refused at run time (an
``int`` input given floats, a ``bool`` event given numbers), so a property would never be judged
and a rule would reject every plan; that is an error like a missing provider.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Collection, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rasm.errors import Location, SourceError, SourceErrors, closest, marked_error, read_utf8
from rasm.loop import LOOP_SIGNAL_TYPES, robustness_key
from rasm.platform.manifest import AppManifest, manifest_location
from rasm.platform.own_topics import own_topic_problems
from rasm.resources import data_dir

__all__ = [
    "Provided",
    "Provider",
    "app_problems",
    "checked_properties",
    "check_app",
    "provided",
    "reads",
    "unprovided",
]

# what the runtime registers in knowledge for a twin (twin_residual also goes in the trace)
_TWIN_KNOWLEDGE = {"twin_residual": "float", "twin_model": "json"}

# which provided types a reader of each type takes
# (rasm.properties.monitor.coerce, Variable.contains)
_PROPERTY_TAKES = {
    "float": {"float", "int"},
    "int": {"int"},
    "bool": {"bool"},
    "str": {"str"},
    "any": {"float", "int", "bool", "str"},
}
_RULE_TAKES = {
    "real": {"float", "int"},
    "int": {"int"},
    "bool": {"bool"},
    "enum": {"str"},
}


@dataclass(frozen=True)
class Provider:
    """What writes a name: its type and where it is declared, in words."""

    type: str
    origin: str


@dataclass(frozen=True)
class Provided:
    """The names an app writes: in the trace (what properties read), in knowledge, and as plan
    fields (what rules read besides knowledge)."""

    trace: dict[str, Provider] = field(default_factory=dict)
    knowledge: dict[str, Provider] = field(default_factory=dict)
    plan: dict[str, Provider] = field(default_factory=dict)

    @property
    def rules(self) -> dict[str, Provider]:
        """What a rule may read: plan fields win over knowledge of the same name, as in the
        Legitimate stage."""
        return {**self.knowledge, **self.plan}


def provided(manifest: AppManifest) -> Provided:
    """Every name ``manifest``'s app writes, with its type and provider."""
    knowledge: dict[str, Provider] = {}
    for probe in manifest.probes:
        for key, signal in probe.signals.items():
            knowledge[key] = Provider(signal.type, f"probe {probe.topic}")
    for effector in manifest.effectors.values():
        for part in ("response", "feedback"):
            for key, signal in getattr(effector, part).items():
                what = "result" if part == "response" and effector.call == "action" else part
                origin = f"effector {effector.name}'s {what}"
                knowledge.setdefault(key, Provider(signal.type, origin))
    for key, kind in manifest.produces.get("monitor", {}).items():
        knowledge.setdefault(key, Provider(kind, "components.monitor.produces"))
    if manifest.modes is not None:
        knowledge.setdefault("mode", Provider("str", "the modes chart"))
    if manifest.twin:
        for key, kind in _TWIN_KNOWLEDGE.items():
            knowledge[key] = Provider(kind, "the digital twin")
    for name in checked_properties(manifest):
        knowledge.setdefault(robustness_key(name), Provider(
            "float", f"the Trustworthiness Checker (property {name}'s robustness)"))
    planned = {
        key: Provider(kind, "components.plan.produces")
        for key, kind in manifest.produces.get("plan", {}).items()
    }
    plan = dict(planned)
    for effector in manifest.effectors.values():
        for key, kind in effector.fields.items():
            plan.setdefault(key, Provider(kind, f"effector {effector.name}'s fields"))
    # a loop key without a known type ("any") is provided but not type-checked
    trace = {key: Provider(kind, "the loop") for key, kind in LOOP_SIGNAL_TYPES.items()}
    trace.update(_mode_signals(manifest))
    # the trace holds knowledge as registered (json values never: reading them is a type
    # error) and the planned record the plan's fields
    trace.update(knowledge)
    for key, provider in planned.items():
        trace.setdefault(key, provider)
    return Provided(trace, knowledge, plan)


def checked_properties(manifest: AppManifest) -> list[str]:
    """The names of the properties a run checks: the platform's that are on, then the app's
    (a file that does not parse has none here: it is reported on its own)."""
    off = {name for name, limits in manifest.platform_properties.items() if limits is None}
    names = [name for name in sorted(_platform_property_names()) if name not in off]
    for path in manifest.properties:
        try:
            spec = _load_properties(read_utf8(path), os.path.normpath(path))
        except (OSError, SourceError, SourceErrors):
            continue
        names += [p.name for p in spec.properties]
    return names


def _mode_signals(manifest: AppManifest) -> dict[str, Provider]:
    """``mode`` and ``mode_<state>``, written in the trace by the app's modes chart."""
    if manifest.modes is None:
        return {}
    from rasm.platform.modes import mode_signals
    from rasm.statechart import load_statechart

    try:
        chart = load_statechart(manifest.modes)
    except (OSError, SourceError, SourceErrors):
        return {}  # the chart check reports it
    return {key: Provider(kind, "the modes chart") for key, kind in mode_signals(chart).items()}


def reads(spec: Any) -> list[tuple[str, Location]]:
    """Every place a property or ``let`` of ``spec`` (a checked Specification) reads a signal,
    in file order, each place once (a ``let`` used twice is read at its definition once)."""
    from rasm.properties.ast import Name, children

    places: dict[tuple[str, Location], None] = {}
    stack = [let.expr for let in reversed(spec.lets)]
    stack += [prop.formula for prop in reversed(spec.properties)]
    while stack:
        node = stack.pop()
        if isinstance(node, Name):
            places.setdefault((node.name, node.location), None)
        stack.extend(reversed(children(node)))
    return sorted(places, key=lambda p: (p[1].line, p[1].col, p[0]))


def unprovided(spec: Any, names: Collection[str]) -> list[tuple[str, Location, str]]:
    """The signals ``spec`` reads that are not in ``names``, as (name, place, what): each read
    (``what`` is "read") and each declaration never read (``what`` is "input" or "event").
    An input declared with a default needs no provider."""
    defaulted = {item.name for item in spec.inputs if item.default is not None}
    have = set(names) | defaulted
    found = [(name, where, "read") for name, where in reads(spec) if name not in have]
    read = {name for name, _ in reads(spec)}
    for kind, items in (("input", spec.inputs), ("event", spec.events)):
        found += [
            (item.name, item.location, kind)
            for item in items
            if item.name not in have and item.name not in read
        ]
    return sorted(found, key=lambda f: (f[1].line, f[1].col, f[0]))


# --------------------------------------------------------------------------- the app check


def app_problems(manifest: AppManifest, transport: str | None = None) -> list[SourceError]:
    """Every name the app's property and rule files read that nothing provides, or provides
    with a type they cannot take; veto properties or a mode signal that do not exist; and the
    problems of the charts the app brings (:mod:`rasm.platform.app_charts`).
    A file that does not parse is reported with its own errors. ``transport``: the one the app
    runs over (default: its manifest's), for what it asks of it (:func:`transport_problems`)."""
    have = provided(manifest)
    problems: list[SourceError] = []
    names: set[str] = set()
    for path in manifest.properties:
        spec = _parsed(path, _load_properties, problems)
        if spec is not None:
            names.update(p.name for p in spec.properties)
            problems += _property_problems(spec, have)
    for path in manifest.rules:
        rules = _parsed(path, _load_rules, problems)
        if rules is not None:
            problems += _rule_problems(rules, have)
    from rasm.platform.app_properties import setting_problems

    found = [
        *_trustworthiness_problems(manifest, have, names),
        *transport_problems(manifest, transport or manifest.transport),
        *own_topic_problems(manifest, names | _platform_property_names()),
        *setting_problems(manifest),
    ]
    problems += sorted(found, key=lambda e: (e.location.line, e.location.col))
    from rasm.platform.app_charts import app_chart_problems

    return problems + app_chart_problems(manifest)


def transport_problems(manifest: AppManifest, transport: str) -> list[SourceError]:
    """What the app asks of ``transport`` that it cannot give: a ``managed_system_lost``
    trigger nothing there reports, an external verdict source with no declared publisher
    over ROS 2 (:mod:`rasm.platform.liveness`)."""
    from rasm.platform.liveness import lost_trigger_problems, publisher_problems

    return [*lost_trigger_problems(manifest, transport), *publisher_problems(manifest, transport)]


def check_app(manifest: AppManifest, transport: str | None = None) -> None:
    """Raise :class:`SourceErrors` with :func:`app_problems`, if there are any (``rasm run``'s
    start-up: an app whose properties could never be judged does not run)."""
    problems = app_problems(manifest, transport)
    if problems:
        raise SourceErrors(problems)


# Every Platform() checks its app: one parse per file text, not one per run (run_app in a
# property-based test builds hundreds); the parsed files are frozen data
@functools.lru_cache(maxsize=64)
def _load_properties(text: str, source: str) -> Any:
    from rasm.properties import load_specification

    return load_specification(text, source=source)


@functools.lru_cache(maxsize=64)
def _load_rules(text: str, source: str) -> Any:
    from rasm.rules import parse_rules

    return parse_rules(text, source=source)


def _parsed(path: Path, load: Any, problems: list[SourceError]) -> Any:
    source = os.path.normpath(path)  # named as a folder lint names the file
    try:
        return load(read_utf8(path), source)
    except SourceErrors as exc:
        problems.extend(exc.errors)
    except SourceError as exc:
        problems.append(exc)
    except OSError as exc:
        problems.append(SourceError(f"cannot read: {exc.strerror}", Location(source)))
    return None


def _property_problems(spec: Any, have: Provided) -> list[SourceError]:
    problems = []
    for name, where, what in unprovided(spec, have.trace):
        problems.append(marked_error(_not_provided(name, what, have.trace), where, len(name)))
    declared = {item.name: item.location for item in (*spec.inputs, *spec.events)}
    first_read = {}
    for name, where in reads(spec):
        first_read.setdefault(name, where)
    for name, kind in spec.signals.items():
        provider = have.trace.get(name)
        if provider is None or provider.type == "any" or provider.type in _PROPERTY_TAKES[kind]:
            continue
        where = declared.get(name) or first_read.get(name) or Location(spec.source)
        used = {"int": "an int", "any": "a plain value"}.get(kind, f"a {kind}")
        problems.append(
            marked_error(
                f"signal '{name}' is read as {used} but {provider.origin} gives it as "
                f"{provider.type}: every value would be refused and no property reading it "
                "judged",
                where,
                len(name),
            )
        )
    return sorted(problems, key=lambda e: (e.location.line, e.location.col))


def _not_provided(name: str, what: str, have: Mapping[str, Provider]) -> str:
    subject = "signal" if what == "read" else what
    message = f"{subject} '{name}' is not provided by any part of the app"
    if name.startswith("mode_") and all(p.origin != "the modes chart" for p in have.values()):
        return (
            f"{message}: in_mode(\"{name.removeprefix('mode_')}\") and mode_<state> read the "
            "managed system's modes chart, and the app has none (managed_system.modes)"
        )
    suggestion = closest(name, have)
    if suggestion is not None:
        return f"{message}: did you mean '{suggestion}'?"
    return (
        f"{message} (declare it in a probe's signals or under components.monitor.produces; "
        "a property can read those, the Plan's fields, the twin's and the loop's keys)"
    )


def _rule_problems(rules: Any, have: Provided) -> list[SourceError]:
    readable = have.rules
    problems = []
    for name, variable in rules.variables.items():
        provider = readable.get(name)
        where = variable.location
        if provider is None:
            message = (
                f"rule variable '{name}' is neither a plan field nor a signal the app provides"
            )
            suggestion = closest(name, readable)
            if suggestion is not None:
                message += f": did you mean '{suggestion}'?"
            if not have.plan:
                message += (
                    "; the app declares no plan fields: list the fields of its plans under "
                    "components.plan.produces"
                )
            problems.append(marked_error(message, where, len(name)))
        elif provider.type != "any" and provider.type not in _RULE_TAKES[variable.type]:
            problems.append(
                marked_error(
                    f"rule variable '{name}' is {variable.type} but {provider.origin} gives it "
                    f"as {provider.type}: the rules reading it would reject every plan",
                    where,
                    len(name),
                )
            )
    return problems


def _trustworthiness_problems(
    manifest: AppManifest, have: Provided, names: set[str]
) -> Iterator[SourceError]:
    """A veto property no file defines would never veto; a mode signal nothing writes leaves
    every effector's modes unknown."""
    if manifest.veto_properties:
        names = names | _platform_property_names() | set(manifest.external_verdicts)
        for i, name in enumerate(manifest.veto_properties):
            if name not in names:
                message = f"veto property '{name}' is not a property of this app"
                suggestion = closest(name, names)
                if suggestion is not None:
                    message += f": did you mean '{suggestion}'?"
                path = ["trustworthiness", "veto_properties", i]
                yield SourceError(message, manifest_location(manifest, path))
    signal = manifest.mode_signal
    if signal is not None and signal not in have.knowledge:
        message = f"mode signal '{signal}' is not a signal the app provides"
        suggestion = closest(signal, have.knowledge)
        if suggestion is not None:
            message += f": did you mean '{suggestion}'?"
        yield SourceError(message, manifest_location(manifest, ["trustworthiness", "mode_signal"]))


@functools.cache
def _platform_property_names() -> frozenset[str]:
    """The properties every app runs (the platform's ``properties/*.rv``)."""
    from rasm.properties import load_specification

    names: set[str] = set()
    for path in sorted(data_dir("properties").glob("*.rv")):
        spec = load_specification(read_utf8(path), source=str(path))
        names.update(p.name for p in spec.properties)
    return frozenset(names)
