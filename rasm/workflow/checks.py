"""Cross-checks of an architecture model that its JSON Schema cannot express.

Each check returns :class:`SourceError` values at the line and column of the offending element:
dangling references, ports with no peer, publisher/subscriber message type mismatches,
components on no compute unit, compute units whose transports cannot reach a component they must
talk to, a MAPLE-K loop missing (or repeating, or splitting) a stage, statecharts declared where
the platform runs none (a chart for a managed-system component, modes on a stage, effector modes
that are no state of the modes chart), and properties or rules that read signals no component
produces (the shared check of :mod:`rasm.platform.signals`).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path, PurePosixPath
from typing import Any

from rasm.errors import Location, SourceError, SourceErrors, closest, mark
from rasm.loop import LOOP_KEYS, STAGES
from rasm.platform.signals import reads, unprovided
from rasm.workflow.model import ArchitectureModel, Check, ModesChart, load_model

__all__ = ["check_model", "lint_model", "mode_states", "produced_signals", "property_reads"]


def lint_model(path: str | Path, *, signals: bool = True) -> list[SourceError]:
    """Every problem in a model (schema and cross-checks) as :class:`SourceError` with positions.

    ``signals=False`` leaves out the names its property and rule files read that no component
    produces (for a model linted with its app, whose manifest's check is the one that runs).
    """
    try:
        model = load_model(path)
    except SourceErrors as exc:
        return list(exc.errors)
    except SourceError as exc:
        return [exc]
    return check_model(model, signals=signals)


def check_model(model: ArchitectureModel, *, signals: bool = True) -> list[SourceError]:
    """Every cross-check problem of ``model``, in file order (``signals=False``: but the names
    its property and rule files read that no component produces)."""
    errors = [
        *_references(model),
        *_signal_clashes(model),
        *_ports(model),
        *_deployment(model),
        *_reachability(model),
        *_loop(model),
        *_statecharts(model),
        *_trustworthiness(model, signals=signals),
    ]
    return sorted(errors, key=lambda e: (e.location.line, e.location.col, e.message))


def _error(model: ArchitectureModel, message: str, location: Location) -> SourceError:
    text = model.source.text if model.source else ""
    return SourceError(message, location, mark(text, location.line, location.col))


def _references(model: ArchitectureModel) -> Iterator[SourceError]:
    for component in model.components.values():
        for port in component.ports.values():
            if port.message not in model.messages:
                known = ", ".join(sorted(model.messages)) or "none declared"
                yield _error(
                    model,
                    f"port {port.ref}: unknown message type '{port.message}' (known: {known})",
                    port.message_location,
                )
    for component, unit in model.deployment.items():
        where = model.deployment_locations[component]
        if component not in model.components:
            yield _error(model, f"deployment names an unknown component '{component}'", where)
        if unit not in model.units:
            known = ", ".join(sorted(model.units))
            yield _error(
                model,
                f"'{component}' is deployed on an unknown compute unit '{unit}' (known: {known})",
                where,
            )
    for link in model.links:
        ends = [(link.publisher, link.publisher_location)]
        ends += list(zip(link.subscribers, link.subscriber_locations, strict=True))
        for ref, where in ends:
            component, _, port = ref.partition(".")
            if component not in model.components:
                yield _error(model, f"topic {link.topic}: unknown component '{component}'", where)
            elif port not in model.components[component].ports:
                ports = ", ".join(sorted(model.components[component].ports)) or "no ports"
                yield _error(
                    model,
                    f"topic {link.topic}: component '{component}' has no port '{port}' "
                    f"(it has {ports})",
                    where,
                )
    for check in model.checks:
        if check.runs_on not in model.units:
            yield _error(
                model,
                f"{check.file} runs on an unknown compute unit '{check.runs_on}'",
                check.runs_on_location,
            )


def _signal_clashes(model: ArchitectureModel) -> Iterator[SourceError]:
    """Fields reaching knowledge under one name with two types (probes share one key space)."""
    from rasm.workflow.derive import probes

    seen: dict[str, tuple[str, str]] = {}
    for message_name in dict.fromkeys(probes(model).values()):
        message = model.messages.get(message_name)
        if message is None:
            continue
        for field_name, spec in message.fields.items():
            kind = str(spec["type"])
            if field_name in seen and seen[field_name][1] != kind:
                other, other_kind = seen[field_name]
                where = (
                    model.source.key(
                        model.source.data["messages"][message_name]["fields"], field_name
                    )
                    if model.source
                    else message.location
                )
                yield _error(
                    model,
                    f"field '{field_name}' of {message_name} is {kind} but {other}'s is "
                    f"{other_kind}: both reach knowledge as '{field_name}'",
                    where,
                )
            seen.setdefault(field_name, (message_name, kind))


def _ports(model: ArchitectureModel) -> Iterator[SourceError]:
    connected: set[str] = set()
    for link in model.links:
        publisher = model.port(link.publisher)
        if publisher is not None:
            connected.add(publisher.ref)
            if publisher.direction != "out":
                yield _error(
                    model,
                    f"topic {link.topic}: publisher {link.publisher} is an 'in' port",
                    link.publisher_location,
                )
        for ref, where in zip(link.subscribers, link.subscriber_locations, strict=True):
            subscriber = model.port(ref)
            if subscriber is None:
                continue
            connected.add(subscriber.ref)
            if subscriber.direction != "in":
                yield _error(model, f"topic {link.topic}: subscriber {ref} is an 'out' port", where)
            if publisher is not None and subscriber.message != publisher.message:
                yield _error(
                    model,
                    f"topic {link.topic}: {ref} expects {subscriber.message} but "
                    f"{link.publisher} publishes {publisher.message}",
                    where,
                )
    for component in model.components.values():
        for port in component.ports.values():
            if port.ref not in connected:
                side = "publishes to" if port.direction == "out" else "subscribes from"
                yield _error(
                    model,
                    f"port {port.ref} has no peer: no row of the communication matrix {side} it",
                    port.location,
                )


def _deployment(model: ArchitectureModel) -> Iterator[SourceError]:
    for component in model.components.values():
        if component.name not in model.deployment:
            yield _error(
                model,
                f"component '{component.name}' is deployed on no compute unit "
                f"(add '{component.name}: UNIT' under deployment)",
                component.location,
            )


def _reachability(model: ArchitectureModel) -> Iterator[SourceError]:
    crossing = False
    for link in model.links:
        pub_component = link.publisher.partition(".")[0]
        pub_unit = model.units.get(model.deployment.get(pub_component, ""))
        for ref, where in zip(link.subscribers, link.subscriber_locations, strict=True):
            sub_component = ref.partition(".")[0]
            sub_unit = model.units.get(model.deployment.get(sub_component, ""))
            if pub_unit is None or sub_unit is None:
                continue  # reported as a dangling reference or an undeployed component
            for unit, peer, peer_unit in (
                (pub_unit, sub_component, sub_unit),
                (sub_unit, pub_component, pub_unit),
            ):
                if link.protocol not in unit.transports:
                    yield _error(
                        model,
                        f"compute unit '{unit.name}' (transports: {', '.join(unit.transports)}) "
                        f"cannot reach '{peer}' on '{peer_unit.name}' over {link.protocol} "
                        f"(topic {link.topic})",
                        where,
                    )
                    break
            else:
                if pub_unit.name != sub_unit.name:
                    crossing = True
                    if link.protocol == "local":
                        yield _error(
                            model,
                            f"topic {link.topic}: '{pub_component}' on '{pub_unit.name}' cannot "
                            f"reach '{sub_component}' on '{sub_unit.name}' over local (an "
                            f"in-process bus); use protocol: mqtt",
                            where,
                        )
    transport = str(model.interface.get("transport", "local"))
    if crossing and not transport.startswith("mqtt://") and model.source is not None:
        data = model.source.data
        where = (
            model.source.value(data["interface"], "transport")
            if "interface" in data and "transport" in (data["interface"] or {})
            else model.source.key(data, "architecture")
        )
        yield _error(
            model,
            "messages cross compute units but interface.transport is "
            f"'{transport}': name the broker (e.g. transport: mqtt://broker:1883)",
            where,
        )


def _loop(model: ArchitectureModel) -> Iterator[SourceError]:
    where = model.source.key(model.source.data, "components") if model.source else Location("")
    seen: dict[str, str] = {}
    for component in model.components.values():
        if component.role not in STAGES:
            continue
        if component.role in seen:
            yield _error(
                model,
                f"'{component.name}' repeats the {component.role} stage of "
                f"'{seen[component.role]}' (one component per MAPLE-K stage)",
                component.location,
            )
        else:
            seen[component.role] = component.name
    for stage in STAGES:
        if stage not in seen:
            yield _error(
                model,
                f"the MAPLE-K loop has no {stage} stage (add a component with role: {stage})",
                where,
            )
    units = {
        model.deployment[c]: c for c in seen.values() if model.deployment.get(c) in model.units
    }
    if len(units) > 1:
        loop_unit = model.managing_unit
        for stage, name in seen.items():
            unit = model.deployment.get(name)
            if unit in model.units and unit != loop_unit:
                yield _error(
                    model,
                    f"the {stage} stage '{name}' is on '{unit}' but the loop runs on "
                    f"'{loop_unit}': rasm runs the five MAPLE-K stages in one process",
                    model.deployment_locations.get(name, where),
                )


def mode_states(model: ArchitectureModel) -> tuple[str, ...]:
    """The states of the model's modes chart: the chart file's when it exists beside the model
    (in a generated app, the engineer's chart is the truth), else the states the model gives."""
    modes = model.modes
    return () if modes is None else _states(modes, _modes_chart(model, modes))


def _states(modes: ModesChart, chart: Any) -> tuple[str, ...]:
    """The modes: the loaded chart's states when there is one, else the model's."""
    if chart is None:
        return modes.states
    return tuple(state for state in chart.states if state != chart.root)


def _modes_chart(model: ArchitectureModel, modes: ModesChart) -> Any:
    """The modes chart file beside the model, loaded; None when there is none or it does not
    load (the app's lint reports a chart that does not load)."""
    from rasm.statechart import load_statechart

    path = model.folder / modes.chart
    if not path.is_file():
        return None
    try:
        return load_statechart(path)
    except (SourceError, SourceErrors):
        return None


def _statecharts(model: ArchitectureModel) -> Iterator[SourceError]:
    """Charts declared where the platform runs none, and effector modes the modes chart lacks."""

    carriers = [c for c in model.components.values() if c.modes is not None]
    files = {check.file for check in model.checks}
    for component in model.components.values():
        if component.implementation == "statechart" and component.role not in STAGES:
            yield _error(
                model,
                f"'{component.name}' is a {component.role}: only a MAPLE-K stage can be a "
                "statechart (the managed system is simulated in Python; give it a modes chart "
                "with modes: instead)",
                component.implementation_location,
            )
        if component.chart is not None and component.chart in files:
            yield _error(
                model,
                f"the chart of '{component.name}', {component.chart}, is also a trustworthiness "
                "file: give that file another path",
                component.implementation_location,
            )
        if component.modes is not None and component.role in STAGES:
            yield _error(
                model,
                f"'{component.name}' is the {component.role} stage: modes belong to the managed "
                "system (put them on a probe, effector or managed component)",
                component.modes.location,
            )
    for extra in carriers[1:]:
        assert extra.modes is not None
        yield _error(
            model,
            f"'{extra.name}' declares modes, but '{carriers[0].name}' already does: the managed "
            "system has one modes chart",
            extra.modes.location,
        )
    modes = model.modes
    if modes is None:
        states: tuple[str, ...] = ()
    else:
        chart = _modes_chart(model, modes)  # loaded once for the checks below
        states = _states(modes, chart)
        yield from _modes_chart_problems(model, modes, chart, states)
    yield from _effector_modes(model, modes, set(states))
    if modes is not None and model.mode_signal is not None and model.source is not None:
        trust = model.source.data["trustworthiness"]
        yield _error(
            model,
            "the managed system's modes are its modes chart: leave out mode_signal",
            model.source.key(trust, "mode_signal"),
        )


def _effector_modes(
    model: ArchitectureModel, modes: ModesChart | None, states: set[str]
) -> Iterator[SourceError]:
    """Effector ports' modes: only on what the execute stage sends to, only with a modes
    chart, and only its states."""
    from rasm.workflow.derive import effectors

    targets = {(e.component, e.port) for e in effectors(model)}
    for component in model.components.values():
        for port in component.ports.values():
            if port.modes is None:
                continue
            where = port.modes_locations[0] if port.modes_locations else port.location
            targeted = (component.name, port.name) in targets
            if not targeted:
                yield _error(
                    model,
                    f"port {port.ref}: modes apply to the actions of the execute stage, and no "
                    "row of the communication matrix sends them here",
                    where,
                )
            if modes is None:
                if targeted:
                    yield _error(
                        model,
                        f"port {port.ref} applies in modes, but the managed system has no modes "
                        "chart (give one of its components modes: {states: [...]})",
                        where,
                    )
                continue
            for mode, place in zip(port.modes, port.modes_locations, strict=True):
                if mode not in states:
                    suggestion = closest(mode, states)
                    hint = f": did you mean '{suggestion}'?" if suggestion else ""
                    yield _error(
                        model,
                        f"port {port.ref}: '{mode}' is not a state of the modes chart "
                        f"{modes.chart} (its states: {', '.join(sorted(states))}){hint}",
                        place,
                    )


def _modes_chart_problems(
    model: ArchitectureModel, modes: ModesChart, chart: Any, states: tuple[str, ...]
) -> Iterator[SourceError]:
    if modes.component in modes.states:
        i = modes.states.index(modes.component)
        yield _error(
            model,
            f"state '{modes.component}' is the modes chart's root (named after its component): "
            "name the mode otherwise",
            modes.state_locations[i],
        )
    chart_path = PurePosixPath(modes.chart)
    if chart_path.is_absolute() or ".." in chart_path.parts or "\\" in modes.chart:
        yield _error(
            model,
            f"the modes chart {modes.chart} must be a path inside the application folder "
            "(relative, no '..')",
            modes.chart_location,
        )
    taken = {c.chart: c.name for c in model.components.values() if c.chart is not None}
    taken.update({check.file: check.kind for check in model.checks})
    if modes.chart in taken:
        yield _error(
            model,
            f"the modes chart {modes.chart} is also the file of '{taken[modes.chart]}'",
            modes.chart_location,
        )
    if chart is not None:
        # the engineer's chart is the truth; the model must not promise modes it lacks
        for state, where in zip(modes.states, modes.state_locations, strict=True):
            if state not in chart.states or state == chart.root:
                yield _error(
                    model,
                    f"'{state}' is not a state of the modes chart {modes.chart}: change the "
                    "model's states to match the chart",
                    where,
                )
    written = {"mode", *(f"mode_{state}" for state in states)}
    for key, where in _signal_places(model):
        if key in written:
            yield _error(
                model,
                f"signal '{key}': the modes chart writes it (mode, mode_<state>); a component "
                "producing it too would mix the two in one knowledge key: rename the signal",
                where,
            )


def _signal_places(model: ArchitectureModel) -> Iterator[tuple[str, Location]]:
    """Each signal that reaches knowledge or the trace under its own name (the fields of the
    messages the monitor receives, what components declare they produce), at its declaration."""
    from rasm.workflow.derive import probes

    if model.source is None:
        return
    data = model.source.data
    for name in sorted(set(probes(model).values()) & set(model.messages)):
        fields = data["messages"][name]["fields"]
        for key in fields:
            yield str(key), model.source.key(fields, key)
    for name, component in model.components.items():
        produces = data["components"][name].get("produces") or {}
        for key in component.produces:
            yield key, model.source.key(produces, key)


def produced_signals(model: ArchitectureModel, *, modes: bool = True) -> dict[str, str]:
    """Every signal some component produces (message fields it publishes, declared knowledge,
    and with ``modes`` the keys the modes chart writes: ``mode``, ``mode_<state>``), with its
    type; the platform's own trace keys are not included."""
    out: dict[str, str] = {}
    if modes and model.modes is not None:
        out["mode"] = "str"
        out.update({f"mode_{state}": "bool" for state in mode_states(model)})
    for component in model.components.values():
        out.update(component.produces)
        for port in component.ports.values():
            message = model.messages.get(port.message)
            if port.direction == "out" and message is not None:
                out.update({k: str(v["type"]) for k, v in message.fields.items()})
    return out


def property_reads(check: Check, model: ArchitectureModel) -> tuple[dict[str, Location], list]:
    """The signals a property check reads (name -> first place read) and any problems in it."""
    spec, problems = _specification(check, model)
    if spec is None:
        return {}, problems
    first: dict[str, Location] = {}
    for name, where in reads(spec):
        first.setdefault(name, where)
    return first, []


def _specification(check: Check, model: ArchitectureModel) -> tuple[Any, list[SourceError]]:
    """A property check's checked specification, or None and the problems in its text."""
    from rasm.properties import load_specification

    text, source = _check_text(check, model)
    if text is None:
        return None, []
    try:
        return load_specification(text, source=source), []
    except (SourceError, SourceErrors) as exc:
        errors = exc.errors if isinstance(exc, SourceErrors) else [exc]
        return None, [_relocate(check, model, e) for e in errors]


def _check_text(check: Check, model: ArchitectureModel) -> tuple[str | None, str]:
    if check.text is not None:
        return check.text, str(model.file)
    path = model.folder / check.file
    if path.is_file():
        try:
            return path.read_text(encoding="utf-8"), str(path)
        except (OSError, UnicodeDecodeError):
            return None, str(path)
    return None, str(path)


def _relocate(check: Check, model: ArchitectureModel, error: SourceError) -> SourceError:
    """A problem found inside a check's inline ``text`` moved to its place in the model."""
    if check.text is None or model.source is None or error.location.file != str(model.file):
        return error
    location = _text_location(check, model, error.location)
    return _error(model, error.message, location)


def _text_location(check: Check, model: ArchitectureModel, inner: Location) -> Location:
    src = model.source
    assert src is not None
    section = src.data["trustworthiness"][check.kind]
    entry = next(e for e in section if str(e["file"]) == check.file)
    start = src.value(entry, "text")
    lines = src.text.splitlines()
    if lines[start.line - 1][start.col - 1 :].startswith(("|", ">")):
        # a block scalar: its content starts on the next line, at the block's indentation
        content = [ln for ln in lines[start.line :] if ln.strip()]
        indent = len(content[0]) - len(content[0].lstrip(" ")) if content else 0
        return Location(src.file, start.line + max(inner.line, 1), indent + max(inner.col, 1))
    return src.code_location(entry, "text", max(inner.line, 1), max(inner.col, 1))


def _trustworthiness(model: ArchitectureModel, *, signals: bool) -> Iterator[SourceError]:
    produced = set(produced_signals(model))
    for check in model.checks:
        if check.kind == "rules":
            rules, problems = _rules(check, model)
            yield from problems
            if rules is not None and signals:
                places = [(n, v.location, "rule variable") for n, v in rules.variables.items()]
                yield from _unproduced(check, model, places, produced | _plan_fields(model))
            continue
        spec, problems = _specification(check, model)
        yield from problems
        if spec is not None and signals:
            readable = produced | LOOP_KEYS  # properties may read the keys the loop writes
            places = [
                (name, where, "" if what == "read" else what)
                for name, where, what in unprovided(spec, readable)
            ]
            yield from _unproduced(check, model, places, readable)


def _plan_fields(model: ArchitectureModel) -> set[str]:
    """What a rule may read of a plan: the fields of the messages on the execute stage's ports
    (a plan becomes those actions) and what the plan stage declares it produces."""
    fields: set[str] = set()
    for stage in ("plan", "execute"):
        component = model.stage(stage)
        if component is None:
            continue
        fields.update(component.produces)
        for port in component.ports.values():
            message = model.messages.get(port.message)
            fields.update(message.fields if message is not None else ())
    return fields


def _unproduced(
    check: Check,
    model: ArchitectureModel,
    places: list[tuple[str, Location, str]],
    produced: set[str],
) -> Iterator[SourceError]:
    """A problem at each place where ``check`` reads (or declares: ``what``) a name that is
    not ``produced``."""
    for signal, where, what in places:
        if signal in produced:
            continue
        if check.text is not None and where.file == str(model.file):
            where = _text_location(check, model, where)
        verb = f"declares {what}" if what else "reads"
        suggestion = closest(signal, produced)
        hint = (
            f"did you mean '{suggestion}'?"
            if suggestion is not None
            else "publish it in a message or declare it under a component's produces"
        )
        message = f"{check.file} {verb} '{signal}', which no component produces ({hint})"
        if where.file == str(model.file):
            yield _error(model, message, where)
        else:
            yield SourceError(message, where)


def _rules(check: Check, model: ArchitectureModel) -> tuple[Any, list[SourceError]]:
    """A rules check's rule set, or None and the problems in its text."""
    from rasm.rules.loader import parse_rules

    text, source = _check_text(check, model)
    if text is None:
        return None, []
    try:
        return parse_rules(text, source=source), []
    except (SourceError, SourceErrors) as exc:
        errors = exc.errors if isinstance(exc, SourceErrors) else [exc]
        return None, [_relocate(check, model, e) for e in errors]
