"""Hypothesis strategies for valid architecture models (as the YAML text an architect writes)."""

from __future__ import annotations

import io
from typing import Any

from hypothesis import strategies as st
from ruamel.yaml import YAML

from rasm.loop import STAGES

# free text with quotes, backslashes and line breaks: it ends up in docstrings and YAML
DESCRIPTIONS = st.text(
    st.characters(codec="utf-8", exclude_categories=("Cc", "Cs"), include_characters="\n"),
    max_size=150,
)


@st.composite
def fields(draw: st.DrawFn, prefix: str) -> dict[str, Any]:
    count = draw(st.integers(1, 3))
    out: dict[str, Any] = {}
    for i in range(count):
        kind = draw(st.sampled_from(["float", "int", "bool", "str"]))
        spec: dict[str, Any] = {"type": kind}
        if kind in ("float", "int") and draw(st.booleans()):
            low = draw(st.integers(-100, 100))
            spec["min"] = low
            spec["max"] = low + draw(st.integers(0, 100))
        out[f"{prefix}_f{i}"] = spec
    return out


@st.composite
def models(draw: st.DrawFn, name: str = "gen") -> dict[str, Any]:
    """A valid model: managed components wired to the monitor and from execute, a loop on one
    unit, managed components spread over units that reach it, checks on the loop's unit."""
    unit_count = draw(st.integers(1, 3))
    units = [f"u{i}" for i in range(unit_count)]
    loop_unit = draw(st.sampled_from(units))
    unit_specs = {
        u: {
            "arch": draw(st.sampled_from(["amd64", "arm64"])),
            "os": "linux",
            "cpus": draw(st.integers(1, 8)),
            "memory_mb": draw(st.integers(64, 8192)),
            "transports": ["local", "mqtt"] if u == loop_unit or draw(st.booleans()) else ["mqtt"],
        }
        for u in units
    }
    stage_names = {s: draw(st.sampled_from([s, f"{s}_x"])) for s in STAGES}
    components: dict[str, Any] = {stage_names[s]: {"role": s} for s in STAGES}
    for stage in components.values():  # any mix of Python and statechart stages
        implementation = draw(st.sampled_from([None, "python", "statechart"]))
        if implementation is not None:
            stage["implementation"] = implementation
    # the managed system's modes chart, carried by its first component, or none
    states = draw(st.sampled_from([None, ["nominal"], ["nominal", "degraded", "halted"]]))
    deployment = {stage_names[s]: loop_unit for s in STAGES}
    messages: dict[str, Any] = {}
    links: list[dict[str, Any]] = []
    monitor, execute = components[stage_names["monitor"]], components[stage_names["execute"]]
    produced: list[tuple[str, str]] = []
    for i in range(draw(st.integers(1, 3))):
        role = draw(st.sampled_from(["probe", "effector", "managed"]))
        comp = f"thing{i}"
        unit = draw(st.sampled_from(units))
        ports: dict[str, Any] = {}
        if role in ("probe", "managed"):
            msg = f"Reading{i}"
            messages[msg] = {"fields": draw(fields(f"r{i}"))}
            produced += [(k, v["type"]) for k, v in messages[msg]["fields"].items()]
            ports["out"] = {"direction": "out", "message": msg}
            monitor.setdefault("ports", {})[f"in{i}"] = {"direction": "in", "message": msg}
            links.append(
                _link(
                    f"{name}/r{i}",
                    f"{comp}.out",
                    f"{stage_names['monitor']}.in{i}",
                    unit,
                    loop_unit,
                    unit_specs,
                    draw,
                )
            )
        if role in ("effector", "managed"):
            msg = f"Command{i}"
            messages[msg] = {"fields": draw(fields(f"c{i}"))}
            ports["cmd"] = {"direction": "in", "message": msg}
            if states is not None and draw(st.booleans()):
                ports["cmd"]["modes"] = draw(st.lists(st.sampled_from(states), min_size=1,
                                                      max_size=len(states), unique=True))
            execute.setdefault("ports", {})[f"out{i}"] = {"direction": "out", "message": msg}
            links.append(
                _link(
                    f"{name}/c{i}",
                    f"{stage_names['execute']}.out{i}",
                    f"{comp}.cmd",
                    loop_unit,
                    unit,
                    unit_specs,
                    draw,
                )
            )
        components[comp] = {"role": role, "ports": ports, "description": draw(DESCRIPTIONS)}
        if i == 0 and states is not None:
            components[comp]["modes"] = {"states": states, "description": draw(DESCRIPTIONS)}
        deployment[comp] = unit
    trust: dict[str, Any] = {
        "properties": [{"file": f"properties/{name}.rv", "runs_on": loop_unit}],
        "rules": [{"file": f"rules/{name}.yaml", "runs_on": loop_unit}],
    }
    numeric = [(k, t) for k, t in produced if t in ("float", "int")]
    if numeric and draw(st.booleans()):
        signal = draw(st.sampled_from(numeric))[0]
        trust["properties"].append(
            {
                "file": "properties/extra.rv",
                "runs_on": loop_unit,
                "text": f"input {signal}: float\n"
                f"property finite:\n    always (abs({signal}) >= 0)\n",
            }
        )
    crossing = any(unit != loop_unit for unit in deployment.values())
    return {
        "architecture": name,
        "description": "generated by hypothesis",
        "messages": messages,
        "components": components,
        "compute_units": unit_specs,
        "deployment": deployment,
        "communication": links,
        "trustworthiness": trust,
        "interface": {
            "transport": "mqtt://localhost:1883" if crossing else "local",
            "knowledge": "memory",
            "loop": {"period": draw(st.sampled_from([0.2, 0.5, 1.0]))},
        },
    }


def _link(
    topic: str,
    publisher: str,
    subscriber: str,
    a: str,
    b: str,
    units: dict[str, Any],
    draw: st.DrawFn,
) -> dict[str, Any]:
    common = set(units[a]["transports"]) & set(units[b]["transports"])
    if a != b:
        common.discard("local")
    return {
        "topic": topic,
        "publisher": publisher,
        "subscribers": [subscriber],
        "protocol": draw(st.sampled_from(sorted(common))),
        "qos": draw(st.sampled_from([0, 1, 2])),
        "rate": draw(st.sampled_from([1, 5, 10])),
    }


def dump(model: dict[str, Any]) -> str:
    yaml = YAML()
    out = io.StringIO()
    yaml.dump(model, out)
    return out.getvalue()
