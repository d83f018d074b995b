"""The application manifest, ``app.yaml``, read and validated with positions.

The shape is a JSON Schema (``app.schema.json`` beside this module, also the reference for editors);
a value that breaks it is reported at its own line and column. Cross-checks the schema cannot
express (files that must exist, ``module:Class`` references, effectors named by actions) come after.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jsonschema

from rasm.errors import Location, RasmError, SourceError, SourceErrors, not_utf8
from rasm.loop import reserved_key
from rasm.platform.manifest_messages import check_messages
from rasm.yamltext import YamlSource, load_yaml, plain

__all__ = [
    "AppManifest",
    "Effector",
    "ExternalVerdict",
    "Fallback",
    "Probe",
    "is_chart_ref",
    "SCHEMA",
    "Signal",
    "load_manifest",
    "load_topic_map",
]

SCHEMA: dict[str, Any] = json.loads(
    (Path(__file__).with_name("app.schema.json")).read_text(encoding="utf-8")
)
_REF = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$")


def is_chart_ref(ref: str) -> bool:
    """Whether a stage's component is a statechart (a path ending in .yaml) and not
    ``module:Class``."""
    return str(ref).endswith((".yaml", ".yml"))


@dataclass(frozen=True)
class Signal:
    """A value the managed system reports: its knowledge key, type and declared range."""

    key: str
    type: str
    minimum: float | None = None
    maximum: float | None = None
    history: int = 100
    field: str | None = None  # its field path in a ROS 2 message (None: the payload's key)
    scale: float = 1  # value = field x scale + offset (a number field only)
    offset: float = 0

    def scaled(self, value: Any) -> Any:
        """``value`` (read from the field) x scale + offset; a value that is no number (or a
        bool) is left as it is, for the type check to judge."""
        if (self.scale == 1 and self.offset == 0) or isinstance(value, bool) or not isinstance(
            value, int | float
        ):
            return value
        return value * self.scale + self.offset


@dataclass(frozen=True)
class Probe:
    """A topic the managed system publishes on, routed by Telegraf into knowledge.

    With a ROS 2 interface ``type`` each signal is read from its field path; ``stamp`` is
    ``header`` when a record's time is the message's ``header.stamp`` (else its arrival).
    ``staleness``: seconds it may stay silent before its signals are stale and the managed
    system counts as lost (None: never); ``publisher``: the ROS 2 node that publishes it,
    whose leaving the graph counts as the managed system lost."""

    topic: str
    signals: dict[str, Signal]
    type: str | None = None
    qos: dict[str, Any] | None = None
    stamp: str = "receipt"
    staleness: float | None = None
    publisher: str | None = None


@dataclass(frozen=True)
class Effector:
    """Where actions for one actuator go, and in which managed-system modes they apply.

    ``fields`` maps each payload key to its value type. An effector on a ROS 2 topic has its
    interface ``type`` and ``message_fields``: message field path -> the payload key that fills
    it (``fields`` then holds the types those fields give the keys)."""

    name: str
    topic: str
    modes: tuple[str, ...] | None = None
    fields: dict[str, str] = field(default_factory=dict)
    type: str | None = None
    qos: dict[str, Any] | None = None
    message_fields: dict[str, str] = field(default_factory=dict)
    # "service" or "action": each action calls the ROS 2 service (or sends a goal to the
    # action) named ``topic``; None: it is published on the topic
    call: str | None = None
    # the response's (an action's result's) and the feedback's fields into knowledge: knowledge
    # key -> the signal, whose ``field`` is the path in the answer
    response: dict[str, Signal] = field(default_factory=dict)
    feedback: dict[str, Signal] = field(default_factory=dict)
    timeout: float = 10.0  # seconds a call may take, or a goal until its result

    @property
    def kind(self) -> str:
        """``topic``, ``service`` or ``action``: how its actions go out."""
        return self.call or "topic"

    @property
    def message_type(self) -> str | None:
        """The message its ``fields`` fill: the topic's type, a service's request, an
        action's goal."""
        if not self.type or self.call is None:
            return self.type
        return f"{self.type}_{'Request' if self.call == 'service' else 'Goal'}"

    @property
    def answer_type(self) -> str | None:
        """The message ``response`` reads: a service's response, an action's result."""
        if not self.type or self.call is None:
            return None
        return f"{self.type}_{'Response' if self.call == 'service' else 'Result'}"

    @property
    def signals(self) -> dict[str, Signal]:
        """What its answers put in knowledge (a topic effector's: nothing)."""
        return {**self.response, **self.feedback}


@dataclass(frozen=True)
class ExternalVerdict:
    """A verdict topic of a monitor outside rasm, a veto source (``trustworthiness.
    external_verdicts``): ``{"value": bool}`` JSON, or on ROS 2 ``std_msgs/msg/Bool`` (its
    ``data``) or ``std_msgs/msg/Empty`` (each message a violation that vetoes ``hold`` s).

    ``freshness``: seconds a JSON or Bool verdict counts (a false vetoes that long whatever
    arrives beside it; a source silent that long is stale); ``publisher``: over ROS 2 the node
    whose messages alone count."""

    name: str
    topic: str
    type: str | None = None
    qos: dict[str, Any] | None = None
    hold: float = 1.0
    freshness: float = 1.0
    publisher: str | None = None


@dataclass(frozen=True)
class Fallback:
    """The safe fallback (``fallback:``): per effector the payload of its fallback action, the
    triggers that engage it, and how long no trigger may hold before control is handed back."""

    actions: dict[str, dict[str, Any]]
    when: tuple[str, ...] = ("veto", "managed_system_lost", "stage_failures")
    after_failures: int = 3
    dwell: float = 5.0

    @property
    def values(self) -> dict[str, Any]:
        """Every fallback action's payload in one: what the rules judge."""
        merged: dict[str, Any] = {}
        for payload in self.actions.values():
            merged.update(payload)
        return merged


@dataclass
class AppManifest:
    """A validated ``app.yaml``; paths are resolved against the app folder."""

    name: str
    folder: Path
    file: Path
    description: str = ""
    components: dict[str, str] = field(default_factory=dict)
    # stage -> {name: type}: the Monitor's derived signals, the fields of the Plan's plans
    produces: dict[str, dict[str, str]] = field(default_factory=dict)
    simulator: str | None = None
    simulator_period: float = 0.1
    # the managed system's modes chart (managed_system.modes), resolved against the app folder
    modes: Path | None = None
    scenario: dict[str, Any] = field(default_factory=dict)
    probes: list[Probe] = field(default_factory=list)
    effectors: dict[str, Effector] = field(default_factory=dict)
    properties: list[Path] = field(default_factory=list)
    rules: list[Path] = field(default_factory=list)
    statecharts: dict[str, Path] = field(default_factory=dict)
    transport: str = "local"
    knowledge: str = "sqlite"
    clock: str | None = None
    period: float = 1.0
    duration: float = 60.0
    stage_budget: float = 1.0
    max_replans: int = 2
    max_actions: int = 16
    veto_properties: tuple[str, ...] = ()
    mode_signal: str | None = None
    external_verdicts: dict[str, ExternalVerdict] = field(default_factory=dict)
    publish_verdicts: bool | None = None  # None: on a network transport
    logging: dict[str, Any] = field(default_factory=dict)
    timing: str | None = None
    twin: str | None = None
    twin_horizon: float = 20.0
    twin_dt: float = 0.5
    fallback: Fallback | None = None
    repair: bool = False  # legitimate.repair: nearest
    repair_weights: dict[str, float] = field(default_factory=dict)
    corrective: bool = False  # trustworthiness.corrective
    # platform_properties: per platform property, its limits (name -> value), or None: off
    platform_properties: dict[str, dict[str, float] | None] = field(default_factory=dict)
    raw: dict[str, Any] = field(default_factory=dict)
    # the ROS 2 types of the app (standard interfaces and its msg/*.msg), when it names any
    types: Any = None

    @property
    def plan_fields(self) -> list[str]:
        """The fields of the Plan's plans (``components.plan.produces``): the variables of the
        app's rules that the planner chooses (SPEC section 7)."""
        return list(self.produces.get("plan", {}))

    @property
    def ros_topics(self) -> dict[str, tuple[str, dict[str, Any] | None]]:
        """Every topic the app names with a ROS 2 type: topic -> (type, QoS settings)."""
        found: dict[str, tuple[str, dict[str, Any] | None]] = {}
        for probe in self.probes:
            if probe.type:
                found[probe.topic] = (probe.type, probe.qos)
        for effector in self.effectors.values():
            if effector.type and effector.call is None:
                found[effector.topic] = (effector.type, effector.qos)
        for verdict in self.external_verdicts.values():
            if verdict.type:
                found[verdict.topic] = (verdict.type, verdict.qos)
        return found

    def component_path(self, stage: str) -> list[str]:
        """Where ``stage``'s module:Class is in app.yaml (for :func:`manifest_location`)."""
        written = self.raw.get("components", {}).get(stage)
        if isinstance(written, dict):
            return ["components", stage, "component"]
        return ["components", stage]

    @property
    def signals(self) -> dict[str, Signal]:
        """What goes in knowledge from outside: the probes' signals, and what the service
        and action effectors' answers carry."""
        out: dict[str, Signal] = {}
        for probe in self.probes:
            out.update(probe.signals)
        for effector in self.effectors.values():
            out.update(effector.signals)
        return out


# a topic map (``rasm check --topics``): the probes of a manifest alone
TOPIC_MAP_SCHEMA: dict[str, Any] = {
    "$defs": SCHEMA["$defs"],
    "type": "object",
    "required": ["probes"],
    "additionalProperties": False,
    "properties": {"probes": SCHEMA["properties"]["probes"]},
}


def _schema_errors(src: YamlSource, schema: dict[str, Any] = SCHEMA) -> list[SourceError]:
    validator = jsonschema.Draft202012Validator(schema)
    errors = []
    for error in sorted(validator.iter_errors(plain(src.data)), key=lambda e: list(e.path)):
        path = list(error.absolute_path)
        where = ".".join(str(p) for p in path) or "the manifest"
        message = error.message
        if "propertyNames" in error.schema_path:
            node = _node_at(src.data, path)
            bad = str(error.instance)
            errors.append(
                src.error(
                    f"{where}: '{bad}' is not a name (letters, digits and _, not first a digit)",
                    src.key(node, bad) if bad in node else src.at(path),
                )
            )
            continue
        if error.validator == "additionalProperties":
            known = error.schema.get("properties", {})
            extra = sorted(set(error.instance) - set(known))
            if extra and isinstance(error.instance, dict):
                location = src.key(_node_at(src.data, path), extra[0])
                message = f"unknown key '{extra[0]}' in {where}"
                if path == ["platform_properties"]:
                    message += (" (the platform properties an app may tune or turn off: "
                                f"{', '.join(known)}; the others are always checked)")
                errors.append(src.error(message, location))
                continue
        if error.validator in ("pattern", "type") and error.schema.get("pattern") == "^off$":
            message = f"{error.instance!r} is neither off nor a mapping of its limits"
        errors.append(src.error(f"{where}: {message}", src.at(path)))
    # the schema's number checks let .nan and .inf through (a run of .inf seconds never ends)
    stack: list[tuple[list[Any], Any]] = [([], src.data)]
    while stack:
        path, node = stack.pop()
        if isinstance(node, dict):
            stack.extend((path + [k], v) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((path + [i], v) for i, v in enumerate(node))
        elif isinstance(node, float) and not math.isfinite(node):
            where = ".".join(str(p) for p in path)
            errors.append(src.error(f"{where}: must be a finite number, not {node}", src.at(path)))
    return errors


def _probes(src: YamlSource, problems: list[SourceError]) -> list[Probe]:
    """The probes of a manifest (or a topic map), as the schema let them through."""
    probes = []
    for i, probe in enumerate(src.data.get("probes", [])):
        signals = {}
        for key, spec in probe["signals"].items():
            signals[str(key)] = Signal(
                str(key),
                spec["type"],
                spec.get("min"),
                spec.get("max"),
                spec.get("history", 100),
                spec.get("field"),
                spec.get("scale", 1),
                spec.get("offset", 0),
            )
            if (reason := reserved_key(str(key))) is not None:
                problems.append(
                    src.error(
                        f"signal '{key}': {reason}; give the signal another name",
                        src.key(src.data["probes"][i]["signals"], key),
                    )
                )
            if (
                spec.get("min") is not None
                and spec.get("max") is not None
                and spec["min"] > spec["max"]
            ):
                problems.append(
                    src.error(
                        f"signal '{key}': min is above max",
                        src.at(["probes", i, "signals", key]),
                    )
                )
        probes.append(
            Probe(
                str(probe["topic"]),
                signals,
                probe.get("type"),
                plain(probe["qos"]) if "qos" in probe else None,
                probe.get("stamp", "receipt"),
                float(probe["staleness"]) if "staleness" in probe else None,
                probe.get("publisher"),
            )
        )
    return probes


_CALL_DEFAULT_TIMEOUT = {"service": 10.0, "action": 60.0}


def _effector(
    src: YamlSource, name: str, spec: dict[str, Any], problems: list[SourceError]
) -> Effector:
    """One effector as the schema let it through: exactly one of topic, service and action;
    a service or action needs its type, and only they have answers and a timeout."""
    where = src.key(src.data["effectors"], name)
    given = [key for key in ("topic", "service", "action") if key in spec]
    if len(given) != 1:
        problems.append(src.error(
            f"effector {name}: give it one topic, service or action (where its actions go)"
            + (f", not {' and '.join(given)}" if given else ""),
            where,
        ))
    kind = next((key for key in ("service", "action") if key in spec), "topic")
    call = None if kind == "topic" else kind
    if call is not None and not spec.get("type"):
        problems.append(src.error(
            f"effector {name}: a {call} needs its type (type: pkg/"
            f"{'srv' if call == 'service' else 'action'}/Name)",
            src.key(spec, call),
        ))
    for key in ("response", "feedback", "timeout"):
        if key in spec and (call is None or (key == "feedback" and call == "service")):
            what = "an action" if key == "feedback" else "a service or an action"
            problems.append(src.error(
                f"effector {name}: {key} belongs to {what}"
                + (" (a service answers once: use response)" if call == "service" else ""),
                src.key(spec, key),
            ))
    answers: dict[str, dict[str, Signal]] = {"response": {}, "feedback": {}}
    for part, found in answers.items():
        for path, key in (spec.get(part) or {}).items():
            if str(key) in found or str(key) in answers["response"]:
                problems.append(src.error(
                    f"effector {name}: knowledge key '{key}' is filled twice",
                    src.at(["effectors", name, part, path]),
                ))
            elif (reason := reserved_key(str(key))) is not None:
                problems.append(src.error(
                    f"effector {name}: '{key}': {reason}; give it another name",
                    src.at(["effectors", name, part, path]),
                ))
            # the value type comes from the field's, once the type store is read
            found[str(key)] = Signal(str(key), "json", field=str(path))
    fields = {str(k): str(v) for k, v in (spec.get("fields") or {}).items()}
    typed = bool(spec.get("type"))
    return Effector(
        name,
        str(spec.get(kind, "")),
        tuple(spec["modes"]) if "modes" in spec else None,
        {} if typed else fields,
        spec.get("type"),
        plain(spec["qos"]) if "qos" in spec else None,
        fields if typed else {},
        call,
        answers["response"],
        answers["feedback"],
        float(spec.get("timeout", _CALL_DEFAULT_TIMEOUT.get(kind, 10.0))),
    )


def _derived_signal_problems(
    src: YamlSource, derived: dict[str, str], probes: list[Probe]
) -> list[SourceError]:
    """The Monitor's declared signals share knowledge with the probes' and the trace with the
    loop's keys: a loop key would forge the loop's events, a probe signal's other type would
    have every value refused."""
    declared = src.data["components"]["monitor"].get("produces", {}) if derived else {}
    by_probe = {key: (probe, signal) for probe in probes for key, signal in probe.signals.items()}
    problems = []
    for name, kind in derived.items():
        where = src.key(declared, name)
        if (reason := reserved_key(name)) is not None:
            problems.append(
                src.error(f"signal '{name}': {reason}; give the signal another name", where)
            )
        elif name in by_probe and by_probe[name][1].type != kind:
            probe, signal = by_probe[name]
            problems.append(
                src.error(
                    f"signal '{name}' is {kind} here but probe {probe.topic} gives it as "
                    f"{signal.type}: one knowledge key has one type",
                    where,
                )
            )
    return problems


def _fallback(
    src: YamlSource, effectors: dict[str, Effector], problems: list[SourceError]
) -> Fallback | None:
    """The ``fallback:`` section; an action for an effector the app does not declare is refused."""
    spec = src.data.get("fallback")
    if spec is None:
        return None
    actions: dict[str, dict[str, Any]] = {}
    for name, payload in spec["actions"].items():
        if name not in effectors:
            known = ", ".join(sorted(effectors)) or "none declared"
            problems.append(src.error(
                f"fallback action for unknown effector {name!r} (effectors: {known})",
                src.key(spec["actions"], name),
            ))
            continue
        actions[str(name)] = {str(k): v for k, v in plain(payload).items()}
        problems.extend(_fallback_payload_problems(src, effectors[name], actions[str(name)]))
    return Fallback(
        actions,
        tuple(spec.get("when", Fallback.when)),
        int(spec.get("after_failures", 3)),
        float(spec.get("dwell", 5.0)),
    )


def _fallback_payload_problems(
    src: YamlSource, effector: Effector, payload: dict[str, Any]
) -> list[SourceError]:
    """A fallback action must be sendable on its effector: every value fits the field's type and,
    on a ROS 2 topic, the payload has exactly the keys the message fields take (else the
    fallback would be refused exactly when it is needed)."""
    from rasm.values import fit

    where = ["fallback", "actions", effector.name]
    problems: list[SourceError] = []
    if effector.message_fields:
        keys = set(effector.message_fields.values())
        absent, extra = sorted(keys - set(payload)), sorted(set(payload) - keys)
        if absent or extra:
            what = f"lacks {', '.join(absent)}" if absent else f"has {', '.join(extra)}"
            problems.append(src.error(
                f"the fallback action for {effector.name} {what}: on {effector.type} it must "
                f"give exactly {', '.join(sorted(keys))}",
                src.at(where),
            ))
    for key, value in payload.items():
        kind = effector.fields.get(key)
        if kind is None:
            continue
        try:
            fit(value, kind)
        except RasmError as exc:
            problems.append(src.error(
                f"the fallback action for {effector.name}: {key}: {exc}", src.at([*where, key])
            ))
    return problems


def _node_at(data: Any, path: list[Any]) -> Any:
    for step in path:
        data = data[step]
    return data


def manifest_location(manifest: AppManifest, path: list[Any]) -> Location:
    """Where the node at ``path`` is written in ``manifest``'s app.yaml (for problems found
    after loading, e.g. a component that cannot be imported); the file alone if unreadable."""
    try:
        src = load_yaml(manifest.file.read_text(encoding="utf-8"), str(manifest.file))
        return src.at(path)
    except (OSError, UnicodeDecodeError, SourceError):
        return Location(str(manifest.file))


def _load_mapping(file: Path, what: str) -> YamlSource:
    """A YAML file whose top level must be a mapping (``what`` says which, when it is not)."""
    try:
        text = file.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise not_utf8(str(file), exc) from None
    src = load_yaml(text, str(file))
    if not isinstance(src.data, dict):
        raise SourceErrors([src.error(what, src.node(src.data))])
    return src


def load_topic_map(path: str | Path, known: Any = None) -> tuple[list[Probe], Any]:
    """The probes of a topic map file (a ``probes:`` list, as in ``app.yaml``) and the type
    store their ROS 2 types need (``known``, default the standard interfaces, and ``msg/*.msg``
    beside the file; None when no probe has a type). Raises :class:`SourceErrors` at the place
    of a problem."""
    file = Path(path)
    if not file.is_file():
        raise SourceErrors([SourceError("no such topic map file", Location(str(file)))])
    src = _load_mapping(file, "a topic map is a mapping with a 'probes:' list")
    errors = _schema_errors(src, TOPIC_MAP_SCHEMA)
    if errors:
        raise SourceErrors(errors)
    problems: list[SourceError] = []
    probes = _probes(src, problems)
    types = None
    if not problems:
        types, _ = check_messages(src, file.parent, probes, {}, {}, problems, known)
    if problems:
        raise SourceErrors(problems)
    return probes, types


def load_manifest(app: str | Path) -> AppManifest:
    """Read ``app.yaml`` from an app folder (or the file itself), raising :class:`SourceErrors`."""
    path = Path(app)
    file = path / "app.yaml" if path.is_dir() else path
    if not file.is_file():
        if path.is_dir():
            problem = f"no app manifest in this folder (expected {file})"
        else:
            problem = f"no such app folder or manifest: {path}"
        raise SourceErrors([SourceError(problem, Location(str(file)))])
    src = _load_mapping(file, "an app manifest is a mapping (name, components, ...)")
    errors = _schema_errors(src)
    if errors:
        raise SourceErrors(errors)
    data = src.data
    folder = file.parent
    problems: list[SourceError] = []

    def existing(key_path: list[Any], value: str) -> Path:
        target = folder / value
        if not target.exists():
            problems.append(
                src.error(
                    f"no such file: {value} (relative to {folder})", src.at(key_path)
                )
            )
        return target

    components: dict[str, str] = {}
    produces: dict[str, dict[str, str]] = {}
    for stage, entry in data.get("components", {}).items():
        # a stage is module:Class, or a mapping naming it and what it produces
        ref_path = ["components", stage]
        if isinstance(entry, dict):
            ref_path.append("component")
            produces[str(stage)] = {str(k): str(v) for k, v in entry.get("produces", {}).items()}
            entry = entry["component"]
        components[str(stage)] = str(entry)
        if is_chart_ref(str(entry)):
            existing(ref_path, str(entry))
        elif not _REF.match(str(entry)):
            problems.append(src.error(f"'{entry}' is not module:Class", src.at(ref_path)))
    twin = data.get("twin") or {}
    if "component" in twin and not _REF.match(str(twin["component"])):
        problems.append(
            src.error(
                f"'{twin['component']}' is not module:Class",
                src.at(["twin", "component"]),
            )
        )
    managed = data.get("managed_system", {}) or {}
    modes = existing(["managed_system", "modes"], managed["modes"]) if "modes" in managed else None
    probes = _probes(src, problems)
    problems.extend(_derived_signal_problems(src, produces.get("monitor", {}), probes))
    effectors = {
        str(name): _effector(src, str(name), spec, problems)
        for name, spec in (data.get("effectors") or {}).items()
    }
    trust = data.get("trustworthiness", {}) or {}
    external = {
        str(name): ExternalVerdict(
            str(name),
            str(spec["topic"]),
            spec.get("type"),
            plain(spec["qos"]) if "qos" in spec else None,
            float(spec.get("hold", 1.0)),
            float(spec.get("freshness", 1.0)),
            spec.get("publisher"),
        )
        for name, spec in (trust.get("external_verdicts") or {}).items()
    }
    types = None
    if not problems:
        types, effectors = check_messages(src, folder, probes, effectors, external, problems)
    properties = [existing(["properties", i], p) for i, p in enumerate(data.get("properties", []))]
    rules_field = data.get("rules", [])
    rules_list = [rules_field] if isinstance(rules_field, str) else list(rules_field)
    rules_path = ["rules"] if isinstance(rules_field, str) else None
    rules = [existing(rules_path or ["rules", i], p) for i, p in enumerate(rules_list)]
    charts = {
        str(k): existing(["statecharts", k], v) for k, v in (data.get("statecharts") or {}).items()
    }
    loop = data.get("loop", {}) or {}
    fallback = _fallback(src, effectors, problems)
    legitimate = data.get("legitimate") or {}
    if problems:
        raise SourceErrors(problems)
    return AppManifest(
        name=str(data["name"]),
        folder=folder,
        file=file,
        description=str(data.get("description", "")),
        components=components,
        produces=produces,
        simulator=managed.get("simulator"),
        simulator_period=managed.get("period", 0.1),
        modes=modes,
        scenario=plain(managed.get("scenario", {}) or {}),
        probes=probes,
        effectors=effectors,
        properties=properties,
        rules=rules,
        statecharts=charts,
        transport=str(data.get("transport", "local")),
        knowledge=str(data.get("knowledge", "sqlite")),
        clock=data.get("clock"),
        period=float(loop.get("period", 1.0)),
        duration=float(data.get("duration", 60.0)),
        stage_budget=float(loop.get("stage_budget", 1.0)),
        max_replans=int(loop.get("max_replans", 2)),
        max_actions=int(loop.get("max_actions", 16)),
        veto_properties=tuple(trust.get("veto_properties", ())),
        mode_signal=trust.get("mode_signal"),
        external_verdicts=external,
        publish_verdicts=trust.get("publish_verdicts"),
        logging=plain(data.get("logging", {}) or {}),
        timing=data.get("timing"),
        twin=(data.get("twin") or {}).get("component"),
        twin_horizon=float((data.get("twin") or {}).get("horizon", 20.0)),
        twin_dt=float((data.get("twin") or {}).get("dt", 0.5)),
        fallback=fallback,
        repair=legitimate.get("repair", "off") == "nearest",
        repair_weights={str(k): float(v) for k, v in (legitimate.get("weights") or {}).items()},
        corrective=bool(trust.get("corrective", False)),
        platform_properties={
            str(name): None if setting == "off" else {str(k): v for k, v in plain(setting).items()}
            for name, setting in (data.get("platform_properties") or {}).items()
        },
        raw=plain(data),
        types=types,
    )
