"""Which property statecharts (``monitors/*.yaml``) apply to a chart.

A property statechart watches another chart through meta-events, and its guards name the states
it watches: ``event.state == 'executing'``, or ``event.state in STAGES`` with ``STAGES`` a tuple
(or the keys of a dict) of names in its preamble. Those names are its **watched states**. A
monitor *applies* to a chart when it watches at least one state and **every** state it watches
exists in the chart: a monitor of the orchestrator applies to the orchestrator (and to a copy or
variant that keeps its stage names), not to a chart that merely shares one name such as ``idle``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

from sismic.model import Statechart

from rasm.resources import platform_monitors
from rasm.statechart import load_statechart

__all__ = ["watched_states", "applicable_monitors", "state_names"]


def state_names(chart: Statechart) -> set[str]:
    """Every state name of ``chart``."""
    return set(chart.states)


def _strings(node: ast.AST) -> set[str] | None:
    """The strings of a literal str / tuple / list / set / dict (its keys), or None."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return {node.value}
    if isinstance(node, ast.Tuple | ast.List | ast.Set):
        items = [_strings(e) for e in node.elts]
        return set().union(*items) if all(i is not None for i in items) else None
    if isinstance(node, ast.Dict):
        keys = [_strings(k) for k in node.keys if k is not None]
        return set().union(*keys) if all(k is not None for k in keys) else None
    return None


def _preamble_names(code: str | None) -> dict[str, set[str]]:
    names: dict[str, set[str]] = {}
    if not code:
        return names
    try:
        tree = ast.parse(code)
    except SyntaxError:
        return names
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign):
            found = _strings(node.value)
            if found is not None:
                for target in node.targets:
                    if isinstance(target, ast.Name):
                        names[target.id] = found
    return names


def _is_event_state(node: ast.AST) -> bool:
    return (
        isinstance(node, ast.Attribute)
        and node.attr == "state"
        and isinstance(node.value, ast.Name)
        and node.value.id == "event"
    )


def watched_states(monitor: Statechart) -> set[str]:
    """The state names a property statechart compares ``event.state`` with."""
    constants = _preamble_names(getattr(monitor, "preamble", None))
    watched: set[str] = set()
    for transition in monitor.transitions:
        guard = transition.guard
        if not guard:
            continue
        try:
            tree = ast.parse(guard.strip(), mode="eval")
        except SyntaxError:
            continue
        for node in ast.walk(tree):
            if not isinstance(node, ast.Compare):
                continue
            sides = [node.left, *node.comparators]
            if not any(_is_event_state(side) for side in sides):
                continue
            for side in sides:
                if isinstance(side, ast.Name) and side.id in constants:
                    watched |= constants[side.id]
                else:
                    watched |= _strings(side) or set()
    return watched


def applicable_monitors(
    chart: Statechart, candidates: Iterable[str | Path | Statechart] | None = None
) -> list[Statechart]:
    """The monitors among ``candidates`` (default: the platform's) that apply to ``chart``."""
    names = state_names(chart)
    out = []
    for candidate in platform_monitors() if candidates is None else candidates:
        monitor = candidate if isinstance(candidate, Statechart) else load_statechart(candidate)
        watched = watched_states(monitor)
        if watched and watched <= names:
            out.append(monitor)
    return out
