"""The architecture model, ``model.yaml``, read as plain data with positions.

The shape is a JSON Schema (``model.schema.json`` beside this module); a value that breaks it is
reported at its own line and column. The model is recognised by its top-level ``architecture``
key. Cross-checks the schema cannot express (dangling references, unconnected ports, mismatched
message types, unreachable units, a MAPLE-K loop missing a stage, ...) live in
:mod:`rasm.workflow.checks`; :func:`rasm.workflow.checks.lint_model` runs both.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jsonschema

from rasm.errors import Location, SourceError, SourceErrors
from rasm.loop import STAGES
from rasm.yamltext import YamlSource, load_yaml, plain

__all__ = [
    "ArchitectureModel",
    "Check",
    "Component",
    "ComputeUnit",
    "Link",
    "Message",
    "ModesChart",
    "Port",
    "MANAGED_ROLES",
    "SCHEMA",
    "load_model",
    "parse_model",
]

SCHEMA: dict[str, Any] = json.loads(
    Path(__file__).with_name("model.schema.json").read_text(encoding="utf-8")
)
MANAGED_ROLES = ("probe", "effector", "managed")
_NOWHERE = Location("<model>")
_RESERVED = frozenset({"Any", "Simulator", "Random", "StageContext", "Action", "Anomaly", "Plan"})


@dataclass(frozen=True)
class Port:
    """A named connection point of a component: direction and message type."""

    component: str
    name: str
    direction: str
    message: str
    location: Location = _NOWHERE
    message_location: Location = _NOWHERE
    # the managed-system modes in which actions arriving here apply (None: in every mode)
    modes: tuple[str, ...] | None = None
    modes_locations: tuple[Location, ...] = ()

    @property
    def ref(self) -> str:
        return f"{self.component}.{self.name}"


@dataclass(frozen=True)
class ModesChart:
    """The managed system's operation modes, a statechart carried by one managed-system
    component: its file in the app and the states the model gives it (the first is initial)."""

    component: str
    chart: str
    states: tuple[str, ...]
    description: str = ""
    location: Location = _NOWHERE
    chart_location: Location = _NOWHERE
    state_locations: tuple[Location, ...] = ()


@dataclass(frozen=True)
class Component:
    """A functional component: its MAPLE-K stage or managed-system role, and its ports."""

    name: str
    role: str
    ports: dict[str, Port] = field(default_factory=dict)
    produces: dict[str, str] = field(default_factory=dict)
    description: str = ""
    location: Location = _NOWHERE
    implementation: str = "python"
    implementation_location: Location = _NOWHERE
    modes: ModesChart | None = None

    @property
    def chart(self) -> str | None:
        """The stage chart's path in the app (``charts/<name>.yaml``), None for Python."""
        return f"charts/{self.name}.yaml" if self.implementation == "statechart" else None

    @property
    def class_name(self) -> str:
        """The generated class's name: CamelCase, suffixed where it would shadow a name the
        generated module needs (``Any``, ``Simulator``, ...)."""
        name = "".join(part.capitalize() for part in self.name.split("_") if part)
        return f"{name}Component" if name in _RESERVED else name

    @property
    def managing(self) -> bool:
        return self.role in STAGES


@dataclass(frozen=True)
class Message:
    """A message type: its fields (name -> {type, min, max, description})."""

    name: str
    fields: dict[str, dict[str, Any]]
    description: str = ""
    location: Location = _NOWHERE


@dataclass(frozen=True)
class ComputeUnit:
    """A compute unit of the physical architecture."""

    name: str
    arch: str
    transports: tuple[str, ...]
    os: str = "linux"
    cpus: int | None = None
    memory_mb: int | None = None
    python: str | None = None
    knowledge: str | None = None
    clock: str | None = None
    description: str = ""
    location: Location = _NOWHERE


@dataclass(frozen=True)
class Link:
    """One row of the communication matrix: a publisher port, its subscriber ports, a topic."""

    topic: str
    publisher: str
    subscribers: tuple[str, ...]
    protocol: str = "local"
    qos: int = 0
    rate: float | None = None
    location: Location = _NOWHERE
    publisher_location: Location = _NOWHERE
    subscriber_locations: tuple[Location, ...] = ()


@dataclass(frozen=True)
class Check:
    """A trustworthiness check: a property or rule file and the unit where it runs."""

    kind: str  # "properties" | "rules"
    file: str
    runs_on: str
    text: str | None = None
    location: Location = _NOWHERE
    runs_on_location: Location = _NOWHERE
    text_location: Location | None = None


@dataclass
class ArchitectureModel:
    """A schema-valid ``model.yaml`` (not yet cross-checked: see :mod:`rasm.workflow.checks`)."""

    name: str
    file: Path
    description: str = ""
    messages: dict[str, Message] = field(default_factory=dict)
    components: dict[str, Component] = field(default_factory=dict)
    units: dict[str, ComputeUnit] = field(default_factory=dict)
    deployment: dict[str, str] = field(default_factory=dict)
    deployment_locations: dict[str, Location] = field(default_factory=dict)
    links: list[Link] = field(default_factory=list)
    checks: list[Check] = field(default_factory=list)
    veto_properties: tuple[str, ...] = ()
    mode_signal: str | None = None
    interface: dict[str, Any] = field(default_factory=dict)
    source: YamlSource | None = None
    raw: dict[str, Any] = field(default_factory=dict)

    @property
    def folder(self) -> Path:
        return self.file.parent

    def port(self, ref: str) -> Port | None:
        """The port named ``component.port``, or None."""
        component, _, port = ref.partition(".")
        found = self.components.get(component)
        return found.ports.get(port) if found else None

    def stage(self, stage: str) -> Component | None:
        """The component playing MAPLE-K ``stage`` (the first one, if several do)."""
        return next((c for c in self.components.values() if c.role == stage), None)

    @property
    def modes(self) -> ModesChart | None:
        """The managed system's modes chart (the first component's that declares one), or
        None."""
        return next((c.modes for c in self.components.values() if c.modes is not None), None)

    def unit_of(self, component: str) -> str | None:
        return self.deployment.get(component)

    @property
    def managing_unit(self) -> str | None:
        """The unit that runs the MAPLE-K loop (where the monitor is deployed)."""
        monitor = self.stage("monitor")
        return self.unit_of(monitor.name) if monitor else None

    def components_on(self, unit: str) -> list[Component]:
        return [c for name, c in self.components.items() if self.deployment.get(name) == unit]


# --------------------------------------------------------------------------- loading


def _schema_errors(src: YamlSource) -> list[SourceError]:
    validator = jsonschema.Draft202012Validator(SCHEMA)
    errors: list[SourceError] = []
    for error in sorted(validator.iter_errors(plain(src.data)), key=lambda e: list(e.path)):
        path = list(error.absolute_path)
        where = ".".join(str(p) for p in path) or "the model"
        if error.validator == "additionalProperties" and isinstance(error.instance, dict):
            extra = sorted(set(error.instance) - set(error.schema.get("properties", {})))
            if extra:
                node = src.data
                for step in path:
                    node = node[step]
                location = src.key(node, extra[0])
                errors.append(src.error(f"unknown key '{extra[0]}' in {where}", location))
                continue
        if error.validator == "propertyNames":
            node = src.data
            for step in path:
                node = node[step]
            bad = str(error.instance)
            errors.append(
                src.error(
                    f"{where}: '{bad}' is not a valid name here "
                    f"(expected {error.schema.get('pattern', 'a name')})",
                    src.key(node, bad) if bad in node else src.at(path),
                )
            )
            continue
        errors.append(src.error(f"{where}: {error.message}", src.at(path)))
    return errors


def parse_model(text: str, file: str | Path) -> ArchitectureModel:
    """Parse and schema-check a model's text, raising :class:`SourceErrors`."""
    src = load_yaml(text, str(file))
    if not isinstance(src.data, dict) or "architecture" not in src.data:
        raise SourceErrors(
            [
                SourceError(
                    "an architecture model is a mapping with a top-level 'architecture: NAME'",
                    Location(str(file), 1, 1),
                )
            ]
        )
    errors = _schema_errors(src)
    if errors:
        raise SourceErrors(errors)
    return _build(src, Path(file))


def load_model(path: str | Path) -> ArchitectureModel:
    """Read ``model.yaml`` (or ``APP/model.yaml``), raising :class:`SourceErrors`."""
    file = Path(path)
    if file.is_dir():
        file = file / "model.yaml"
    if not file.is_file():
        raise SourceErrors([SourceError(f"no architecture model at {file}", Location(str(file)))])
    try:
        text = file.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise SourceErrors(
            [SourceError("not a UTF-8 text file", Location(str(file), 1, 1))]
        ) from None
    return parse_model(text, file)


def _modes_chart(src: YamlSource, component: str, spec: Any) -> ModesChart | None:
    modes = spec.get("modes")
    if modes is None:
        return None
    return ModesChart(
        component,
        str(modes.get("chart", f"charts/{component}_modes.yaml")),
        tuple(str(s) for s in modes["states"]),
        str(modes.get("description", "")),
        src.key(spec, "modes"),
        src.value(modes, "chart") if "chart" in modes else src.key(spec, "modes"),
        tuple(src.item(modes["states"], i) for i in range(len(modes["states"]))),
    )


def _build(src: YamlSource, file: Path) -> ArchitectureModel:
    data = src.data
    messages = {
        str(name): Message(
            str(name),
            {str(k): plain(v) for k, v in spec["fields"].items()},
            str(spec.get("description", "")),
            src.key(data["messages"], name),
        )
        for name, spec in (data.get("messages") or {}).items()
    }
    components: dict[str, Component] = {}
    for name, spec in data["components"].items():
        ports = {}
        for port_name, port in (spec.get("ports") or {}).items():
            ports[str(port_name)] = Port(
                str(name),
                str(port_name),
                str(port["direction"]),
                str(port["message"]),
                src.key(spec["ports"], port_name),
                src.value(port, "message"),
                tuple(str(m) for m in port["modes"]) if "modes" in port else None,
                tuple(src.item(port["modes"], i) for i in range(len(port.get("modes") or ()))),
            )
        components[str(name)] = Component(
            str(name),
            str(spec["role"]),
            ports,
            {str(k): str(v) for k, v in (spec.get("produces") or {}).items()},
            str(spec.get("description", "")),
            src.key(data["components"], name),
            str(spec.get("implementation", "python")),
            src.value(spec, "implementation") if "implementation" in spec else _NOWHERE,
            _modes_chart(src, str(name), spec),
        )
    units = {
        str(name): ComputeUnit(
            str(name),
            str(spec["arch"]),
            tuple(str(t) for t in spec["transports"]),
            str(spec.get("os", "linux")),
            spec.get("cpus"),
            spec.get("memory_mb"),
            spec.get("python"),
            spec.get("knowledge"),
            spec.get("clock"),
            str(spec.get("description", "")),
            src.key(data["compute_units"], name),
        )
        for name, spec in data["compute_units"].items()
    }
    deployment = {str(k): str(v) for k, v in (data.get("deployment") or {}).items()}
    deployment_locations = {
        str(k): src.value(data["deployment"], k) for k in (data.get("deployment") or {})
    }
    links = []
    for row in data.get("communication") or []:
        links.append(
            Link(
                str(row["topic"]),
                str(row["publisher"]),
                tuple(str(s) for s in row["subscribers"]),
                str(row.get("protocol", "local")),
                int(row.get("qos", 0)),
                row.get("rate"),
                src.node(row),
                src.value(row, "publisher"),
                tuple(src.item(row["subscribers"], i) for i in range(len(row["subscribers"]))),
            )
        )
    trust = data.get("trustworthiness") or {}
    checks = []
    for kind in ("properties", "rules"):
        for entry in trust.get(kind) or []:
            checks.append(
                Check(
                    kind,
                    str(entry["file"]),
                    str(entry["runs_on"]),
                    str(entry["text"]) if "text" in entry else None,
                    src.value(entry, "file"),
                    src.value(entry, "runs_on"),
                    src.value(entry, "text") if "text" in entry else None,
                )
            )
    return ArchitectureModel(
        name=str(data["architecture"]),
        file=file,
        description=str(data.get("description", "")),
        messages=messages,
        components=components,
        units=units,
        deployment=deployment,
        deployment_locations=deployment_locations,
        links=links,
        checks=checks,
        veto_properties=tuple(str(v) for v in trust.get("veto_properties") or ()),
        mode_signal=trust.get("mode_signal"),
        interface=plain(data.get("interface") or {}),
        source=src,
        raw=plain(data),
    )
