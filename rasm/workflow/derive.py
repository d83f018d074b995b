"""What a model means for an application, and a minimal model for an app that has none.

:func:`app_config` turns a model into the content of ``app.yaml`` (probes are the topics the
monitor subscribes to, effectors the components that subscribe to the execute stage);
:func:`model_from_manifest` goes the other way for ``rasm package`` of an app without
``model.yaml``: one compute unit (this machine) running everything.
"""

from __future__ import annotations

import platform as host
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rasm.workflow.model import (
    MANAGED_ROLES,
    ArchitectureModel,
    Check,
    Component,
    ComputeUnit,
    Link,
    Message,
    Port,
)

__all__ = [
    "Effector",
    "Publication",
    "app_config",
    "effectors",
    "host_arch",
    "model_from_manifest",
    "probes",
    "publications",
]

_ARCH = {
    "x86_64": "amd64",
    "amd64": "amd64",
    "aarch64": "arm64",
    "arm64": "arm64",
    "armv7l": "armv7",
    "riscv64": "riscv64",
    "i686": "x86",
    "i386": "x86",
}


def host_arch() -> str:
    """This machine's CPU architecture in the model's vocabulary."""
    return _ARCH.get(host.machine().lower(), "amd64")


@dataclass(frozen=True)
class Effector:
    """An app effector: the component (and port) that receives the execute stage's actions."""

    name: str
    topic: str
    component: str
    port: str
    message: str
    modes: tuple[str, ...] | None = None  # the managed-system modes its actions apply in


@dataclass(frozen=True)
class Publication:
    """A topic a managed-system component publishes, produced by its out-port method."""

    topic: str
    component: str
    port: str
    message: str


def probes(model: ArchitectureModel) -> dict[str, str]:
    """Topics the monitor subscribes to -> the message type published on each."""
    monitor = model.stage("monitor")
    out: dict[str, str] = {}
    for link in model.links:
        publisher = model.port(link.publisher)
        if monitor is None or publisher is None:
            continue
        if any(ref.partition(".")[0] == monitor.name for ref in link.subscribers):
            out[link.topic] = publisher.message
    return out


def effectors(model: ArchitectureModel) -> list[Effector]:
    """The components the execute stage publishes actions to, named for ``Action(name, ...)``."""
    execute = model.stage("execute")
    out: list[Effector] = []
    for link in model.links:
        if execute is None or link.publisher.partition(".")[0] != execute.name:
            continue
        for ref in link.subscribers:
            port = model.port(ref)
            component = model.components.get(ref.partition(".")[0])
            if port is None or component is None:
                continue
            inputs = [p for p in component.ports.values() if p.direction == "in"]
            name = component.name if len(inputs) <= 1 else f"{component.name}_{port.name}"
            out.append(
                Effector(name, link.topic, component.name, port.name, port.message, port.modes)
            )
    return out


def publications(model: ArchitectureModel) -> list[Publication]:
    """Topics published by managed-system components (what the simulator steps)."""
    out = []
    for link in model.links:
        component = model.components.get(link.publisher.partition(".")[0])
        port = model.port(link.publisher)
        if component is not None and port is not None and component.role in MANAGED_ROLES:
            out.append(Publication(link.topic, component.name, port.name, port.message))
    return out


def app_config(model: ArchitectureModel) -> dict[str, Any]:
    """The ``app.yaml`` content for ``model`` (embedded default: local bus, simulator)."""
    interface = model.interface
    components: dict[str, Any] = {}
    for stage in ("monitor", "analyse", "plan", "legitimate", "execute"):
        component = model.stage(stage)
        if component is None:
            continue
        ref = component.chart or f"components:{component.class_name}"
        # what the monitor or plan declares it produces: the app's signal check needs it
        if component.produces and stage in ("monitor", "plan"):
            components[stage] = {"component": ref, "produces": dict(component.produces)}
        else:
            components[stage] = ref
    simulator = interface.get("simulator", {})
    managed_system: dict[str, Any] = {}
    if model.modes is not None:
        managed_system["modes"] = model.modes.chart
    managed_system.update(
        simulator="components:Simulator",
        period=simulator.get("period", 0.1),
        scenario=simulator.get("scenario", {}),
    )
    config: dict[str, Any] = {
        "name": model.name,
        "description": model.description or f"{model.name}: generated from its model",
        "components": components,
        "managed_system": managed_system,
        "probes": [
            {
                "topic": topic,
                "signals": {
                    key: {k: v for k, v in spec.items() if k in ("type", "min", "max")}
                    for key, spec in model.messages[message].fields.items()
                },
            }
            for topic, message in probes(model).items()
            if message in model.messages
        ],
        "effectors": {
            e.name: {
                "topic": e.topic,
                **({"modes": list(e.modes)} if e.modes is not None else {}),
                "fields": {k: v["type"] for k, v in model.messages[e.message].fields.items()},
            }
            for e in effectors(model)
            if e.message in model.messages
        },
        "properties": [c.file for c in model.checks if c.kind == "properties"],
        "rules": [c.file for c in model.checks if c.kind == "rules"],
        "transport": "local",
        "knowledge": interface.get("knowledge", "sqlite"),
        "duration": interface.get("duration", 60),
        "loop": interface.get("loop", {"period": 1.0}),
    }
    trust = {}
    if model.mode_signal:
        trust["mode_signal"] = model.mode_signal
    if model.veto_properties:
        trust["veto_properties"] = list(model.veto_properties)
    if trust:
        config["trustworthiness"] = trust
    if not config["probes"]:
        del config["probes"]
    if not config["effectors"]:
        del config["effectors"]
    return config


def _message_name(text: str) -> str:
    words = [w for w in "".join(c if c.isalnum() else " " for c in text).split() if w]
    return "".join(w[:1].upper() + w[1:] for w in words) or "Message"


def model_from_manifest(manifest: Any) -> ArchitectureModel:
    """A minimal model of an app that has no ``model.yaml``: its five stages, one managed
    system publishing the probes and receiving the effectors' actions, all on this machine."""
    unit = ComputeUnit("local", host_arch(), ("local", "mqtt"), os="linux")
    messages: dict[str, Message] = {}
    components: dict[str, Component] = {}
    links: list[Link] = []
    managed_ports: dict[str, Port] = {}
    monitor_ports: dict[str, Port] = {}
    execute_ports: dict[str, Port] = {}
    for i, probe in enumerate(manifest.probes):
        name = _message_name(probe.topic)
        fields = {
            key: {
                k: v
                for k, v in (("type", s.type), ("min", s.minimum), ("max", s.maximum))
                if v is not None
            }
            for key, s in probe.signals.items()
        }
        messages[name] = Message(name, fields)
        port = f"probe{i}"
        managed_ports[port] = Port("managed_system", port, "out", name)
        monitor_ports[port] = Port("monitor", port, "in", name)
        links.append(Link(probe.topic, f"managed_system.{port}", (f"monitor.{port}",)))
    for name, effector in manifest.effectors.items():
        message = _message_name(f"{name} command")
        fields = {k: {"type": v} for k, v in effector.fields.items()} or {
            "payload": {"type": "json"}
        }
        messages[message] = Message(message, fields)
        port = _safe(name)
        managed_ports[port] = Port("managed_system", port, "in", message)
        execute_ports[port] = Port("execute", port, "out", message)
        links.append(Link(effector.topic, f"execute.{port}", (f"managed_system.{port}",)))
    for stage, ref in manifest.components.items():
        ports = monitor_ports if stage == "monitor" else execute_ports if stage == "execute" else {}
        produces = manifest.produces.get(stage, {})
        components[stage] = Component(stage, stage, dict(ports), dict(produces), description=ref)
    components["managed_system"] = Component(
        "managed_system", "managed", managed_ports, description=manifest.simulator or ""
    )
    checks = [Check("properties", _rel(p, manifest.folder), "local") for p in manifest.properties]
    checks += [Check("rules", _rel(p, manifest.folder), "local") for p in manifest.rules]
    return ArchitectureModel(
        name=manifest.name,
        file=manifest.folder / "model.yaml",
        description=manifest.description,
        messages=messages,
        components=components,
        units={"local": unit},
        deployment={name: "local" for name in components},
        links=links,
        checks=checks,
        veto_properties=tuple(manifest.veto_properties),
        mode_signal=manifest.mode_signal,
        interface={
            "transport": manifest.transport,
            "knowledge": manifest.knowledge,
            "duration": manifest.duration,
            "loop": {
                "period": manifest.period,
                "stage_budget": manifest.stage_budget,
                "max_replans": manifest.max_replans,
            },
        },
    )


def _safe(name: str) -> str:
    cleaned = "".join(c if c.isalnum() else "_" for c in name.lower()).strip("_")
    return cleaned if cleaned[:1].isalpha() else f"port_{cleaned}"


def _rel(path: Path, folder: Path) -> str:
    try:
        return str(Path(path).resolve().relative_to(Path(folder).resolve()))
    except ValueError:
        return str(path)
