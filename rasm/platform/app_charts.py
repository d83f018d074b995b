"""The checks of the statecharts an app brings: its modes chart, its stage charts, and its
replacements for platform charts.

Each is a chart file in the app folder. Besides being a valid chart (:func:`rasm.statechart.
load_statechart`), it must fit the place the manifest gives it:

* **a replacement** for a platform chart (``statecharts: {adaptation_orchestrator: my.yaml}``)
  must honour that chart's interface (``statecharts/interfaces.json``): have every state the
  platform does work in, a transition on every event the platform sends it, and send every
  event the platform listens for. A renamed stage state would otherwise run nothing, silently;
* **a stage chart** must react to its stage's request and send only outcomes its stage allows
  (:data:`rasm.platform.chart_stages.STAGE_OUTCOMES`);
* **the modes chart**: the effectors' ``modes:`` must name its states.

``rasm lint`` reports these problems with the app's others; ``rasm run`` refuses to start on them.
"""

from __future__ import annotations

import ast
import functools
import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rasm.errors import Location, SourceError, SourceErrors, closest, marked_error, read_utf8
from rasm.platform.chart_stages import STAGE_OUTCOMES
from rasm.platform.manifest import AppManifest, is_chart_ref, manifest_location
from rasm.platform.modes import mode_signals
from rasm.resources import data_dir
from rasm.yamltext import YamlSource, load_yaml

__all__ = [
    "ChartOutline",
    "app_chart_problems",
    "check_charts",
    "interface_of",
    "interface_problems",
    "outline",
    "platform_chart_names",
    "stage_chart_problems",
]


@dataclass
class ChartOutline:
    """Where a chart's states are, the events its transitions take, and the events its code
    sends (``send('name', ...)`` with the name written out)."""

    file: str
    root: str = ""
    root_location: Location | None = None
    states: dict[str, Location] = field(default_factory=dict)
    parents: dict[str, str] = field(default_factory=dict)
    receives: dict[str, Location] = field(default_factory=dict)
    # event -> the states with a transition on it
    takers: dict[str, set[str]] = field(default_factory=dict)
    sends: dict[str, list[Location]] = field(default_factory=dict)
    # the effectors written out in send('action', effector='name', ...), with places
    effectors: list[tuple[str, Location]] = field(default_factory=list)

    def takes(self, event: str, state: str) -> bool:
        """Whether a transition on ``event`` leaves ``state`` or one of its ancestors."""
        sources = self.takers.get(event, set())
        while state:
            if state in sources:
                return True
            state = self.parents.get(state, "")
        return False

    @property
    def start(self) -> Location:
        return self.root_location or Location(self.file, 1, 1)


def outline(path: str | Path) -> ChartOutline:
    """The outline of the chart file ``path`` (one :func:`rasm.statechart.load_statechart`
    accepts; a file it refuses gives what could be read)."""
    text = read_utf8(path)
    src = load_yaml(text, str(path))
    found = ChartOutline(str(path))
    chart = src.data.get("statechart") if isinstance(src.data, dict) else None
    if not isinstance(chart, dict):
        return found
    if isinstance(chart.get("preamble"), str):
        _sends(src, chart, "preamble", found)
    root = chart.get("root state")
    if isinstance(root, dict):
        found.root = str(root.get("name", ""))
        found.root_location = src.node(root)
        _walk(src, root, found)
    return found


def _walk(src: YamlSource, state: dict[str, Any], found: ChartOutline) -> None:
    name = str(state.get("name", ""))
    if "name" in state:
        found.states.setdefault(name, src.value(state, "name"))
    for key in ("on entry", "on exit"):
        if isinstance(state.get(key), str):
            _sends(src, state, key, found)
    for transition in state.get("transitions") or []:
        if not isinstance(transition, dict):
            continue
        if "event" in transition:
            event = str(transition["event"])
            found.receives.setdefault(event, src.value(transition, "event"))
            found.takers.setdefault(event, set()).add(name)
        if isinstance(transition.get("action"), str):
            _sends(src, transition, "action", found)
    for key in ("states", "parallel states"):
        for child in state.get(key) or []:
            if isinstance(child, dict):
                if "name" in child:
                    found.parents.setdefault(str(child["name"]), name)
                _walk(src, child, found)


def _sends(src: YamlSource, mapping: Any, key: str, found: ChartOutline) -> None:
    """The events ``send('name', ...)`` in the code at ``mapping[key]`` names, with places."""
    try:
        tree = ast.parse(str(mapping[key]))
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return  # the chart check reports it
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id == "send"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            where = src.code_location(mapping, key, node.lineno, node.col_offset + 1)
            found.sends.setdefault(node.args[0].value, []).append(where)
            for keyword in node.keywords:
                value = keyword.value
                if (
                    node.args[0].value == "action"
                    and keyword.arg == "effector"
                    and isinstance(value, ast.Constant)
                    and isinstance(value.value, str)
                ):
                    place = src.code_location(mapping, key, value.lineno, value.col_offset + 1)
                    found.effectors.append((value.value, place))


# --------------------------------------------------------------------------- interfaces


@functools.cache
def _interfaces() -> dict[str, Any]:
    return json.loads((data_dir("statecharts") / "interfaces.json").read_text(encoding="utf-8"))


def interface_of(name: str) -> dict[str, Any]:
    """What the platform relies on in its chart ``name``, the lifecycle's included: ``states``
    (a list), ``receives`` (event -> the states it must be taken in; empty: anywhere) and
    ``sends`` (a list). KeyError for a name that is no platform chart."""
    interfaces = _interfaces()
    own = interfaces[name]
    common = interfaces["lifecycle"]
    return {
        "states": [*common["states"], *own["states"]],
        "receives": {**common["receives"], **own["receives"]},
        "sends": [*common["sends"], *own["sends"]],
    }


def platform_chart_names() -> list[str]:
    """The platform charts with a declared interface: the names ``statecharts:`` may replace."""
    return sorted(key for key in _interfaces() if key not in ("description", "lifecycle"))


def interface_problems(name: str, path: str | Path) -> list[SourceError]:
    """How the chart file ``path`` fails to honour the interface of platform chart ``name``."""
    interface = interface_of(name)
    found = outline(path)
    problems = []
    for state in interface["states"]:
        if state not in found.states:
            problems.append(marked_error(
                f"this replacement for the platform's {name} chart has no state '{state}': the "
                f"platform relies on it (its {name} chart's interface: states "
                f"{', '.join(interface['states'])})",
                found.start,
            ))
    for event, states in interface["receives"].items():
        if event not in found.receives:
            problems.append(marked_error(
                f"this replacement for the platform's {name} chart has no transition on "
                f"'{event}': the platform sends it that event, which would be ignored",
                found.start,
            ))
            continue
        for state in states:
            if state in found.states and not found.takes(event, state):
                problems.append(marked_error(
                    f"no transition on '{event}' leaves state '{state}' (nor a state around "
                    f"it): the platform sends '{event}' to its {name} chart in '{state}', "
                    "where it would be ignored",
                    found.states[state],
                    len(state),
                ))
    for event in interface["sends"]:
        if event not in found.sends:
            problems.append(marked_error(
                f"this replacement for the platform's {name} chart never sends '{event}': "
                f"the platform listens for it (write send('{event}') where it happens)",
                found.start,
            ))
    return problems


# --------------------------------------------------------------------------- stage charts


def stage_chart_problems(stage: str, path: str | Path) -> list[SourceError]:
    """How the chart file ``path`` cannot answer for MAPLE-K stage ``stage``: it does not react
    to the stage's request (an event named after the stage), never sends an outcome, or sends
    an event that is neither an outcome of its stage nor one it takes itself."""
    allowed = STAGE_OUTCOMES[stage]
    found = outline(path)
    problems = []
    if stage not in found.receives:
        problems.append(marked_error(
            f"a chart for the {stage} stage needs a transition on the event '{stage}': the "
            "platform sends it once per iteration, and the chart answers it",
            found.start,
        ))
    if not set(allowed) & set(found.sends):
        problems.append(marked_error(
            f"this chart for the {stage} stage never sends an outcome: it answers "
            f"'{stage}' with send() of {_either(allowed)}",
            found.start,
        ))
    for event, places in sorted(found.sends.items(), key=lambda e: e[1][0].line):
        if event in allowed or (event in found.receives and event not in _ALL_OUTCOMES):
            continue
        others = [s for s, outcomes in STAGE_OUTCOMES.items() if event in outcomes]
        why = f"the {others[0]} stage's outcome, not" if others else "not"
        for where in places:
            problems.append(marked_error(
                f"'{event}' is {why} an outcome of the {stage} stage (it answers with "
                f"{_either(allowed)})",
                where,
                len(event) + 2,
            ))
    return problems


_ALL_OUTCOMES = frozenset(o for outcomes in STAGE_OUTCOMES.values() for o in outcomes)


def _either(names: tuple[str, ...]) -> str:
    quoted = [f"'{n}'" for n in names]
    return quoted[0] if len(quoted) == 1 else f"{', '.join(quoted[:-1])} or {quoted[-1]}"


# --------------------------------------------------------------------------- an app's charts


def app_chart_problems(manifest: AppManifest) -> list[SourceError]:
    """Every problem of the charts ``manifest`` names (modes, stages, replacements)."""
    problems: list[SourceError] = []
    modes = _loaded(manifest.modes, problems) if manifest.modes is not None else None
    if modes is not None:
        problems += list(_effector_mode_problems(manifest, set(modes.states)))
        problems += list(_mode_signal_clashes(manifest, mode_signals(modes)))
        if manifest.mode_signal is not None:
            problems.append(SourceError(
                "the managed system's modes are its modes chart (managed_system.modes): leave "
                "out trustworthiness.mode_signal",
                manifest_location(manifest, ["trustworthiness", "mode_signal"]),
            ))
    for stage, ref in manifest.components.items():
        if is_chart_ref(ref) and stage in STAGE_OUTCOMES:
            path = manifest.folder / ref
            if _loaded(path, problems) is not None:
                problems += stage_chart_problems(stage, path)
                if stage == "execute":
                    problems += _unknown_effectors(manifest, path)
    known = platform_chart_names()
    for name, path in manifest.statecharts.items():
        if name not in known:
            problems.append(SourceError(
                f"statecharts: '{name}' is not a platform chart (one of: {', '.join(known)})",
                manifest_location(manifest, ["statecharts", name]),
            ))
        elif _loaded(path, problems) is not None:
            problems += interface_problems(name, path)
    return problems


def check_charts(manifest: AppManifest) -> None:
    """Raise :class:`SourceErrors` with :func:`app_chart_problems`, if there are any."""
    problems = app_chart_problems(manifest)
    if problems:
        raise SourceErrors(problems)


def _loaded(path: Path, problems: list[SourceError]) -> Any:
    from rasm.statechart import load_statechart

    if not path.is_file():
        return None  # the manifest reports the missing file
    try:
        return load_statechart(path)
    except SourceErrors as exc:
        problems.extend(exc.errors)
    except SourceError as exc:
        problems.append(exc)
    return None


def _effector_mode_problems(manifest: AppManifest, states: set[str]) -> Iterator[SourceError]:

    for name, effector in manifest.effectors.items():
        for i, mode in enumerate(effector.modes or ()):
            if mode not in states:
                message = f"effector {name}: '{mode}' is not a state of the modes chart"
                suggestion = closest(mode, states)
                if suggestion is not None:
                    message += f": did you mean '{suggestion}'?"
                yield SourceError(
                    message, manifest_location(manifest, ["effectors", name, "modes", i])
                )


def _unknown_effectors(manifest: AppManifest, path: Path) -> list[SourceError]:
    """An Execute chart's actions for an effector the app does not declare would all be
    dropped."""

    problems = []
    for name, where in outline(path).effectors:
        if name not in manifest.effectors:
            message = f"effector '{name}' is not an effector of the app"
            suggestion = closest(name, manifest.effectors)
            if suggestion is not None:
                message += f": did you mean '{suggestion}'?"
            problems.append(marked_error(message, where, len(name) + 2))
    return problems


def _mode_signal_clashes(manifest: AppManifest, written: dict[str, str]) -> Iterator[SourceError]:
    """A probe or Monitor signal named like a key the modes chart writes would mix two
    sources in one knowledge key and one trace key."""
    for i, probe in enumerate(manifest.probes):
        for key in probe.signals:
            if key in written:
                yield SourceError(
                    f"signal '{key}': the modes chart writes it (mode, mode_<state>); give the "
                    "signal another name",
                    manifest_location(manifest, ["probes", i, "signals", key]),
                )
    for key in manifest.produces.get("monitor", {}):
        if key in written:
            yield SourceError(
                f"signal '{key}': the modes chart writes it (mode, mode_<state>); give the "
                "signal another name",
                manifest_location(manifest, [*manifest.component_path("monitor")[:-1],
                                             "produces", key]),
            )
