"""Draw a chart as Mermaid, PlantUML or Graphviz dot text.

States get generated identifiers (``s0``, ``s1``, …) and keep their names as labels, so any state
name, however written, yields valid diagram source.
"""

from __future__ import annotations

from sismic.io import export_to_plantuml
from sismic.model import (
    CompoundState,
    DeepHistoryState,
    FinalState,
    OrthogonalState,
    ShallowHistoryState,
    Statechart,
    Transition,
)

__all__ = ["FORMATS", "export"]

FORMATS = ("mermaid", "plantuml", "dot")


def _label(transition: Transition) -> str:
    parts = []
    if transition.event:
        parts.append(transition.event)
    if transition.guard:
        parts.append(f"[{' '.join(transition.guard.split())}]")
    return " ".join(parts)


def _ids(statechart: Statechart) -> dict[str, str]:
    order: list[str] = []
    todo = [statechart.root]
    while todo:
        name = todo.pop(0)
        order.append(name)
        todo[0:0] = statechart.children_for(name)
    return {name: f"s{i}" for i, name in enumerate(order)}


def _mermaid_text(text: str) -> str:
    # Mermaid reads ':' and ';' as syntax inside labels; its entity codes keep them visible.
    return text.replace(";", "#59;").replace(":", "#58;").replace('"', "#quot;")


def to_mermaid(statechart: Statechart) -> str:
    ids = _ids(statechart)
    lines = ["stateDiagram-v2"]

    def state_block(name: str, indent: str) -> None:
        state = statechart.state_for(name)
        sid = ids[name]
        label = name
        if isinstance(state, ShallowHistoryState):
            label = f"{name} (H)"
        elif isinstance(state, DeepHistoryState):
            label = f"{name} (H*)"
        lines.append(f'{indent}state "{_mermaid_text(label)}" as {sid}')
        children = statechart.children_for(name)
        if isinstance(state, CompoundState | OrthogonalState) and children:
            lines.append(f"{indent}state {sid} {{")
            if isinstance(state, CompoundState):
                for child in children:
                    state_block(child, indent + "    ")
                if state.initial:
                    lines.append(f"{indent}    [*] --> {ids[state.initial]}")
            else:
                for i, child in enumerate(sorted(children)):
                    if i:
                        lines.append(f"{indent}    --")
                    state_block(child, indent + "    ")
            lines.append(f"{indent}}}")
        if isinstance(state, FinalState):
            lines.append(f"{indent}{sid} --> [*]")

    state_block(statechart.root, "    ")
    lines.append(f"    [*] --> {ids[statechart.root]}")
    for transition in statechart.transitions:
        target = transition.target or transition.source
        label = _label(transition)
        suffix = f" : {_mermaid_text(label)}" if label else ""
        lines.append(f"    {ids[transition.source]} --> {ids[target]}{suffix}")
    return "\n".join(lines) + "\n"


def _dot_text(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"')


def to_dot(statechart: Statechart) -> str:
    ids = _ids(statechart)
    lines = [
        f'digraph "{_dot_text(statechart.name)}" {{',
        "    compound=true;",
        '    node [shape=box, style=rounded, fontname="Helvetica"];',
        '    edge [fontname="Helvetica", fontsize=10];',
    ]

    def state_block(name: str, indent: str) -> None:
        state = statechart.state_for(name)
        sid = ids[name]
        children = statechart.children_for(name)
        if children:
            lines.append(f"{indent}subgraph cluster_{sid} {{")
            style = "dashed" if isinstance(state, OrthogonalState) else "rounded"
            lines.append(f'{indent}    label="{_dot_text(name)}"; style={style};')
            lines.append(f'{indent}    {sid}_anchor [shape=point, style=invis, label=""];')
            if isinstance(state, CompoundState) and state.initial:
                lines.append(f'{indent}    {sid}_init [shape=point, label=""];')
                lines.append(
                    f"{indent}    {sid}_init -> {_node(state.initial)}{_lhead(state.initial)};"
                )
            for child in children:
                state_block(child, indent + "    ")
            lines.append(f"{indent}}}")
        elif isinstance(state, FinalState):
            lines.append(f'{indent}{sid} [label="{_dot_text(name)}", shape=doublecircle];')
        elif isinstance(state, ShallowHistoryState | DeepHistoryState):
            mark = "H*" if isinstance(state, DeepHistoryState) else "H"
            lines.append(f'{indent}{sid} [label="{mark}", shape=circle];')
        else:
            lines.append(f'{indent}{sid} [label="{_dot_text(name)}"];')

    def _node(name: str) -> str:
        return f"{ids[name]}_anchor" if statechart.children_for(name) else ids[name]

    def _lhead(name: str) -> str:
        return f", lhead=cluster_{ids[name]}" if statechart.children_for(name) else ""

    state_block(statechart.root, "    ")
    for transition in statechart.transitions:
        target = transition.target or transition.source
        attrs = [f'label="{_dot_text(_label(transition))}"']
        if statechart.children_for(transition.source):
            attrs.append(f"ltail=cluster_{ids[transition.source]}")
        if statechart.children_for(target):
            attrs.append(f"lhead=cluster_{ids[target]}")
        if transition.target is None:
            attrs.append("style=dotted")
        lines.append(f"    {_node(transition.source)} -> {_node(target)} [{', '.join(attrs)}];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def export(statechart: Statechart, fmt: str) -> str:
    """The chart as diagram source in ``fmt`` (one of :data:`FORMATS`)."""
    if fmt == "mermaid":
        return to_mermaid(statechart)
    if fmt == "plantuml":
        text = export_to_plantuml(statechart)
        return text if text.endswith("\n") else text + "\n"
    if fmt == "dot":
        return to_dot(statechart)
    raise ValueError(f"unknown format {fmt!r}; expected one of {', '.join(FORMATS)}")
