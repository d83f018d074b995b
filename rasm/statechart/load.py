"""Load a statechart from sismic's YAML format, with the validation sismic does not do.

sismic's own checks are shallow: a schema failure says only "mapping validation failed",
YAML errors escape raw, code with syntax errors loads and fails on first use, a compound state
without ``initial`` loads and then sits with no active child. Here every such problem is found at
load time and reported as ``file:line:col: message`` from the YAML node's position.

Problems come in two severities: *errors* stop loading (the chart cannot run as written) and
*warnings* (unreachable states) are reported by ``rasm lint`` but do not stop a simulation of a
chart under construction.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sismic.exceptions import StatechartError as SismicStatechartError
from sismic.io.datadict import import_from_dict
from sismic.model import Statechart

from rasm.errors import Location, SourceError, SourceErrors, not_utf8
from rasm.yamltext import YamlSource, load_yaml, plain

__all__ = ["ChartProblem", "load_statechart", "check_statechart", "source_of"]

STATECHART_KEYS = {"name", "description", "preamble", "root state"}
STATE_KEYS = {
    "name",
    "type",
    "on entry",
    "on exit",
    "transitions",
    "contract",
    "initial",
    "parallel states",
    "states",
    "memory",
    "description",
}
TRANSITION_KEYS = {"target", "event", "guard", "action", "contract", "priority", "description"}
STATE_TYPES = {"final", "shallow history", "deep history"}
CONTRACT_KEYS = {"before", "after", "always"}

_SOURCES: weakref.WeakKeyDictionary[Statechart, ChartSource] = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class ChartProblem:
    """One problem found in a chart; ``error`` False means a warning."""

    error: SourceError
    severity: str = "error"

    def __str__(self) -> str:
        text = str(self.error)
        return text if self.severity == "error" else text.replace(": ", ": warning: ", 1)

    def one_line(self) -> str:
        """``file:line:col: message`` without the marked excerpt (for ``rasm lint``)."""
        prefix = "" if self.severity == "error" else "warning: "
        return f"{self.error.location}: {prefix}{self.error.message}"


@dataclass
class ChartSource:
    """Where each state and transition of a loaded chart is written."""

    file: str
    states: dict[str, Location] = field(default_factory=dict)
    transitions: dict[tuple[str, int], Location] = field(default_factory=dict)
    preamble: Location | None = None


def source_of(statechart: Statechart) -> ChartSource | None:
    """Positions of a chart loaded by :func:`load_statechart`, or None."""
    return _SOURCES.get(statechart)


class _Checker:
    """Walks the YAML tree once, collecting problems and positions."""

    def __init__(self, src: YamlSource) -> None:
        self.src = src
        self.problems: list[ChartProblem] = []
        self.positions = ChartSource(src.file)
        # name -> (state mapping, parent name) for the semantic checks
        self.states: dict[str, tuple[Any, str | None]] = {}
        self.transitions: list[tuple[str, Any, int]] = []

    def error(self, message: str, location: Location, width: int = 1) -> None:
        self.problems.append(ChartProblem(self.src.error(message, location, width)))

    def warning(self, message: str, location: Location, width: int = 1) -> None:
        self.problems.append(ChartProblem(self.src.error(message, location, width), "warning"))

    # ------------------------------------------------------------------ schema

    def check_document(self) -> None:
        data = self.src.data
        if not isinstance(data, dict) or "statechart" not in data:
            self.error(
                "a statechart file is a mapping with a top-level 'statechart' key",
                self.src.node(data),
            )
            return
        for key in data:
            if key != "statechart":
                self.error(
                    f"unknown top-level key '{key}' (expected only 'statechart')",
                    self.src.key(data, key),
                    len(str(key)),
                )
        chart = data["statechart"]
        if not isinstance(chart, dict):
            self.error(
                "'statechart' must be a mapping with 'name' and 'root state'",
                self.src.value(data, "statechart"),
            )
            return
        self.unknown_keys(chart, STATECHART_KEYS, "statechart")
        if "name" not in chart:
            self.error("the statechart has no 'name'", self.src.key(data, "statechart"))
        else:
            self.scalar(chart, "name")
        for key in ("description", "preamble"):
            if key in chart:
                self.scalar(chart, key)
        if "preamble" in chart and isinstance(chart["preamble"], str):
            self.positions.preamble = self.src.value(chart, "preamble")
            self.code(chart, "preamble", "exec")
        if "root state" not in chart:
            self.error("the statechart has no 'root state'", self.src.key(data, "statechart"))
            return
        root = chart["root state"]
        if not isinstance(root, dict):
            self.error(
                "'root state' must be a mapping (a state)", self.src.value(chart, "root state")
            )
            return
        self.check_state(root, None)

    def unknown_keys(self, mapping: Any, allowed: set[str], what: str) -> None:
        for key in mapping:
            if key not in allowed:
                expected = ", ".join(sorted(allowed))
                self.error(
                    f"unknown key '{key}' in {what} (expected one of: {expected})",
                    self.src.key(mapping, key),
                    len(str(key)),
                )

    def scalar(self, mapping: Any, key: str) -> bool:
        value = mapping[key]
        if isinstance(value, dict | list) or value is None:
            found = "a list" if isinstance(value, list) else "a mapping"
            found = "nothing" if value is None else found
            self.error(
                f"'{key}' must be a single value, not {found}",
                self.src.value(mapping, key),
            )
            return False
        return True

    def code(self, mapping: Any, key: str, mode: str) -> None:
        """Compile guard/action/contract/preamble code now, so syntax errors show at load."""
        text = str(mapping[key])
        try:
            compile(text.strip() if mode == "eval" else text, f"<{key}>", mode)
        except SyntaxError as exc:
            line = exc.lineno or 1
            col = exc.offset or 1
            if mode == "eval":  # strip() removed leading blank lines and spaces
                stripped = text.lstrip()
                skipped = text[: len(text) - len(stripped)]
                line += skipped.count("\n")
                if line == 1 + skipped.count("\n"):
                    col += len(skipped.rsplit("\n", 1)[-1])
            location = self.src.code_location(mapping, key, line, col)
            what = {"eval": "expression", "exec": "code"}[mode]
            message = exc.msg
            if mode == "eval" and _needs_parentheses(text.strip()):
                message = ("the expression goes on over several lines, which Python reads "
                           "only inside parentheses: put the whole expression in ( )")
            self.error(f"invalid Python {what} in '{key}': {message}", location)
        except (ValueError, MemoryError, RecursionError):  # past the compiler's own limits
            self.error(
                f"the Python code in '{key}' is nested too deeply to compile",
                self.src.value(mapping, key),
            )

    def contracts(self, owner: Any, what: str) -> None:
        items = owner["contract"]
        if not isinstance(items, list):
            self.error(
                "'contract' must be a list of {before|after|always: condition}",
                self.src.value(owner, "contract"),
            )
            return
        for i, item in enumerate(items):
            if (
                not isinstance(item, dict)
                or len(item) != 1
                or next(iter(item)) not in CONTRACT_KEYS
            ):
                self.error(
                    f"a contract of {what} is one of 'before: …', 'after: …', 'always: …'",
                    self.src.item(items, i),
                )
                continue
            key = next(iter(item))
            if self.scalar(item, key):
                self.code(item, key, "eval")

    def check_state(self, state: Any, parent: str | None) -> None:
        self.unknown_keys(state, STATE_KEYS, "a state")
        if "name" not in state:
            self.error("a state has no 'name'", self.src.node(state))
            return
        if not self.scalar(state, "name"):
            return
        name = str(state["name"])
        location = self.src.value(state, "name")
        if name in self.states:
            first = self.positions.states[name]
            self.error(
                f"duplicate state name '{name}' (first defined at line {first.line}); "
                "state names are global in a chart",
                location,
                len(name),
            )
        else:
            self.states[name] = (state, parent)
            self.positions.states[name] = self.src.node(state)
        stype = state.get("type")
        if stype is not None and str(stype) not in STATE_TYPES:
            self.error(
                f"unknown state type '{stype}' (expected final, shallow history or deep history)",
                self.src.value(state, "type"),
                len(str(stype)),
            )
        for key in ("on entry", "on exit"):
            if key in state and self.scalar(state, key):
                self.code(state, key, "exec")
        if "contract" in state:
            self.contracts(state, f"state '{name}'")
        has_children = [k for k in ("states", "parallel states") if k in state]
        if len(has_children) == 2:
            self.error(
                f"state '{name}' declares both 'states' and 'parallel states'",
                self.src.key(state, "parallel states"),
            )
        if stype is not None:
            for key in (*has_children, "transitions", "initial"):
                if key in state:
                    self.error(f"a {stype} state cannot have '{key}'", self.src.key(state, key))
        if "memory" in state and stype not in ("shallow history", "deep history"):
            self.error("only history states have a 'memory'", self.src.key(state, "memory"))
        for key in has_children:
            children = state[key]
            if not isinstance(children, list) or not children:
                self.error(
                    f"'{key}' must be a non-empty list of states", self.src.value(state, key)
                )
                continue
            for i, child in enumerate(children):
                if not isinstance(child, dict):
                    self.error(
                        "a state must be a mapping with a 'name'", self.src.item(children, i)
                    )
                    continue
                self.check_state(child, name)
        if "transitions" in state and stype is None:
            transitions = state["transitions"]
            if not isinstance(transitions, list):
                self.error("'transitions' must be a list", self.src.value(state, "transitions"))
            else:
                for i, transition in enumerate(transitions):
                    if not isinstance(transition, dict):
                        self.error("a transition must be a mapping", self.src.item(transitions, i))
                        continue
                    self.check_transition(name, transition, i)

    def check_transition(self, source: str, transition: Any, index: int) -> None:
        self.unknown_keys(transition, TRANSITION_KEYS, "a transition")
        self.positions.transitions[(source, index)] = self.src.node(transition)
        self.transitions.append((source, transition, index))
        for key in ("target", "event"):
            if key in transition:
                self.scalar(transition, key)
        if "guard" in transition and self.scalar(transition, "guard"):
            self.code(transition, "guard", "eval")
        if "action" in transition and self.scalar(transition, "action"):
            self.code(transition, "action", "exec")
        if "contract" in transition:
            self.contracts(transition, f"a transition of '{source}'")
        if "priority" in transition:
            priority = transition["priority"]
            if not (isinstance(priority, int) and not isinstance(priority, bool)) and str(
                priority
            ) not in ("high", "low"):
                self.error(
                    "'priority' must be an integer, 'high' or 'low'",
                    self.src.value(transition, "priority"),
                )
        if "target" not in transition and "event" not in transition and "guard" not in transition:
            self.warning(
                f"a transition of '{source}' has no target, event or guard: it fires on every step",
                self.src.node(transition),
            )

    # ------------------------------------------------------------------ semantics

    def check_semantics(self) -> None:
        for source, transition, _ in self.transitions:
            target = transition.get("target")
            if target is not None and str(target) not in self.states:
                self.error(
                    f"transition of '{source}' targets unknown state '{target}'",
                    self.src.value(transition, "target"),
                    len(str(target)),
                )
        for name, (state, _) in self.states.items():
            children = state.get("states")
            if isinstance(children, list) and children and state.get("type") is None:
                child_names = {
                    str(c["name"]) for c in children if isinstance(c, dict) and "name" in c
                }
                if "initial" not in state:
                    self.error(
                        f"compound state '{name}' has no 'initial' state "
                        f"(one of: {', '.join(sorted(child_names))})",
                        self.src.node(state),
                    )
                elif str(state["initial"]) not in child_names:
                    self.error(
                        f"initial state '{state['initial']}' of '{name}' is not one of its "
                        "children",
                        self.src.value(state, "initial"),
                        len(str(state["initial"])),
                    )
                else:
                    self.check_initial_history(name, state)
            elif "initial" in state and state.get("type") is None:
                self.error(
                    f"'initial' is only for a state with 'states' ('{name}' has none)",
                    self.src.key(state, "initial"),
                )
            if "memory" in state:
                parent = self.states[name][1]
                siblings = self._children(parent)
                if str(state["memory"]) not in siblings:
                    self.error(
                        f"memory '{state['memory']}' of history state '{name}' is not a "
                        "sibling of it",
                        self.src.value(state, "memory"),
                    )
        if not any(p.severity == "error" for p in self.problems):
            self.check_reachability()
            self.check_unguarded_twins()

    def check_initial_history(self, name: str, state: Any) -> None:
        """A history state as 'initial' restores what its parent last had active; entered
        before that parent ever had an active child, it has only its 'memory' to go to."""
        initial = str(state["initial"])
        child = self.states[initial][0]
        if str(child.get("type")) not in ("shallow history", "deep history"):
            return
        where = self.src.value(state, "initial")
        if self.states[name][1] is None:
            self.error(
                f"the root state's 'initial' is the history state '{initial}': the root is "
                "entered once, so there is never anything to restore (and without 'memory' "
                "the first step fails); name the state to start in",
                where,
                len(initial),
            )
        elif "memory" not in child:
            self.warning(
                f"initial state '{initial}' of '{name}' is a history state without "
                f"'memory': entering '{name}' before any of its children was active fails",
                where,
                len(initial),
            )

    def _children(self, name: str | None) -> set[str]:
        if name is None:
            return set()
        state = self.states[name][0]
        out: set[str] = set()
        for key in ("states", "parallel states"):
            for child in state.get(key) or []:
                if isinstance(child, dict) and "name" in child:
                    out.add(str(child["name"]))
        return out

    def check_reachability(self) -> None:
        root = str(self.src.data["statechart"]["root state"]["name"])
        outgoing: dict[str, list[str]] = {}
        for source, transition, _ in self.transitions:
            if transition.get("target") is not None:
                outgoing.setdefault(source, []).append(str(transition["target"]))
        reached: set[str] = set()
        todo = [root]
        while todo:
            name = todo.pop()
            if name in reached:
                continue
            reached.add(name)
            state, parent = self.states[name]
            if parent is not None:
                todo.append(parent)  # entering a state enters its ancestors
            if state.get("initial") is not None:
                todo.append(str(state["initial"]))
            if state.get("memory") is not None:
                todo.append(str(state["memory"]))
            for child in state.get("parallel states") or []:
                todo.append(str(child["name"]))
            todo.extend(outgoing.get(name, []))
        for name, (state, _) in self.states.items():
            if name not in reached:
                self.warning(
                    f"state '{name}' can never be entered", self.src.value(state, "name"), len(name)
                )


    def check_unguarded_twins(self) -> None:
        """Two transitions of one state on one event (or both eventless), neither guarded nor
        given a different priority, are enabled together every time: a non-deterministic
        choice, and the step fails."""
        first: dict[tuple[str, str | None, str], Any] = {}
        for source, transition, _ in self.transitions:
            if transition.get("guard") is not None:
                continue
            event = transition.get("event")
            key = (source, None if event is None else str(event),
                   str(transition.get("priority", 0)))
            earlier = first.setdefault(key, transition)
            if earlier is not transition:
                on = f"on '{event}'" if event is not None else "without an event"
                where = self.src.key(transition, "event") if event is not None else (
                    self.src.node(transition))
                self.warning(
                    f"state '{source}' has two transitions {on} and no guard on either: both "
                    "are always enabled together, a non-deterministic choice that fails the "
                    "step (guard one, or give them different priorities)",
                    where,
                )


def _needs_parentheses(text: str) -> bool:
    """Whether ``text``, which does not compile as an expression, is one written over several
    lines (a ``|`` block) that only lacks the parentheses that let Python join them."""
    if "\n" not in text:
        return False
    try:
        compile(f"(\n{text}\n)", "<guard>", "eval")
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        return False
    return True


def check_statechart(
    text: str, file: str = "<text>"
) -> tuple[Statechart | None, list[ChartProblem]]:
    """Validate chart text and, when it has no errors, build it; returns (chart, all problems)."""
    try:
        src = load_yaml(text, file)
    except SourceError as exc:
        return None, [ChartProblem(exc)]
    checker = _Checker(src)
    checker.check_document()
    checker.check_semantics()
    checker.problems.sort(key=lambda p: (p.error.location.line, p.error.location.col))
    if any(p.severity == "error" for p in checker.problems):
        return None, checker.problems
    try:
        statechart = import_from_dict(plain(src.data))
    except SismicStatechartError as exc:  # pragma: no cover - our checks come first
        cause = exc.__cause__ or exc
        problem = ChartProblem(SourceError(f"sismic refused the chart: {cause}", Location(file)))
        return None, [*checker.problems, problem]
    _SOURCES[statechart] = checker.positions
    return statechart, checker.problems


def load_statechart(
    path: str | Path | None = None, *, text: str | None = None, source: str | None = None
) -> Statechart:
    """Load a statechart from a YAML file (or ``text``), raising :class:`SourceErrors` if invalid.

    Warnings (such as unreachable states) do not stop loading; ``rasm lint`` reports them.
    """
    if text is None:
        if path is None:
            raise TypeError("load_statechart needs a path or text")
        try:
            text = Path(path).read_text(encoding="utf-8")
        except UnicodeDecodeError as exc:
            raise not_utf8(source or str(path), exc) from None
    file = source or (str(path) if path is not None else "<text>")
    statechart, problems = check_statechart(text, file)
    errors = [p.error for p in problems if p.severity == "error"]
    if statechart is None:
        raise SourceErrors(errors)
    return statechart
