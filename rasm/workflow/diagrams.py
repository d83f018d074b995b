"""Mermaid diagrams of a model: logical architecture, physical architecture, deployment.

Plain functions from an :class:`~rasm.workflow.model.ArchitectureModel` to Mermaid text, used by
the package's ``00_Documentation``; they render on GitHub, GitLab and most Markdown viewers.
"""

from __future__ import annotations

from typing import Any

from rasm.loop import STAGES
from rasm.workflow.model import ArchitectureModel

__all__ = ["deployment_diagram", "logical_diagram", "model_to_dict", "physical_diagram"]


def _id(name: str) -> str:
    return "n_" + "".join(c if c.isalnum() else "_" for c in name)


def _label(text: str) -> str:
    return text.replace('"', "'")


def logical_diagram(model: ArchitectureModel) -> str:
    """Components grouped into the managing (MAPLE-K) and managed systems; edges are topics."""
    lines = ["flowchart LR"]
    managing = [c for c in model.components.values() if c.role in STAGES]
    managed = [c for c in model.components.values() if c.role not in STAGES]
    for title, group in (("managing system (MAPLE-K)", managing), ("managed system", managed)):
        if not group:
            continue
        lines.append(f'  subgraph {_id(title)}["{title}"]')
        for c in group:
            lines.append(f'    {_id(c.name)}["{_label(c.name)}<br/><i>{c.role}</i>"]')
        lines.append("  end")
    order = [c.name for s in STAGES for c in managing if c.role == s]
    for a, b in zip(order, order[1:], strict=False):
        lines.append(f"  {_id(a)} -.->|knowledge| {_id(b)}")
    for link in model.links:
        pub = link.publisher.partition(".")[0]
        port = model.port(link.publisher)
        label = _label(f"{link.topic}: {port.message}" if port else link.topic)
        for ref in link.subscribers:
            lines.append(f'  {_id(pub)} -->|"{label}"| {_id(ref.partition(".")[0])}')
    return "\n".join(lines) + "\n"


def physical_diagram(model: ArchitectureModel) -> str:
    """Compute units and the transports that connect them."""
    lines = ["flowchart LR"]
    for unit in model.units.values():
        resources = ", ".join(
            part
            for part in (
                f"{unit.cpus} CPU" if unit.cpus else "",
                f"{unit.memory_mb} MB" if unit.memory_mb else "",
            )
            if part
        )
        detail = f"{unit.arch}, {unit.os}" + (f", {resources}" if resources else "")
        lines.append(f'  {_id(unit.name)}[("{unit.name}<br/>{detail}")]')
    pairs: dict[tuple[str, str], set[str]] = {}
    for link in model.links:
        a = model.deployment.get(link.publisher.partition(".")[0])
        for ref in link.subscribers:
            b = model.deployment.get(ref.partition(".")[0])
            if a and b and a != b and a in model.units and b in model.units:
                pairs.setdefault(tuple(sorted((a, b))), set()).add(link.protocol)  # type: ignore[arg-type]
    for (a, b), protocols in sorted(pairs.items()):
        lines.append(f'  {_id(a)} <-->|"{", ".join(sorted(protocols))}"| {_id(b)}')
    return "\n".join(lines) + "\n"


def deployment_diagram(model: ArchitectureModel) -> str:
    """Each compute unit as a box holding the components deployed on it."""
    lines = ["flowchart TB"]
    for unit in model.units.values():
        lines.append(f'  subgraph {_id("unit_" + unit.name)}["{unit.name} ({unit.arch})"]')
        for c in model.components_on(unit.name):
            lines.append(f'    {_id(c.name)}["{_label(c.name)}<br/><i>{c.role}</i>"]')
        for check in model.checks:
            if check.runs_on == unit.name:
                lines.append(f'    {_id("check_" + check.file)}{{{{"{_label(check.file)}"}}}}')
        lines.append("  end")
    return "\n".join(lines) + "\n"


def model_to_dict(model: ArchitectureModel) -> dict[str, Any]:
    """The model as plain data in the ``model.yaml`` shape (for a derived model, its only form)."""
    if model.raw:
        return model.raw
    out: dict[str, Any] = {"architecture": model.name}
    if model.description:
        out["description"] = model.description
    out["messages"] = {m.name: {"fields": m.fields} for m in model.messages.values()}
    out["components"] = {
        c.name: {
            "role": c.role,
            **({"description": c.description} if c.description else {}),
            **(
                {
                    "ports": {
                        p.name: {"direction": p.direction, "message": p.message}
                        for p in c.ports.values()
                    }
                }
                if c.ports
                else {}
            ),
        }
        for c in model.components.values()
    }
    out["compute_units"] = {
        u.name: {"arch": u.arch, "os": u.os, "transports": list(u.transports)}
        for u in model.units.values()
    }
    out["deployment"] = dict(model.deployment)
    out["communication"] = [
        {
            "topic": link.topic,
            "publisher": link.publisher,
            "subscribers": list(link.subscribers),
            "protocol": link.protocol,
            "qos": link.qos,
        }
        for link in model.links
    ]
    trust: dict[str, Any] = {}
    for kind in ("properties", "rules"):
        entries = [{"file": c.file, "runs_on": c.runs_on} for c in model.checks if c.kind == kind]
        if entries:
            trust[kind] = entries
    if model.mode_signal:
        trust["mode_signal"] = model.mode_signal
    if trust:
        out["trustworthiness"] = trust
    out["interface"] = dict(model.interface)
    return out
