"""What a chart's code reads and writes: the static facts the exploration is built on.

The exploration keeps in its states only what can change what the chart does next. A context
variable is *state* when a guard or a contract reads it, when a property reads it, or when code
that assigns a state variable reads it (the closure, computed here). Everything else (counters
nobody tests, reasons kept for a log) is sliced away: two runs that differ only there take the
same transitions. The timers' thresholds (``after(x)``, ``idle(x)``) and the event data a guard
reads are found here too.

The analysis is conservative: code that could reach its namespace by introspection (``locals()``,
``exec``, ``globals()``) makes every variable state, and a method call or an item assignment on a
variable counts as assigning it.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

from sismic.model import Statechart

__all__ = ["ChartCode", "Timer", "analyse_chart"]

# names the interpreter puts beside the context in guards and actions
_EXPOSED = frozenset({
    "active", "time", "after", "idle", "event", "send", "notify", "setdefault", "__old__",
})
_INTROSPECTION = frozenset({"globals", "locals", "vars", "dir", "eval", "exec", "__dict__"})


@dataclass(frozen=True)
class Timer:
    """An ``after(x)`` or ``idle(x)`` in the guard of a transition from ``state``: ``seconds``
    is the argument's source, evaluated in the context when a threshold is needed."""

    state: str
    kind: str  # "after" | "idle"
    seconds: str


@dataclass
class _Code:
    """One piece of chart code: the names it reads and assigns, and the event data it reads."""

    reads: set[str] = field(default_factory=set)
    writes: set[str] = field(default_factory=set)
    data: set[str] = field(default_factory=set)  # event data keys
    introspects: bool = False
    reads_time: bool = False
    timers: list[tuple[str, str]] = field(default_factory=list)  # (after|idle, argument source)
    sends: set[str] = field(default_factory=set)  # the events it sends (send('name'))
    # per statement: (what it may assign, what that may depend on: the names it reads and those
    # of the conditions it runs under), so that one line counting events does not make every
    # variable of its block state
    effects: list[tuple[set[str], set[str], bool]] = field(default_factory=list)


@dataclass
class ChartCode:
    """The static facts of a chart: see the module docstring."""

    #: context variables that are state (None: all of them, the code introspects)
    state_variables: frozenset[str] | None
    #: whether the chart's behaviour depends on the absolute time (a guard reads ``time``)
    reads_time: bool
    #: the timers of each state
    timers: dict[str, list[Timer]]
    #: per event name, the data keys its transitions' guards read (to split into regions)
    guard_data: dict[str, set[str]]
    #: per event name, the data keys any code run on it reads
    data: dict[str, set[str]]
    #: the guards of each event's transitions, as source text (for the regions)
    guards: dict[str, list[str]]
    #: event names the chart's transitions wait for
    events: list[str]
    #: events the chart's code sends (send('name', ...))
    sends: set[str]


def _parse(code: str | None, mode: str) -> ast.AST | None:
    if not code:
        return None
    try:
        return ast.parse(code.strip() if mode == "eval" else code, mode=mode)
    except SyntaxError:
        return None  # load_statechart reported it; a chart with one does not get here


def _walk(node: ast.AST) -> list[ast.AST]:
    """Every node of the tree, each before its children: ``ast.walk``'s nodes in its order,
    without its generators (the analysis runs on every piece of code of a chart)."""
    out = [node]
    for current in out:  # grows while it is read
        for name in current._fields:
            value = getattr(current, name, None)
            if value.__class__ is list:
                out.extend(item for item in value if isinstance(item, ast.AST))
            elif isinstance(value, ast.AST):
                out.append(value)
    return out


def _base_name(node: ast.AST) -> str | None:
    while isinstance(node, ast.Attribute | ast.Subscript):
        node = node.value
    return node.id if isinstance(node, ast.Name) else None


def _literal_key(node: ast.AST) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def _is_event_data(node: ast.AST) -> bool:
    return (
        isinstance(node, ast.Attribute) and node.attr == "data"
        and isinstance(node.value, ast.Name) and node.value.id == "event"
    )


def _scan(tree: ast.AST | None) -> _Code:
    found = _Code()
    if tree is None:
        return found
    for node in _walk(tree):
        if isinstance(node, ast.Name):
            if isinstance(node.ctx, ast.Load):
                if node.id in _INTROSPECTION:
                    found.introspects = True
                elif node.id == "time":
                    found.reads_time = True
                found.reads.add(node.id)
            else:
                found.writes.add(node.id)
        elif isinstance(node, ast.Attribute | ast.Subscript) and isinstance(
            node.ctx, ast.Store | ast.Del
        ):
            base = _base_name(node)
            if base is not None:
                found.writes.add(base)
        elif isinstance(node, ast.Call):
            func = node.func
            if isinstance(func, ast.Name) and func.id in ("after", "idle") and node.args:
                found.timers.append((func.id, ast.unparse(node.args[0])))
            elif isinstance(func, ast.Name) and func.id == "setdefault" and node.args:
                key = _literal_key(node.args[0])
                if key is None:
                    found.introspects = True
                else:
                    found.writes.add(key)
            elif isinstance(func, ast.Name) and func.id == "send" and node.args:
                name = _literal_key(node.args[0])
                if name is not None:
                    found.sends.add(name)
            elif isinstance(func, ast.Attribute):
                if _is_event_data(func.value) and func.attr == "get" and node.args:
                    key = _literal_key(node.args[0])
                    if key is not None:
                        found.data.add(key)
                else:
                    base = _base_name(func.value)
                    if base is not None and base != "event":
                        found.writes.add(base)  # items.append(x) changes items
        elif isinstance(node, ast.Subscript) and _is_event_data(node.value):
            key = _literal_key(node.slice)
            if key is not None:
                found.data.add(key)
        elif (
            isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
            and node.value.id == "event" and node.attr not in ("data", "name")
        ):
            found.data.add(node.attr)  # event.x is event.data['x']
    found.reads -= _EXPOSED
    found.writes -= _EXPOSED
    return found


def _merge(parts: list[_Code]) -> _Code:
    """What one walk over the parts' common tree finds (each part walked on its own)."""
    found = _Code()
    for part in parts:
        found.reads |= part.reads
        found.writes |= part.writes
        found.data |= part.data
        found.sends |= part.sends
        found.introspects |= part.introspects
        found.reads_time |= part.reads_time
        found.timers += part.timers
    return found


# the statements :func:`_effects` looks into (it takes any other one as a whole)
_COMPOUND = (ast.If, ast.While, ast.For, ast.AsyncFor, ast.With, ast.AsyncWith, ast.Try)


def _scan_code(tree: ast.AST | None) -> _Code:
    """:func:`_scan` of a piece of code, with its :func:`_effects`."""
    if not isinstance(tree, ast.Module):
        found = _scan(tree)
        found.effects = _effects(tree)
        return found
    if not any(isinstance(stmt, _COMPOUND) for stmt in tree.body):
        # simple statements only: the tree is walked once, statement by statement
        parts = [_scan(stmt) for stmt in tree.body]
        found = _merge(parts)
        found.effects = [(p.writes, p.reads, p.reads_time) for p in parts]
        return found
    found = _scan(tree)
    found.effects = _effects(tree)
    return found


def _effects(tree: ast.AST | None) -> list[tuple[set[str], set[str], bool]]:
    """(assigned, read, reads time) of each simple statement of ``tree``, a statement under an
    ``if``/``for``/``while``/``with``/``try`` also reading what decides whether it runs."""
    out: list[tuple[set[str], set[str], bool]] = []

    def visit(statements: list[ast.stmt], control: set[str], control_time: bool) -> None:
        for stmt in statements:
            if isinstance(stmt, ast.If | ast.While):
                test = _scan(stmt.test)
                inner = control | test.reads
                visit(stmt.body + stmt.orelse, inner, control_time or test.reads_time)
            elif isinstance(stmt, ast.For | ast.AsyncFor):
                head = _scan(stmt.iter)
                target = _scan(stmt.target)
                inner = control | head.reads
                out.append((target.writes, inner, control_time or head.reads_time))
                visit(stmt.body + stmt.orelse, inner, control_time or head.reads_time)
            elif isinstance(stmt, ast.With | ast.AsyncWith | ast.Try):
                body = list(getattr(stmt, "body", []))
                for handler in getattr(stmt, "handlers", []):
                    body.extend(handler.body)
                body += list(getattr(stmt, "orelse", [])) + list(getattr(stmt, "finalbody", []))
                visit(body, control, control_time)
            else:
                found = _scan(stmt)
                out.append((found.writes, found.reads | control, found.reads_time or control_time))

    if isinstance(tree, ast.Module):
        visit(tree.body, set(), False)
    elif tree is not None:
        found = _scan(tree)
        out.append((found.writes, found.reads, found.reads_time))
    return out


def _conditions(obj) -> Iterator[str]:
    for kind in ("preconditions", "postconditions", "invariants"):
        yield from getattr(obj, kind, None) or ()


def analyse_chart(statechart: Statechart, roots: Iterable[str] = ()) -> ChartCode:
    """The static facts of ``statechart``; ``roots`` are variables that are state whatever the
    chart does with them (those a property reads)."""
    guards_read: set[str] = set(roots)
    reads_time = False
    timers: dict[str, list[Timer]] = {}
    guard_data: dict[str, set[str]] = {}
    data: dict[str, set[str]] = {}
    guards: dict[str, list[str]] = {}
    events: list[str] = []
    sends: set[str] = set()
    # each distinct piece of code is parsed and walked once (charts repeat their actions)
    scanned: dict[tuple[str, str], _Code] = {}

    def scan(code: str | None, mode: str) -> _Code:
        if not code:
            return _Code()
        found = scanned.get((code, mode))
        if found is None:
            tree = _parse(code, mode)
            found = scanned[code, mode] = _scan_code(tree) if mode == "exec" else _scan(tree)
        return found

    # the preamble runs once, before the first step: what it reads is in the initial state
    # already, so it makes nothing state (its introspection still counts)
    preamble = scan(statechart.preamble, "exec")
    sends |= preamble.sends
    introspects = preamble.introspects
    actions: dict[str, _Code] = {}  # by code: the same code has the same effects
    for transition in statechart.transitions:
        event = transition.event
        if event is not None and event not in events:
            events.append(event)
        guard = scan(transition.guard, "eval")
        guards_read |= guard.reads
        introspects |= guard.introspects
        reads_time |= guard.reads_time
        for kind, seconds in guard.timers:
            timers.setdefault(transition.source, []).append(
                Timer(transition.source, kind, seconds)
            )
        action = actions[transition.action or ""] = scan(transition.action, "exec")
        if event is not None:
            if transition.guard:
                guards.setdefault(event, []).append(transition.guard)
            guard_data.setdefault(event, set()).update(guard.data)
            data.setdefault(event, set()).update(guard.data | action.data)
        for condition in _conditions(transition):
            contract = scan(condition, "eval")
            guards_read |= contract.reads
            introspects |= contract.introspects
    for name in statechart.states:
        state = statechart.state_for(name)
        for code in (getattr(state, "on_entry", None), getattr(state, "on_exit", None)):
            actions[code or ""] = scan(code, "exec")
        for condition in _conditions(state):
            contract = scan(condition, "eval")
            guards_read |= contract.reads
            introspects |= contract.introspects
    introspects |= any(code.introspects for code in actions.values())
    for code in actions.values():
        sends |= code.sends
    state = set(guards_read)
    for timer_list in timers.values():
        for timer in timer_list:
            state |= scan(timer.seconds, "eval").reads
    effects = [effect for code in actions.values() for effect in code.effects]
    changed = True
    while changed:  # the closure: a statement that assigns a state variable makes what it reads
        changed = False
        for writes, reads, uses_time in effects:
            if writes & state and not reads <= state:
                state |= reads
                changed = True
            if writes & state and uses_time:
                reads_time = True
    return ChartCode(
        state_variables=None if introspects else frozenset(state),
        reads_time=reads_time,
        timers=timers,
        guard_data=guard_data,
        data=data,
        guards=guards,
        events=sorted(events),
        sends=sends,
    )
